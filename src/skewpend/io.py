"""Files: trajectories streamed to CSV or NetCDF (atomically), run configurations from TOML.

Every file skewpend writes appears only when complete: it is written to a temporary file
``.NAME.skewpend-PID-RANDOM.tmp`` beside it, created exclusively (a name that exists -- a file
or a symbolic link someone planted -- is never opened, followed or reused: another random name
is drawn), and renamed into place; an error or Ctrl-C removes the temporary file, and one left
by a killed process is removed by the next write to the same name.  Files get the permissions
the user's umask gives any new file.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import sys
from pathlib import Path
from typing import Any, Dict, Iterator, Optional, Sequence

import numpy as np

from .errors import ParameterError, SkewpendError
from .schema import CHAIN_NAMES, GEOMETRY_NAMES, LINK_FIELDS, MOTOR_KEYS, NAMES, did_you_mean, field, nearest, nearest_link_key, unknown_names_message

__all__ = [
    "require_netcdf",
    "write_trajectory",
    "TrajectoryWriter",
    "read_config",
    "atomic_path",
    "check_output_path",
    "write_netcdf",
    "read_netcdf",
    "CSV_COLUMNS",
    "csv_metadata_path",
    "has_trajectory_metadata",
    "CONFIG_SECTIONS",
    "TRAJECTORY_SUFFIXES",
]


def require_netcdf():
    """The ``netCDF4`` module, or one clear :class:`SkewpendError` naming the extra to install."""
    from .errors import require

    return require("netCDF4", "writing .nc")

#: Columns of a trajectory CSV, in order.
CSV_COLUMNS = ("t", "phi", "psi", "dphi", "dpsi", "energy", "work", "x1", "y1", "z1", "x2", "y2", "z2")


def trajectory_columns(coordinates=("phi", "psi")) -> tuple:
    """A trajectory file's columns for these coordinates: ``t``, the angles, their rates, ``energy``,
    ``work``, then each rod end's ``x, y, z`` (:data:`CSV_COLUMNS` for the double pendulum; a chain of
    ``n`` links has ``q1`` to ``qn``, ``dq1`` to ``dqn`` and ``x1`` to ``zn``)."""
    n = len(coordinates)
    return (("t",) + tuple(coordinates) + tuple(f"d{c}" for c in coordinates) + ("energy", "work")
            + tuple(f"{x}{k}" for k in range(1, n + 1) for x in "xyz"))


def column_unit(name: str) -> str:
    """The unit of a trajectory file's column (any number of links)."""
    if name in UNITS:
        return UNITS[name]
    if name[:1] in "xyz" and name[1:].isdigit():
        return "m"
    return "rad/s" if name.startswith("d") else "rad"

#: Units of the columns.
UNITS = {"t": "s", "phi": "rad", "psi": "rad", "dphi": "rad/s", "dpsi": "rad/s", "energy": "J", "work": "J",
         **{k: "m" for k in ("x1", "y1", "z1", "x2", "y2", "z2")}}
TRAJECTORY_SUFFIXES = (".csv", ".nc")
#: What a trajectory file's attribute ``kind`` says.
TRAJECTORY_KIND = "skewpend trajectory"
#: Bytes per row on disk, for the up-front space check (CSV: 13 numbers of up to 24 characters).
BYTES_PER_ROW = {".csv": 13 * 24, ".nc": 13 * 8}


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _tmp_file(path: Path) -> Path:
    """A new, empty temporary file beside ``path``, created exclusively under a random name
    (``O_EXCL``: never an existing file, never through a symbolic link); ``OSError`` if the
    directory does not take it."""
    import tempfile

    directory = path.parent if str(path.parent) else Path(".")
    fd, name = tempfile.mkstemp(prefix=f".{short_name(path.name)}.skewpend-{os.getpid()}-", suffix=".tmp", dir=directory)
    os.close(fd)
    return Path(name)


def short_name(name: str) -> str:
    """``name`` cut to 120 characters for a temporary name (a name near the file system's limit of
    255 bytes stays writable: the temporary name adds some 30)."""
    return name if len(name.encode()) <= 120 else name.encode()[:120].decode("utf-8", "ignore")


