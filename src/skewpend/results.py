"""The result protocol: what every result of skewpend offers, written once.

Every result (a trajectory, a flip map, a Lyapunov spectrum, a chaos diagram, ...) is a small
immutable object carrying its data and how it was made -- in the manner of diffrax's
``Solution(ts, ys, stats, result)``:

* ``params`` -- the :class:`~skewpend.Parameters`;
* ``settings`` -- the resolved settings (plain JSON data; :func:`canonical_json` is their one
  encoding, :func:`fingerprint` its SHA-256, which a store records to refuse resuming with
  other settings);
* ``stats`` -- statistics with documented keys (``steps`` always counts *accepted* steps,
  ``rejected`` the rejected ones);
* ``status`` -- a :class:`~skewpend.status.Status`; ``message`` and ``ok`` follow from it (and
  from ``failures``, the count of failed trajectories of a grid);
* ``to_xarray()``, ``to_netcdf(path)``, ``summary()``; :func:`skewpend.open_result` reads any
  result file back as the class that wrote it.

:class:`ResultProtocol` implements these from one method a result class supplies,
``_dataset()``: its variables, coordinates and attributes in a neutral form
(:class:`DatasetSpec`) that xarray, NetCDF (``netCDF4``, no xarray needed) and Zarr all take.
:func:`grid_status` is the one rule for a grid of many trajectories: all ok, or
:attr:`Status.PARTIAL` with a message naming how many failed.

Reading back is the mirror of writing: each result kind reads itself in the module that writes it
(a reader registered for its ``result_kind``, see :mod:`skewpend.analysis.readback`), with the
helpers here -- :func:`result_container` (what a path holds, by content), :func:`protocol_fields`
(``params``, ``settings``, ``stats``, ``status``, ``message`` of a file this protocol wrote),
:func:`netcdf_reader` (a reader of one kind's ``*.nc`` file, every missing or bad part one line)
and :func:`agree` (what a file stores against what its parameters give, to :data:`AGREEMENT`).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import math
import numbers
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Dict, Mapping, Tuple

import numpy as np

from .errors import ParameterError, SkewpendError, require
from .status import Status

__all__ = ["Result", "ResultProtocol", "DatasetSpec", "canonical_json", "fingerprint", "plain", "grid_status",
           "AGREEMENT", "agree", "json_attr", "protocol_fields", "netcdf_reader", "result_container", "netcdf_kind",
           "zarr_store_kind"]


def plain(value: Any) -> Any:
    """``value`` as plain JSON data: tuples and arrays as lists, NumPy scalars as Python numbers,
    non-finite floats as ``None`` (JSON has no NaN)."""
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return [plain(v) for v in value.tolist()]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        x = float(value)
        return x if math.isfinite(x) else None
    return value


def _brief(value: Any) -> str:
    """A value in a few characters: an array by its dtype and shape (whole when it has at most
    four numbers), a number to six digits, a long string or list cut short."""
    if isinstance(value, np.ndarray):
        if value.size <= 4 and value.dtype.kind in "biufc":
            return np.array2string(value, precision=6, separator=", ", max_line_width=10**6).replace("\n", "")
        return f"{value.dtype}[{'x'.join(map(str, value.shape))}]"
    if isinstance(value, (float, np.floating)):
        return f"{float(value):.6g}"
    if isinstance(value, (list, tuple)) and (len(value) > 4 or not all(isinstance(v, numbers.Real) for v in value)):
        kinds = sorted({type(v).__name__ for v in value})
        return f"{type(value).__name__} of {len(value)}" + (f" {kinds[0]}" if len(kinds) == 1 else "")
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def canonical_json(settings: Mapping[str, Any]) -> str:
    """The one encoding of settings: sorted keys, no spaces, strict JSON."""
    return json.dumps(plain(settings), sort_keys=True, separators=(",", ":"), allow_nan=False)


def fingerprint(settings: Mapping[str, Any]) -> str:
    """SHA-256 (hex) of :func:`canonical_json`."""
    return hashlib.sha256(canonical_json(settings).encode()).hexdigest()


def grid_status(failed: int, total: int, what: str = "trajectories") -> Tuple[Status, str]:
    """``(status, message)`` of a grid of ``total`` trajectories of which ``failed`` failed."""
    if failed <= 0:
        return Status.SUCCESS, f"all {total} {what} completed"
    return Status.PARTIAL, (f"{failed} of {total} {what} failed (non-finite state, step size underflow or "
                            "max_steps reached); they are NaN in the result")


@dataclass
class DatasetSpec:
    """A result's data in a neutral form: ``variables`` and ``coords`` map a name to
    ``(dims, values, attributes)``; ``attrs`` are numbers, strings and lists only."""

    variables: Dict[str, Tuple[Tuple[str, ...], np.ndarray, Dict[str, Any]]]
    coords: Dict[str, Tuple[Tuple[str, ...], np.ndarray, Dict[str, Any]]]
    attrs: Dict[str, Any] = field(default_factory=dict)

    def to_xarray(self):
        xr = require("xarray", "to_xarray()")
        return xr.Dataset({k: (d, v, dict(a)) for k, (d, v, a) in self.variables.items()},
                          coords={k: (d, v, dict(a)) for k, (d, v, a) in self.coords.items()},
                          attrs=dict(self.attrs))


class ResultProtocol:
    """Mixin of every result class (see the module).  A class supplies ``_dataset()`` and has
    the fields ``params``, ``settings``, ``stats``, ``status``; ``message`` may be a field."""

    #: What the file attribute ``kind`` says (and :func:`skewpend.open_result` dispatches on).
    result_kind: ClassVar[str] = "result"
    if TYPE_CHECKING:  # what every result class has (declared by the dataclasses themselves)
        params: Any

        @property
        def settings(self) -> Dict[str, Any]: ...

    @property
    def ok(self) -> bool:
        """True when the whole computation succeeded (``status`` is SUCCESS)."""
        return Status.of(getattr(self, "status", Status.SUCCESS)) is Status.SUCCESS

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        # a result's repr is a line a person reads (shapes, not whole arrays): put in each class's
        # own namespace, where @dataclass keeps it instead of writing its field-by-field repr
        if "__repr__" not in cls.__dict__:
            cls.__repr__ = ResultProtocol.__repr__  # type: ignore[method-assign]

    def __repr__(self) -> str:
        """``<Trajectory success: the message; t float64[124], y float64[124x4], ...>``: the
        status, the message and each data field by its shape (a few numbers shown whole)."""
        status = Status.of(getattr(self, "status", Status.SUCCESS))
        names: list = [f.name for f in dataclasses.fields(self)] if dataclasses.is_dataclass(self) else []  # type: ignore[arg-type]
        shown = [f"{name} {_brief(getattr(self, name, None))}" for name in names
                 if name not in ("params", "settings", "stats", "status", "message") and not name.startswith("_")]
        text = f"<{type(self).__name__} {status.name.lower()}: {getattr(self, 'message', status.message)}"
        body = ", ".join(shown)
        if len(body) > 300:
            body = body[:297].rsplit(", ", 1)[0] + ", ..."
        return f"{text}; {body}>" if body else text + ">"

    def _dataset(self) -> DatasetSpec:  # pragma: no cover - every result class overrides it
        raise NotImplementedError

    def _base_attrs(self) -> Dict[str, Any]:
        from . import __version__

        status = Status.of(getattr(self, "status", Status.SUCCESS))
        return {
            "kind": self.result_kind, "skewpend_version": __version__, "status": int(status),
            "message": str(getattr(self, "message", status.message)),
            "params": canonical_json(self.params.to_dict()), "settings": canonical_json(self.settings),
            "stats": canonical_json(getattr(self, "stats", {})),
        }

    def to_xarray(self):
        """An :class:`xarray.Dataset` of the result, with how it was made as attributes."""
        return self._dataset().to_xarray()

    def to_netcdf(self, path):
        """Write the result to a NetCDF 4 file ``*.nc`` (``netCDF4``, the ``netcdf`` extra; no
        xarray needed), atomically: the file appears complete or not at all.  Returns the path."""
        from .io import write_netcdf

        return write_netcdf(self._dataset(), path)

    def summary(self) -> str:
        """A few lines for a person: what it is, its status, its main statistics."""
        status = Status.of(getattr(self, "status", Status.SUCCESS))
        lines = [f"{self.result_kind}: {getattr(self, 'message', status.message)}"]
        stats = getattr(self, "stats", {}) or {}
        shown = [f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in stats.items()
                 if isinstance(v, (int, float)) and not isinstance(v, bool)]
        if shown:
            lines.append(", ".join(shown[:10]))
        return "\n".join(lines)


@dataclass(frozen=True, kw_only=True)
class Result(ResultProtocol):
    """The fields every result class shares, keyword-only (so a subclass lists its own data
    fields first): ``params``, ``settings``, ``stats``, ``status`` (an int from C becomes its
    :class:`Status`), ``message``."""

    params: Any
    settings: Dict[str, Any]
    stats: Dict[str, Any] = field(default_factory=dict)
    status: Status = Status.SUCCESS
    message: str = ""

    def __post_init__(self):
        object.__setattr__(self, "status", Status.of(self.status))
        if not self.message:
            object.__setattr__(self, "message", self.status.message)


# -- reading a result back: what the reader of every kind shares ------------------------------------------
#: Relative agreement required between what a file stores and what its parameters give when the
#: missing parts are recomputed (the same model agrees to rounding, ~1e-12; another model by far
#: more than this).
AGREEMENT = 1e-6

_HDF5 = b"\x89HDF\r\n\x1a\n"
_NETCDF3 = (b"CDF\x01", b"CDF\x02", b"CDF\x05")


def result_container(path: Path) -> str:
    """``"netcdf"``, ``"zarr"`` or ``"csv"`` (a trajectory's) by content (the name's suffix must
    agree); anything else -- missing, empty, a JSON export, another CSV table -- is one
    :class:`ParameterError` line."""
    if not path.exists():
        raise ParameterError(f"{path} does not exist")
    suffix = path.suffix.lower()
    if path.is_dir():
        if (path / "zarr.json").is_file() or (path / ".zgroup").is_file():
            if suffix != ".zarr":
                raise ParameterError(f"{path} is a Zarr store but its name does not end in .zarr; rename it")
            return "zarr"
        raise ParameterError(f"{path} is a directory, not a Zarr store made by skewpend (no group metadata in it)")
    if not path.is_file():
        raise ParameterError(f"{path} is not a regular file")
    try:
        with open(path, "rb") as fh:
            head = fh.read(512)
    except OSError as exc:
        raise ParameterError(f"{path} cannot be read: {exc.strerror or exc}") from None
    if not head:
        raise ParameterError(f"{path} is empty, not a result file")
    if head.startswith(_HDF5) or head.startswith(_NETCDF3):
        if suffix != ".nc":
            raise ParameterError(f"{path} is a NetCDF file but its name does not end in .nc; rename it")
        return "netcdf"
    from .io import CSV_COLUMNS, chain_columns

    first = head.split(b"\n", 1)[0].strip()
    if first == ",".join(CSV_COLUMNS).encode() or chain_columns(first.decode(errors="replace")):
        if suffix != ".csv":
            raise ParameterError(f"{path} is a trajectory CSV file but its name does not end in .csv; rename it")
        return "csv"
    if head.lstrip()[:1] in (b"{", b"["):
        raise ParameterError(f"{path} is a JSON export (of `--out FILE.json` or `--format json`), which keeps only part "
                             "of a result; to read a result back, write it with to_netcdf() or `--out FILE.nc`")
    if b"," in first and b"\0" not in head:
        raise ParameterError(f"{path} is a CSV table without how it was made (header {first[:60].decode(errors='replace')!r}); "
                             "only trajectories are read back from CSV: write other results with to_netcdf() or "
                             "`--out FILE.nc`")
    raise ParameterError(f"{path} is not a result file of skewpend (neither NetCDF, a Zarr store nor a trajectory CSV)")


def netcdf_kind(path: Path) -> Any:
    """The attribute ``kind`` of the NetCDF file ``path`` (None without one)."""
    netCDF4 = require("netCDF4", "reading .nc")
    try:
        with netCDF4.Dataset(path) as ds:
            return ds.getncattr("kind") if "kind" in ds.ncattrs() else None
    except (OSError, RuntimeError, KeyError) as exc:
        raise ParameterError(f"{path} is not a readable NetCDF file, or is truncated "
                             f"({str(exc).strip() or type(exc).__name__})") from None


def zarr_store_kind(path: Path) -> Any:
    """The store kind (attribute ``kind``) of a Zarr store skewpend made; another store is refused."""
    zarr = require("zarr", "a Zarr store")
    try:
        attrs = dict(zarr.open_group(str(path), mode="r").attrs)
    except Exception:  # noqa: BLE001 - whatever Zarr raises for a damaged group
        raise ParameterError(f"{path} is a damaged Zarr store: its group metadata cannot be read") from None
    if "skewpend_store" not in attrs:
        raise ParameterError(f"{path} is a Zarr store, but not one made by skewpend")
    return attrs.get("kind")


def json_attr(attrs: Mapping[str, Any], key: str) -> Any:
    """The attribute ``key`` decoded from JSON (as :func:`canonical_json` wrote it)."""
    return json.loads(str(attrs[key]))


def protocol_fields(path: Path, attrs: Mapping[str, Any], parameters) -> Dict[str, Any]:
    """``params``, ``settings``, ``stats``, ``status``, ``message`` of a file this protocol wrote
    (:meth:`ResultProtocol._base_attrs`); ``parameters`` is the parameters' class (its
    ``from_mapping`` reads them: this layer does not know the model)."""
    try:
        params = parameters.from_mapping(json_attr(attrs, "params"))
    except SkewpendError as exc:
        raise ParameterError(f"{path}: its parameters cannot be read back ({exc})") from None
    return {"params": params, "settings": json_attr(attrs, "settings"), "stats": json_attr(attrs, "stats"),
            "status": Status.of(int(attrs["status"])), "message": str(attrs["message"])}


def agree(path: Path, what: str, stored, rebuilt, *, scale: float = 0.0) -> None:
    """Refuse ``stored`` unless it equals ``rebuilt`` to :data:`AGREEMENT` of their scale (NaN
    where NaN): a file written by another model is one :class:`ParameterError` line."""
    a = np.asarray(stored, dtype=complex if np.iscomplexobj(stored) or np.iscomplexobj(rebuilt) else float)
    b = np.asarray(rebuilt, dtype=a.dtype)
    if a.shape != b.shape:
        raise ParameterError(f"{path} was written by another model: its {what} has shape {a.shape}, the parameters "
                             f"give {b.shape}")
    nan_a, nan_b = np.isnan(a), np.isnan(b)
    finite = np.isfinite(a) & np.isfinite(b)
    both_inf = np.isinf(a) & np.isinf(b) & (a == b)
    size = max(scale, float(np.max(np.abs(a[finite]))) if finite.any() else 0.0, 1e-300)
    diff = float(np.max(np.abs(a[finite] - b[finite]))) if finite.any() else 0.0
    if np.any(nan_a != nan_b) or not np.all(finite | both_inf | (nan_a & nan_b)) or diff > AGREEMENT * size:
        raise ParameterError(
            f"{path} was written by another model: its {what} differs from what its parameters give "
            f"(by {diff:.3g}, more than {AGREEMENT:g} of {size:.3g}); it cannot be read back with these equations")


def netcdf_reader(kind: str) -> Callable[[Callable[..., Any]], Callable[[Any], Any]]:
    """Decorator: ``build(path, variables, attrs)`` of one result kind becomes ``read(path)``, the
    reader of that kind's ``*.nc`` file (:func:`skewpend.io.read_netcdf`); a variable or
    attribute missing or bad is one :class:`ParameterError` line naming the kind."""
    def decorate(build):
        @functools.wraps(build)
        def read(path):
            from .io import read_netcdf

            path = Path(path)
            variables, attrs = read_netcdf(path, kind=kind)
            try:
                return build(path, variables, attrs)
            except ParameterError:
                raise
            except (KeyError, TypeError, ValueError, IndexError) as exc:  # json.JSONDecodeError is a ValueError
                raise ParameterError(f"{path} is not a {kind} made by skewpend (missing or bad {type(exc).__name__}: "
                                     f"{exc})") from None
        return read
    return decorate


# -- the quantiles of the intervals ---------------------------------------------------------------
@functools.lru_cache(maxsize=256)
def t_quantile(q: float, dof: int) -> float:
    """Student's t quantile (every interval skewpend reports): SciPy's ``stdtrit``, which
    ``scipy.stats.t.ppf`` calls (scipy.special is light to import; scipy.stats takes 0.4-1 s, a tenth
    of a report's first-run overhead and a third of a warm identification)."""
    from scipy.special import stdtrit

    return float(stdtrit(dof, q))


@functools.lru_cache(maxsize=16)
def normal_quantile(q: float) -> float:
    """The normal quantile: ``scipy.special.ndtri``, which ``scipy.stats.norm.ppf`` calls."""
    from scipy.special import ndtri

    return float(ndtri(q))
