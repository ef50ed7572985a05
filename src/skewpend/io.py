"""Files: trajectories to CSV or NetCDF (atomically), run configurations from TOML."""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
from pathlib import Path
from typing import Any, Dict, Iterator

import numpy as np

from .errors import ParameterError, SkewpendError

__all__ = ["write_trajectory", "read_config", "atomic_path", "CSV_COLUMNS", "CONFIG_SECTIONS"]

#: Columns of a trajectory CSV, in order.
CSV_COLUMNS = ("t", "phi", "psi", "dphi", "dpsi", "energy", "work", "x1", "y1", "z1", "x2", "y2", "z2")


@contextlib.contextmanager
def atomic_path(path: Path) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; move it into place only if the block succeeds."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise ParameterError(f"cannot write {path}: directory {directory} does not exist")
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _table(traj) -> np.ndarray:
    return np.column_stack([traj.t, traj.y, traj.energy, traj.work, traj.tips()])


def write_trajectory(traj, path: os.PathLike) -> Path:
    """Write a :class:`~skewpend.integrate.Trajectory` to ``.csv`` or ``.nc`` (NetCDF 3 via xarray).

    The file appears only when complete (written to a temporary file, then renamed).
    A trajectory holding non-finite numbers is refused.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".nc"):
        raise ParameterError(f"unknown output format {path.suffix!r} for {path}; allowed: .csv, .nc")
    table = _table(traj)
    if not np.all(np.isfinite(table)):
        raise SkewpendError("refusing to write non-finite values")
    with atomic_path(path) as tmp:
        if suffix == ".csv":
            np.savetxt(tmp, table, delimiter=",", header=",".join(CSV_COLUMNS), comments="", fmt="%.17g")
        else:
            _to_dataset(traj, table).to_netcdf(tmp, engine="scipy", format="NETCDF3_64BIT")
    return path


def _to_dataset(traj, table: np.ndarray):
    try:
        import xarray as xr
    except ImportError:  # pragma: no cover - depends on the installation
        raise SkewpendError("writing .nc needs xarray: pip install 'skewpend[netcdf]'") from None
    from . import __version__

    data = {name: ("t", table[:, i]) for i, name in enumerate(CSV_COLUMNS) if name != "t"}
    ds = xr.Dataset(data, coords={"t": traj.t})
    units = {"phi": "rad", "psi": "rad", "dphi": "rad/s", "dpsi": "rad/s", "energy": "J", "work": "J", "t": "s"}
    for name, unit in units.items():
        ds[name].attrs["units"] = unit
    for name in ("x1", "y1", "z1", "x2", "y2", "z2"):
        ds[name].attrs["units"] = "m"
    attrs: Dict[str, Any] = {
        "title": "skewpend trajectory of the skewed double pendulum",
        "skewpend_version": __version__,
        "method": traj.method,
        "status": traj.status,
        "message": traj.message,
        "energy_drift": traj.energy_drift,
    }
    for key, value in traj.params.to_dict().items():
        if value is not None:
            attrs[f"param_{key}"] = np.asarray(value, dtype=float) if isinstance(value, list) else float(value)
    for key, value in traj.settings.items():
        if value is not None:
            attrs[f"setting_{key}"] = value
    for key, value in traj.stats.items():
        attrs[f"stat_{key}"] = int(value) if isinstance(value, bool) else value
    ds.attrs.update(attrs)
    return ds


# -- configuration -----------------------------------------------------------------------------------
CONFIG_SECTIONS = {
    "parameters": {"a", "b", "m1", "m2", "alpha", "g", "c1", "c2", "tau1", "tau2", "com1", "com2", "inertia1", "inertia2", "axis1", "axis2"},
    "initial": {"phi0", "psi0", "dphi0", "dpsi0"},
    "simulation": {"t_end", "dt_out", "method", "rtol", "atol", "dt", "out"},
}


def read_config(path: os.PathLike) -> Dict[str, Dict[str, Any]]:
    """Read a run configuration (TOML) with sections ``parameters``, ``initial``, ``simulation``.

    Values are returned as written (angles may be strings such as ``"30deg"``); unknown
    sections or keys are an error.
    """
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
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"config file {path} is not valid TOML: {exc}") from None
    for section, values in data.items():
        if section not in CONFIG_SECTIONS:
            raise ParameterError(f"{path}: unknown section [{section}]; allowed: {', '.join(CONFIG_SECTIONS)}")
        if not isinstance(values, dict):
            raise ParameterError(f"{path}: [{section}] must be a table")
        unknown = sorted(set(values) - CONFIG_SECTIONS[section])
        if unknown:
            raise ParameterError(
                f"{path}: unknown key(s) {unknown} in [{section}]; allowed: {sorted(CONFIG_SECTIONS[section])}"
            )
    return {s: dict(data.get(s, {})) for s in CONFIG_SECTIONS}