def _remove_stale(path: Path) -> None:
    """Temporary files of earlier writes to ``path`` whose process is gone (e.g. ``kill -9``):
    regular files named as :func:`_tmp_file` names them (a symbolic link or a directory of that
    name is left alone)."""
    pattern = re.compile(rf"^\.{re.escape(short_name(path.name))}\.skewpend-(\d+)(?:-[A-Za-z0-9_]+)?\.tmp$")
    try:
        entries = list(path.parent.iterdir()) if str(path.parent) else list(Path(".").iterdir())
    except OSError:
        return
    for entry in entries:
        m = pattern.match(entry.name)
        if not m or int(m.group(1)) == os.getpid() or entry.is_symlink() or not entry.is_file():
            continue
        try:
            os.kill(int(m.group(1)), 0)
        except ProcessLookupError:
            with contextlib.suppress(OSError):
                entry.unlink()
        except (PermissionError, OSError):
            pass  # alive (another user's process) or unknown: leave it


def _one_of(items: Sequence[str]) -> str:
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " or " + items[-1]


def check_output_path(path, suffixes: Sequence[str], option: str = "--out") -> Path:
    """Refuse, before any work starts, an output path that cannot be written.

    The suffix must be one of ``suffixes``; the path must not name a directory; its directory
    must exist and accept a new file (tested by creating and removing a temporary file).
    """
    path = _as_path(path, option)
    if path.suffix.lower() not in suffixes:
        raise ParameterError(f"{option}: expected a file name ending in {_one_of(suffixes)}, got {str(path)!r}")
    if path.is_dir():
        raise ParameterError(f"{option}: {path} is a directory; give a file name ending in {_one_of(suffixes)}")
    if path.exists() and not path.is_file():
        raise ParameterError(f"{option}: {path} exists and is not a regular file")
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise ParameterError(f"{option}: cannot write {path}: directory {directory} does not exist")
    try:
        tmp = _tmp_file(path)
    except OSError as exc:
        raise ParameterError(f"{option}: cannot write {path}: {exc.strerror or exc}") from None
    with contextlib.suppress(OSError):
        os.unlink(tmp)  # ours: created just now, exclusively
    return path


def check_disk_space(path: Path, rows: float) -> None:
    """Refuse a file that would not fit on its file system (estimated from the row count)."""
    need = rows * BYTES_PER_ROW.get(Path(path).suffix.lower(), 13 * 24)
    directory = Path(path).parent if str(Path(path).parent) else Path(".")
    try:
        free = shutil.disk_usage(directory).free
    except OSError:
        return
    if need > free:
        raise ParameterError(
            f"the output would take about {_size(need)} ({rows:.3g} rows) but only {_size(free)} is free in {directory}; "
            "use a larger dt_out, a shorter t_end, or another directory"
        )


