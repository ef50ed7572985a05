"""One door for every result skewpend writes: :func:`open_result`.

A result file says what it holds in its attribute ``kind`` (:attr:`ResultProtocol.result_kind`,
written by the result protocol); :func:`open_result` recognises the container by its content
(NetCDF/HDF5 signature, a Zarr group, skewpend's trajectory CSV header), reads ``kind`` and hands
the path to that kind's reader, which returns the same result class with its data, ``params``,
``settings``, ``stats``, ``status`` and ``message``.

Each kind reads itself back in the module that writes it (xarray's backends register themselves
the same way): :data:`READERS` maps a kind to ``"module:function"``, imported on first use, so
that this module imports no analysis.  A reader of a ``*.nc`` file is a function
``build(path, variables, attrs)`` under :func:`skewpend.results.netcdf_reader`; the grid results
read complete ``*.zarr`` stores too (their ``open_*`` functions).  The shared pieces --
recognising the container, ``params``/``settings``/``stats``/``status``/``message``, and
:func:`~skewpend.results.agree` with :data:`AGREEMENT` -- live beside the result protocol in
:mod:`skewpend.results`.

Where a file holds only part of an object (the linearisation of an equilibrium, the monodromy
matrices of a family of orbits, the full states of a Poincare section's crossings), its reader
recomputes the missing part from the parameters and the stored data, and checks what the file
stores against it to :data:`AGREEMENT` (relative to each quantity's scale): a file written by
another model -- edited parameters, another version of the equations -- is one
:class:`~skewpend.errors.ParameterError`, never a silently inconsistent object.  Stored arrays
are returned exactly as stored.
"""

from __future__ import annotations

from importlib import import_module
from pathlib import Path
from typing import Any, Callable, Dict, Tuple

from ..errors import ParameterError
from ..results import AGREEMENT, netcdf_kind, result_container, zarr_store_kind

__all__ = ["open_result", "result_kinds", "reader", "READERS", "AGREEMENT"]

#: The reader of each result kind (the file attribute ``kind``): ``"module:function"`` in the module
#: that writes the kind, called as ``function(path)``.
READERS: Dict[str, str] = {
    "skewpend trajectory": "skewpend.numeric.simulation:read_trajectory_result",
    "Lyapunov spectrum": "skewpend.analysis.lyapunov:read_lyapunov_spectrum",
    "Lyapunov map": "skewpend.analysis.lyapunov:open_lyapunov_map",
    "normal modes": "skewpend.analysis.modes:read_normal_modes",
    "modes sweep": "skewpend.analysis.modes:read_modes_sweep",
    "flip map": "skewpend.analysis.flipmap:open_flip_map",
    "chain flip map": "skewpend.analysis.flipmap:open_flip_map",  # a chain's, written before flip maps were one
    "equilibria": "skewpend.analysis.equilibria:read_equilibria",
    "periodic orbit": "skewpend.analysis.orbits:read_periodic_orbit",
    "nonlinear normal mode": "skewpend.analysis.orbits:read_nnm",
    "nonlinear normal mode along alpha": "skewpend.analysis.orbits:read_nnm_alpha",
    "Poincare section": "skewpend.analysis.poincare:read_poincare_section",
    "region of attraction": "skewpend.analysis.roa:open_region_of_attraction",
    "chaos diagram": "skewpend.analysis.chaos:open_chaos_diagram",  # the caller's parameters: recorded by store and file
    "identification": "skewpend.analysis.identify:read_identification",
}


def reader(kind: str) -> Callable[[Any], Any]:
    """The reader ``function(path)`` of a result kind (its module imported now)."""
    module, _, name = READERS[kind].partition(":")
    return getattr(import_module(module), name)


def _store_kinds() -> Dict[str, str]:
    """Zarr store kind -> result kind, from the jobs that write them."""
    from .chaos import STORE_KIND as CHAOS
    from .flipmap import FORMER_STORE_KIND as CHAIN_FLIP, STORE_KIND as FLIP
    from .lyapunov import LyapunovMapJob
    from .roa import STORE_KIND as ROA

    return {FLIP: "flip map", CHAIN_FLIP: "chain flip map", CHAOS: "chaos diagram", LyapunovMapJob.kind: "Lyapunov map", ROA: "region of attraction"}


def result_kinds() -> Tuple[str, ...]:
    """Every result kind :func:`open_result` reads (the file attribute ``kind``)."""
    return tuple(READERS)


def open_result(path):
    """The result stored at ``path``, whatever its kind: a trajectory (``.nc`` or ``.csv``), a
    Lyapunov spectrum or map, normal modes or a modes sweep, a flip map, equilibria, a periodic
    orbit, a nonlinear normal mode (in energy or along alpha), a Poincare section, a region of
    attraction, a chaos diagram or an identification -- written by ``to_netcdf(path)``
    (``*.nc``), a complete store ``*.zarr`` of a grid computation, or
    ``simulate(..., out="run.csv")``.

    The container is recognised by its content and the kind by the file's ``kind`` attribute;
    the result comes back as the class that wrote it, with its data, ``params``, ``settings``,
    ``stats``, ``status`` and ``message``.  Parts a file does not hold (the linearisation of
    equilibria, the monodromy matrices of a family of orbits, the full states of a section's
    crossings, ...) are recomputed from the parameters and checked against what is stored (to
    :data:`AGREEMENT` relative): a file written by another model is refused.

    Anything else -- a missing, empty or truncated file, a file or directory skewpend did not
    write, an unknown kind, a JSON or CSV export that keeps only part of a result -- is one
    :class:`~skewpend.errors.ParameterError` line.

    >>> import os, tempfile, skewpend
    >>> path = os.path.join(tempfile.mkdtemp(), "modes.nc")
    >>> modes = skewpend.normal_modes(skewpend.reference_parameters())
    >>> _ = modes.to_netcdf(path)
    >>> back = skewpend.open_result(path)
    >>> type(back).__name__, bool((back.frequencies == modes.frequencies).all())
    ('Modes', True)
    """
    if isinstance(path, bool) or not isinstance(path, (str, bytes)) and not hasattr(path, "__fspath__"):
        raise ParameterError(f"path must be a file name, got {path!r}")
    path = Path(path.decode() if isinstance(path, bytes) else path)
    container = result_container(path)
    if container == "netcdf":
        kind = netcdf_kind(path)
        if kind is None:
            raise ParameterError(f"{path} is a NetCDF file, but not a result of skewpend (it has no 'kind' attribute)")
    elif container == "zarr":
        store_kind = zarr_store_kind(path)
        kind = _store_kinds().get(str(store_kind))
        if kind is None:
            raise ParameterError(f"{path} is a skewpend store of kind {store_kind!r}, which open_result cannot read; "
                                 f"it reads stores of {', '.join(sorted(_store_kinds()))}")
    else:
        from ..io import has_trajectory_metadata

        if not has_trajectory_metadata(path):  # run.csv.json beside it (an older CSV: its "# key: value" lines)
            raise ParameterError(f"{path} is a trajectory CSV without its metadata file {path.name}.json beside it (how "
                                 "the run was made): keep the two files together")
        kind = "skewpend trajectory"
    if str(kind) not in READERS:
        raise ParameterError(f"{path} holds a result of kind {str(kind)!r}, which this version of skewpend cannot read "
                             f"back; known kinds: {', '.join(READERS)}")
    return reader(str(kind))(path)