def _size(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if n < 1000 or unit == "PB":
            return f"{n:.3g} {unit}"
        n /= 1000.0
    return f"{n:.3g} PB"


def _as_path(path, option: str = "path") -> Path:
    """``path`` as a :class:`Path`; anything but text or a path-like is one :class:`ParameterError`."""
    try:
        path = Path(os.fspath(path))
    except TypeError:
        raise ParameterError(f"{option} must be a file path, got {type(path).__name__}") from None
    if not str(path).strip() or str(path) == ".":
        raise ParameterError(f"{option} must be a file path, got {str(path)!r}")
    return path


@contextlib.contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; move it into place only if the block succeeds.

    The file gets the permissions of the user's umask; on any exception (Ctrl-C included)
    the temporary file is removed and ``path`` is untouched.
    """
    path = _as_path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise ParameterError(f"cannot write {path}: directory {directory} does not exist")
    if path.is_dir():
        raise ParameterError(f"cannot write {path}: it is a directory")
    _remove_stale(path)
    try:
        tmp = _tmp_file(path)
    except OSError as exc:
        raise ParameterError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        try:
            yield tmp
            os.chmod(tmp, 0o666 & ~_umask())
            os.replace(tmp, path)
        except OSError as exc:  # a full disk, a directory removed under us, ...
            raise SkewpendError(f"cannot write {path}: {exc.strerror or exc}") from None
        except RuntimeError as exc:  # netCDF4/HDF5 report a full disk as "NetCDF: HDF error"
            if not str(exc).startswith("NetCDF"):
                raise
            raise SkewpendError(f"cannot write {path}: {str(exc).strip()}{_disk_hint(directory)}") from None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _disk_hint(directory: Path) -> str:
    """``" (no space left on device)"`` when ``directory``'s file system is (nearly) full."""
    try:
        st = os.statvfs(directory)
    except OSError:
        return ""
    return " (no space left on device)" if st.f_bavail * st.f_frsize < (1 << 20) else ""


def write_netcdf(spec, path) -> Path:
    """Write a :class:`~skewpend.results.DatasetSpec` to the NetCDF 4 file ``path`` (``*.nc``)
    with ``netCDF4`` (no xarray needed), atomically.  Lists among the attributes become float
    arrays, booleans integers, ``None`` is left out.  The one NetCDF writer of every result."""
    path = Path(path)
    if path.suffix.lower() != ".nc":
        raise ParameterError(f"expected a file name ending in .nc, got {str(path)!r}")
    netCDF4 = require_netcdf()
    with atomic_path(path) as tmp:
        ds = netCDF4.Dataset(tmp, "w", format="NETCDF4")
        try:
            sizes: Dict[str, int] = {}
            for dims, values, _ in list(spec.coords.values()) + list(spec.variables.values()):
                for dim, size in zip(dims, np.shape(values)):
                    sizes.setdefault(dim, int(size))
            for dim, size in sizes.items():
                ds.createDimension(dim, size)
            for group in (spec.coords, spec.variables):
                for name, (dims, values, attrs) in group.items():
                    values = np.asarray(values)
                    kind = "f8" if values.dtype.kind == "f" else ("i1" if values.dtype == np.int8 else
                                                                   ("i4" if values.dtype.itemsize <= 4 else "i8"))
                    compress = values.ndim >= 2
                    v = ds.createVariable(name, kind, tuple(dims), zlib=compress, complevel=4 if compress else 0,
                                          fill_value=False)
                    v.setncatts(_flat_attrs(dict(attrs)))
                    v[...] = values
            ds.setncatts(_flat_attrs(dict(spec.attrs)))
        finally:
            ds.close()
    return path


def read_netcdf(path, *, kind: str):
    """``(variables, attrs)`` of a NetCDF file written by :func:`write_netcdf` for a result of
    ``kind``; anything else is one clear :class:`ParameterError`."""
    from .errors import require

    netCDF4 = require("netCDF4", "reading .nc")
    path = Path(path)
    if not path.is_file():
        raise ParameterError(f"{path} does not exist")
    try:
        with netCDF4.Dataset(path) as ds:
            ds.set_auto_mask(False)
            attrs = {k: ds.getncattr(k) for k in ds.ncattrs()}
            variables = {name: np.asarray(v[...]) for name, v in ds.variables.items()}
    except (OSError, RuntimeError, KeyError) as exc:
        raise ParameterError(f"{path} is not a readable NetCDF file ({str(exc).strip() or type(exc).__name__})") from None
    if attrs.get("kind") not in (None, kind) and str(attrs.get("kind")) != kind:
        raise ParameterError(f"{path} holds a {attrs.get('kind')}, not a {kind}")
    return variables, attrs


def _attr_value(value):
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, (list, tuple)):
        return np.asarray(value, dtype=float)
    return value


def _flat_attrs(metadata: Dict[str, Any]) -> Dict[str, Any]:
    return {k: _attr_value(v) for k, v in metadata.items() if v is not None}


def csv_metadata_path(path) -> Path:
    """The metadata file of a trajectory CSV: ``run.csv`` -> ``run.csv.json`` (beside it)."""
    path = Path(path)
    return path.with_name(path.name + ".json")


def has_trajectory_metadata(path) -> bool:
    """Whether the trajectory CSV ``path`` has its record of how it was made: the metadata file
    beside it (:func:`csv_metadata_path`) naming the kind, or -- a file of skewpend before 0.x that
    kept it in the CSV -- ``# kind:`` among its last lines."""
    import json

    meta = csv_metadata_path(path)
    if meta.is_file():
        try:
            return json.loads(meta.read_text()).get("kind") == TRAJECTORY_KIND
        except (OSError, ValueError, AttributeError, UnicodeDecodeError):
            return False
    with open(path, "rb") as fh:
        fh.seek(0, 2)
        fh.seek(max(0, fh.tell() - 65536))
        tail = fh.read()
    return b"\n# kind: " in tail


def _json_value(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"{type(value).__name__} is not JSON")


class TrajectoryWriter:
    """Rows of a trajectory streamed to ``.csv`` or ``.nc`` as they are computed.

    Use as a context manager: ``write(block)`` appends rows (columns :data:`CSV_COLUMNS`),
    ``finish(metadata)`` records how the run ended; leaving the block without an exception
    moves the file into place, with one it is removed.  CSV: a header line and the rows, plain
    numbers only (``pandas.read_csv(path)``, ``numpy.genfromtxt(path, delimiter=",",
    names=True)``, ``numpy.loadtxt(path, delimiter=",", skiprows=1)`` read it as it is), the
    metadata in a JSON file beside it, ``run.csv.json`` (:func:`csv_metadata_path`), written and
    moved into place with it.  NetCDF 4 (``netCDF4``): one variable per column along the unlimited
    dimension ``t``, with units; metadata as global attributes.
    """

    def __init__(self, path, metadata: Optional[Dict[str, Any]] = None, columns: Sequence[str] = CSV_COLUMNS):
        self.path = Path(path)
        self.columns = tuple(columns)
        self._row = ",".join(["%r"] * len(self.columns)) + "\n"
        self.suffix = self.path.suffix.lower()
        if self.suffix not in TRAJECTORY_SUFFIXES:
            raise ParameterError(f"unknown output format {self.path.suffix!r} for {self.path}; allowed: .csv, .nc")
        self.metadata = dict(metadata or {})
        self.rows = 0
        self._stack = contextlib.ExitStack()

    def __enter__(self) -> "TrajectoryWriter":
        if self.suffix == ".nc":
            require_netcdf()  # before anything is created
        try:
            tmp = self._stack.enter_context(atomic_path(self.path))
            if self.suffix == ".csv":
                # the metadata file's block is entered last, so it is moved into place first (then the
                # CSV): a reader that finds the CSV finds its metadata; an error removes both
                self._meta_tmp = self._stack.enter_context(atomic_path(csv_metadata_path(self.path)))
                self._stack.callback(self._write_metadata)
                self._fh = self._stack.enter_context(open(tmp, "w"))
                self._fh.write(",".join(self.columns) + "\n")
            else:
                netCDF4 = require_netcdf()
                ds = netCDF4.Dataset(tmp, "w", format="NETCDF4")
                self._stack.callback(ds.close)
                ds.createDimension("t", None)
                self._vars = []
                for name in self.columns:
                    v = ds.createVariable(name, "f8", ("t",))
                    v.units = column_unit(name)
                    self._vars.append(v)
                self._ds = ds
        except BaseException:
            # leave the atomic writer by its error path: the temporary file is removed, never committed
            if not self._stack.__exit__(*sys.exc_info()):
                raise
        return self

    def write(self, block: np.ndarray) -> None:
        """Append rows, shape (k, columns), all finite."""
        block = np.asarray(block, dtype=float)
        if block.ndim != 2 or block.shape[1] != len(self.columns):
            raise ValueError(f"expected rows of {len(self.columns)} columns")
        if not np.all(np.isfinite(block)):
            raise SkewpendError("refusing to write non-finite values")
        if block.shape[0] == 0:
            return
        if self.suffix == ".csv":  # each number as Python's repr: the shortest text that reads back to the same
            # double, and always a float's ("0.0", not "0": pandas reads every column as float64)
            self._fh.write("".join(self._row % tuple(row) for row in block.tolist()))
        else:
            lo = self.rows
            for i, v in enumerate(self._vars):
                v[lo : lo + block.shape[0]] = block[:, i]
        self.rows += block.shape[0]

    def finish(self, metadata: Optional[Dict[str, Any]] = None) -> None:
        self.metadata.update(metadata or {})
        if self.suffix != ".csv":  # (the CSV's metadata file is written when the block closes)
            self._ds.setncatts({"title": "skewpend trajectory of the skewed double pendulum",
                                **_flat_attrs(self.metadata)})

    def _write_metadata(self) -> None:
        import json

        with open(self._meta_tmp, "w") as fh:
            json.dump({"columns": list(self.columns), "units": [column_unit(c) for c in self.columns], "csv_rows": self.rows,
                       **_flat_attrs(self.metadata)}, fh, indent=1, default=_json_value)
            fh.write("\n")

    def __exit__(self, *exc) -> bool:
        return self._stack.__exit__(*exc)


def trajectory_metadata(traj) -> Dict[str, Any]:
    """What a file records about how a trajectory was made (flat key -> number/string)."""
    from . import __version__

    md: Dict[str, Any] = {
        "kind": TRAJECTORY_KIND,
        "skewpend_version": __version__,
        "method": traj.method,
        "status": traj.status,
        "message": traj.message,
        "energy_drift": traj.energy_drift,
    }
    data = traj.params.to_dict()
    if "links" in data:  # a model of [[links]] tables (as model_from_mapping reads it): its plain data as one JSON text
        import json

        md["chain"] = json.dumps(data)
    else:
        for key, value in data.items():
            if value is not None:
                md[f"param_{key}"] = np.asarray(value, dtype=float).ravel().tolist() if isinstance(value, list) else float(value)
    for key, value in traj.settings.items():
        if value is not None:
            md[f"setting_{key}"] = value
    for key, value in traj.stats.items():
        md[f"stat_{key}"] = value
    return md


def trajectory_table(t, y, energy, work, tips) -> np.ndarray:
    """Rows in :data:`CSV_COLUMNS` order."""
    return np.column_stack([t, y, energy, work, tips])


def _csv_value(text: str):
    """A ``# key: value`` line's value as written by :class:`TrajectoryWriter`: a number, a list
    of numbers (space-separated), or the text."""
    parts = text.split()
    try:
        values = [float(v) for v in parts]
    except ValueError:
        return text
    return values[0] if len(values) == 1 else values


def read_trajectory(path) -> "tuple[np.ndarray, Dict[str, Any]]":
    """``(rows, metadata)`` of a trajectory file ``*.csv`` or ``*.nc`` written by skewpend
    (:data:`CSV_COLUMNS` columns; the flat metadata of :func:`trajectory_metadata`)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in TRAJECTORY_SUFFIXES:
        raise ParameterError(f"expected a trajectory file ending in .csv or .nc, got {str(path)!r}")
    if not path.is_file():
        raise ParameterError(f"{path} does not exist")
    if suffix == ".nc":
        variables, attrs = read_netcdf(path, kind=TRAJECTORY_KIND)
        columns = CSV_COLUMNS if "chain" not in attrs else trajectory_columns(
            tuple(c for c in variables if c.startswith("q") and c[1:].isdigit()))
        missing = [c for c in columns if c not in variables]
        if missing:
            raise ParameterError(f"{path} is not a skewpend trajectory: it lacks {', '.join(missing)}")
        rows = np.column_stack([np.asarray(variables[c], dtype=float) for c in columns])
        meta = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in attrs.items()}
        return rows, meta
    meta: Dict[str, Any] = {}
    try:
        with open(path) as fh:
            header = fh.readline().strip()
            for line in fh:  # (a file of an older skewpend: its metadata in '# key: value' lines at the end)
                if line.startswith("# ") and ": " in line:
                    key, _, value = line[2:].rstrip("\n").partition(": ")
                    meta[key] = _csv_value(value)
        columns = chain_columns(header) or CSV_COLUMNS
        if header != ",".join(columns):
            raise ValueError("its header is not skewpend's")
        rows = np.loadtxt(path, delimiter=",", skiprows=1, comments="#", ndmin=2)
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{path} is not a skewpend trajectory CSV file ({exc})") from None
    if rows.shape[1:] != (len(columns),):
        raise ParameterError(f"{path} is not a skewpend trajectory CSV file (expected {len(columns)} columns)")
    sidecar = csv_metadata_path(path)
    if not meta:
        import json

        try:
            meta = json.loads(sidecar.read_text())
            if not isinstance(meta, dict):
                raise ValueError("not a JSON object")
        except FileNotFoundError:
            raise ParameterError(f"{path}: its metadata file {sidecar.name} (how the run was made, written beside the "
                                 "CSV) is missing; keep the two files together") from None
        except (OSError, ValueError, UnicodeDecodeError) as exc:
            raise ParameterError(f"{path}: its metadata file {sidecar.name} cannot be read ({exc})") from None
        meta.pop("columns", None)
        meta.pop("units", None)
    expected = meta.pop("csv_rows", None)
    if isinstance(expected, (int, float)) and expected != rows.shape[0]:
        raise ParameterError(f"{path} has {rows.shape[0]} rows where its metadata records {int(expected)}: truncated "
                             "or edited")
    return rows, meta


def chain_columns(header: str):
    """The columns of a chain's trajectory CSV whose header is ``header`` (None: not a chain's)."""
    names = header.split(",")
    n = sum(1 for c in names if c.startswith("q") and c[1:].isdigit())
    if n < 1:
        return None
    columns = trajectory_columns(tuple(f"q{k}" for k in range(1, n + 1)))
    return columns if header == ",".join(columns) else None


def write_trajectory(traj, path: os.PathLike) -> Path:
    """Write a kept :class:`~skewpend.integrate.Trajectory` to ``.csv`` or ``.nc``.

    (To stream a long run to a file without holding it, pass ``out=`` to
    :func:`skewpend.simulate` instead.)  The file appears only when complete.
    """
    path = Path(path)
    table = trajectory_table(traj.t, traj.y, traj.energy, traj.work, traj.tips())
    with TrajectoryWriter(path, columns=trajectory_columns(getattr(traj.params, "coordinates", ("phi", "psi")))) as w:
        w.write(table)
        w.finish(trajectory_metadata(traj))
    return path


# -- configuration -----------------------------------------------------------------------------------
CONFIG_SECTIONS = {
    "parameters": set(NAMES),
    "initial": {"phi0", "psi0", "dphi0", "dpsi0", "q0", "dq0"},
    "simulation": {"t_end", "dt_out", "method", "rtol", "atol", "dt", "max_steps", "out", "plot"},
    "chain": set(CHAIN_NAMES),
    "motor": set(MOTOR_KEYS),  # a voltage-driven DC motor on a chain's joint (skewpend.config.Motor)
}
#: A chain's links: an array of tables ``[[links]]``, one a link (its keys: the schema's LINK_FIELDS).
LINKS_SECTION = "links"


def _check_run_value(path, section: str, key: str, value: Any, depth: int = 0) -> None:
    """A run file's value nests at most two lists deep (a 3x3 matrix), and its integers are
    numbers a double holds (a 330-digit integer would overflow every computation)."""
    if depth > 2 or isinstance(value, dict) and depth > 0:
        raise ParameterError(f"{path}: [{section}] {key}: nested too deeply; expected a number, a string, a list "
                             f"of them or a 3x3 matrix")
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) > 2**1023:
        raise ParameterError(f"{path}: [{section}] {key}: the integer {str(value)[:12]}... ({len(str(abs(value)))} "
                             f"digits) is beyond any double; expected a number of at most 1.8e308 in magnitude")
    if isinstance(value, list):
        for v in value:
            _check_run_value(path, section, key, v, depth + 1)


def read_config(path: os.PathLike) -> Dict[str, Dict[str, Any]]:
    """Read a run configuration (TOML) with sections ``parameters``, ``initial``, ``simulation``.

    Values are returned as written (angles may be strings such as ``"30deg"``); unknown
    sections or keys are an error.
    """
    import datetime

    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover
        import tomli as tomllib
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            data = tomllib.load(fh)
    except FileNotFoundError:
        raise ParameterError(f"config file {path} does not exist") from None
    except IsADirectoryError:
        raise ParameterError(f"config file {path} is a directory; give a TOML file") from None
    except OSError as exc:
        raise ParameterError(f"config file {path} cannot be read: {exc.strerror or exc}") from None
    except UnicodeDecodeError as exc:
        raise ParameterError(
            f"config file {path} is not valid TOML: not UTF-8 text (byte {exc.start}); give a TOML text file"
        ) from None
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"config file {path} is not valid TOML: {exc}") from None
    except RecursionError:  # the reader recurses once per level of nesting
        raise ParameterError(f"config file {path} nests arrays or tables too deeply; a run file's values are "
                             f"numbers, strings, lists of them and 3x3 matrices") from None
    if not data:
        raise ParameterError(
            f"config file {path} is empty; expected one or more of the sections [{'], ['.join(CONFIG_SECTIONS)}]"
        )
    links = data.pop(LINKS_SECTION, None)
    if links is not None:
        keys = [key for key, _, _ in LINK_FIELDS]
        if not isinstance(links, list) or not all(isinstance(t, dict) for t in links):
            raise ParameterError(f"{path}: links must be an array of tables, one [[links]] table a link")
        for i, table in enumerate(links, start=1):
            unknown = [k for k in table if k not in keys]
            if unknown:
                raise ParameterError(f"{path}: [[links]] {i}: unknown key {unknown[0]!r}{did_you_mean(nearest_link_key(unknown[0]))}; "
                                     f"a link takes {', '.join(keys)}")
            for key, value in table.items():
                _check_run_value(path, f"links {i}", key, value)
    for section, values in data.items():
        if section not in CONFIG_SECTIONS:
            close = nearest(section, [*CONFIG_SECTIONS, LINKS_SECTION])
            raise ParameterError(f"{path}: unknown section [{section}]{did_you_mean(close and ('[[links]]' if close == LINKS_SECTION else f'[{close}]'))}; "
                                 f"allowed: {', '.join(CONFIG_SECTIONS)}, [[links]]")
        if not isinstance(values, dict):
            raise ParameterError(f"{path}: [{section}] must be a table")
        unknown = [k for k in values if k not in CONFIG_SECTIONS[section]]
        if unknown and section == "parameters":
            raise ParameterError(unknown_names_message(unknown, NAMES, where=f"{path}: [parameters]"))
        if unknown:
            raise ParameterError(
                f"{path}: unknown key(s) {sorted(unknown)}{did_you_mean(nearest(sorted(unknown)[0], CONFIG_SECTIONS[section]))} "
                f"in [{section}]; allowed: {sorted(CONFIG_SECTIONS[section])}"
            )
        for key, value in values.items():
            _check_run_value(path, section, key, value)
            if isinstance(value, (datetime.date, datetime.time)):
                raise ParameterError(f"{path}: [{section}] {key}: expected a number or a string, got a TOML date/time {value}")
            if key in GEOMETRY_NAMES and (
                isinstance(value, dict) or isinstance(value, list) and any(isinstance(v, (list, dict)) for v in value)
            ):
                matrix = field(key).kind == "inertia" and isinstance(value, list) and len(value) == 3 and all(isinstance(r, list) and len(r) == 3 for r in value)
                if not matrix:
                    shape = "a 3x3 matrix [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]] or a flat list of 3, 6 or 9" if matrix is False and field(key).kind == "inertia" else "a flat list of 3"
                    got = "a table" if isinstance(value, dict) else repr(value)
                    raise ParameterError(f"{path}: [{section}] {key}: expected {shape} numbers or symbol names, got {got}")
    out: Dict[str, Any] = {s: dict(data.get(s, {})) for s in CONFIG_SECTIONS}
    if links is not None:
        out[LINKS_SECTION] = links
    return out
