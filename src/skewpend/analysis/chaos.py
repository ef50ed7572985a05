"""How the skew angle changes chaos: the chaos diagram over (alpha, energy).

For each skew angle ``alpha`` and each energy ``E`` above the minimum of the potential, the
diagram samples ``samples`` initial conditions on that energy surface -- spread over the
Poincare section ``phi = 0`` (crossed with ``phi' > 0``) by a Halton sequence, as
:func:`~skewpend.analysis.poincare.poincare` seeds its orbits -- and measures the largest
Lyapunov exponent of each over ``t_end`` seconds (one tangent vector, Benettin).  The fraction
of them whose exponent is *clearly positive* (above ``threshold``) is the chaotic fraction of
that energy surface.  Regular orbits have finite-time exponents of order ``ln(t_end)/t_end``;
chaotic ones of order the inverse of the swing time; the default threshold sits between:
``max(0.1 omega_low, 4 ln(t_end)/t_end)``, with ``omega_low`` the lower small-oscillation
frequency at ``alpha = 0`` (from the generated Jacobian at rest).

The work is cut into rows (one ``alpha`` each) on the ensemble engine: local threads, or tasks
on a Dask cluster (``scheduler=``), with a resumable Zarr store (``store=``, ``resume=``) written
row chunk by row chunk -- the same machinery and guarantees as the flip map: bitwise the same
result whatever the workers, the chunking or the cluster.
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Optional, Sequence

import numpy as np

from ..errors import ParameterError
from ..symbolic.model import Parameters
from .lyapunov import MAX_STEPS, _check_max_steps, _check_params, _check_times, _check_tolerances, largest_exponents

__all__ = ["chaos_diagram", "ChaosDiagram", "open_chaos_diagram", "default_threshold", "STORE_KIND"]

STORE_KIND = "chaos-diagram"
#: Statistics per row (and per store chunk).
CHUNK_STATS = ("trajectories", "failed", "unreachable", "steps", "wall_time")
_MAX_CELLS = 1_000_000  # alpha x energy x samples trajectories at most


@dataclass(frozen=True)
class ChaosDiagram:
    """The result of :func:`chaos_diagram`.

    * ``alpha`` -- shape ``(na,)`` [rad]; ``energy`` -- shape ``(ne,)`` [J above the minimum of
      the potential at that alpha];
    * ``exponent`` -- shape ``(na, ne, samples)``: the largest Lyapunov exponent [1/s] of each
      sampled start (NaN: the start could not be placed on the surface, or its integration
      failed);
    * ``threshold`` [1/s]: exponents above it count as chaotic;
    * ``fraction`` -- shape ``(na, ne)``: the chaotic fraction of the valid samples;
    * ``params`` (alpha replaced row by row), ``settings``, ``stats``.
    """

    alpha: np.ndarray
    energy: np.ndarray
    exponent: np.ndarray
    threshold: float
    params: Parameters
    settings: Dict[str, Any]
    stats: Dict[str, Any] = field(default_factory=dict)

    @property
    def valid(self) -> np.ndarray:
        return np.count_nonzero(np.isfinite(self.exponent), axis=2)

    @property
    def fraction(self) -> np.ndarray:
        chaotic = np.count_nonzero(np.nan_to_num(self.exponent, nan=-np.inf) > self.threshold, axis=2)
        valid = self.valid
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(valid > 0, chaotic / np.maximum(valid, 1), np.nan)

    @property
    def mean_exponent(self) -> np.ndarray:
        out = np.full(self.exponent.shape[:2], np.nan)
        ok = self.valid > 0
        out[ok] = np.nanmean(self.exponent[ok], axis=-1)
        return out

    def table(self) -> str:
        """The chaotic fractions as a text table: rows alpha [deg], columns energy [J]."""
        head = "alpha\\E [J] " + " ".join(f"{e:>6.3g}" for e in self.energy)
        lines = [head]
        for i, a in enumerate(self.alpha):
            cells = " ".join("   nan" if not np.isfinite(f) else f"{f:6.2f}" for f in self.fraction[i])
            lines.append(f"{math.degrees(a):8.1f} deg " + cells)
        return "\n".join(lines)

    def to_xarray(self):
        """An :class:`xarray.Dataset`: ``exponent`` on (alpha, energy, sample), ``fraction`` and
        ``mean_exponent`` on (alpha, energy), the settings as attributes."""
        import xarray as xr

        return xr.Dataset(
            {
                "exponent": (("alpha", "energy", "sample"), self.exponent, _VARIABLES["exponent"]),
                "fraction": (("alpha", "energy"), self.fraction, _VARIABLES["fraction"]),
                "mean_exponent": (("alpha", "energy"), self.mean_exponent, {"units": "1/s"}),
            },
            coords={"alpha": ("alpha", self.alpha, _VARIABLES["alpha"]),
                    "energy": ("energy", self.energy, _VARIABLES["energy"]),
                    "sample": ("sample", np.arange(self.exponent.shape[2]))},
            attrs={"title": "chaos diagram of the skewed double pendulum (skewpend)", "threshold": self.threshold,
                   "settings": json.dumps(self.settings), "params": json.dumps(self.params.to_dict())},
        )

    def to_netcdf(self, path) -> None:
        """:meth:`to_xarray` as NetCDF4 (netCDF4 engine), written atomically."""
        from ..io import atomic_path, require_netcdf

        require_netcdf()
        with atomic_path(path) as tmp:
            self.to_xarray().to_netcdf(tmp, engine="netcdf4")


_VARIABLES = {
    "exponent": {"units": "1/s", "long_name": "largest Lyapunov exponent of a start on the energy surface"},
    "fraction": {"units": "1", "long_name": "fraction of starts with a clearly positive largest exponent"},
    "alpha": {"units": "rad", "long_name": "skew angle of the second hinge axis"},
    "energy": {"units": "J", "long_name": "energy above the minimum of the potential"},
    "sample": {"long_name": "index of the start on the energy surface"},
}


def _omega_low(params: Parameters) -> float:
    """The lower small-oscillation angular frequency [rad/s] at rest (0 if none: g = 0)."""
    from ..numeric.kernels import kernel_module, parameter_vector

    kernel = kernel_module(params, chaos=True)
    J = np.zeros(25)
    kernel.jac(np.zeros(5), parameter_vector(params), J)
    ev = np.linalg.eigvals(J.reshape(5, 5)[:4, :4])
    w = np.abs(ev.imag)
    w = w[w > 1e-9]
    return float(w.min()) if w.size else 0.0


def default_threshold(params: Parameters, t_end: float) -> float:
    """``max(0.1 omega_low, 4 ln(t_end) / t_end)`` [1/s]; ``omega_low`` at ``alpha = 0``."""
    base = params.replace(alpha=0.0) if params.uses_alpha else params
    return max(0.1 * _omega_low(base), 4.0 * math.log(max(t_end, math.e)) / t_end)


def potential_range(params: Parameters) -> float:
    """The potential energy's span [J] over the torus (at ``params``' alpha): a natural top energy."""
    from ..numeric.kernels import kernel_module, parameter_vector
    from .poincare import _potential

    kernel = kernel_module(params, chaos=True)
    u = np.linspace(-math.pi, math.pi, 181)
    Q = np.array(np.meshgrid(u, u, indexing="ij")).reshape(2, -1).T
    V = _potential(kernel, parameter_vector(params), Q)
    return float(V.max() - V.min())


@dataclass(frozen=True)
class _Job:
    """What computing rows needs: small and picklable (sent with each cluster task)."""

    params: Parameters
    alpha: tuple
    energy: tuple
    samples: int
    t_end: float
    renorm_every: float
    transient: float
    rtol: float
    atol: float
    max_steps: int
    version: str


def _compute_row(job: _Job, i: int, cancel=None):
    """Row ``i`` (one alpha): ``(i, exponents (ne, samples), stats)``."""
    from ..numeric.kernels import kernel_module, parameter_vector
    from .poincare import EnergySurface, energy_minimum, section_seeds

    start = time.perf_counter()
    params = job.params.replace(alpha=float(job.alpha[i]))
    kernel = kernel_module(params, chaos=True)
    p = parameter_vector(params)
    e_min, _ = energy_minimum(kernel, p)
    ne, S = len(job.energy), job.samples
    out = np.full((ne, S), np.nan)
    stats = np.zeros(len(CHUNK_STATS))
    for j, de in enumerate(job.energy):
        surface = EnergySurface(kernel, p, e_min + float(de), 0, 0.0, e_min)
        v_section, _ = surface.bounds()
        if v_section >= surface.energy:
            stats[2] += S
            continue
        seeds = section_seeds(surface, S)
        stats[2] += S - seeds.shape[0]
        if seeds.shape[0] == 0:
            continue
        starts = surface.states(seeds[:, 0], seeds[:, 1], +1)
        lam, status, steps = largest_exponents(kernel, p, starts, t_end=job.t_end, renorm_every=job.renorm_every,
                                               transient=job.transient, rtol=job.rtol, atol=job.atol,
                                               max_steps=job.max_steps, cancel=cancel)
        out[j, : lam.size] = lam
        stats[0] += lam.size
        stats[1] += int(np.count_nonzero(status != 0))
        stats[3] += int(steps.sum())
    stats[4] = time.perf_counter() - start
    return i, out, stats


def _cluster_task(job: _Job, rows: Sequence[int]) -> list:
    from .. import __version__
    from ..errors import SkewpendError

    if __version__ != job.version:
        raise SkewpendError(f"a worker has skewpend {__version__}, this run {job.version}: install the same skewpend on every worker")
    return [_compute_row(job, i) for i in rows]


def _settings(params, alpha, energy, samples, t_end, renorm_every, transient, threshold, rtol, atol, max_steps):
    from .. import __version__

    return {
        "params": params.replace(alpha=0.0).to_dict() if params.uses_alpha else params.to_dict(),
        "alpha": [float(a) for a in alpha], "energy": [float(e) for e in energy], "samples": int(samples),
        "t_end": t_end, "renorm_every": renorm_every, "transient": transient, "threshold": threshold,
        "rtol": rtol, "atol": atol, "max_steps": int(max_steps), "section": "phi=0", "direction": 1,
        "seeds": "halton", "skewpend_version": __version__,
    }


def chaos_diagram(
    params: Parameters,
    *,
    alpha: Optional[Sequence[float]] = None,
    n_alpha: int = 7,
    energy: Optional[Sequence[float]] = None,
    n_energy: int = 8,
    samples: int = 24,
    t_end: float = 150.0,
    renorm_every: float = 1.0,
    transient: float = 0.0,
    threshold: Optional[float] = None,
    rtol: Optional[float] = 1e-8,
    atol: Optional[float] = 1e-8,
    max_steps: int = MAX_STEPS,
    workers: Optional[int] = None,
    progress: Optional[Callable[[int, int], None]] = None,
    store=None,
    resume: bool = False,
    scheduler=None,
) -> ChaosDiagram:
    """The chaotic fraction of the energy surfaces over ``alpha x energy``.

    ``alpha``: the skew angles [rad] (default ``n_alpha`` from 0 to 90 deg); ``energy``: the
    energies above the minimum of the potential [J] (default ``n_energy`` evenly up to the
    potential's span, the energy at which both rods can stand upside down).  ``samples``
    starts per cell on the section ``phi = 0``; each start's largest exponent over ``t_end`` s
    (renormalised every ``renorm_every``, the first ``transient`` s not counted) at
    ``rtol``/``atol`` (default 1e-8); ``threshold`` [1/s] (default :func:`default_threshold`).
    ``params`` gives everything but alpha, and must not fix the second axis itself.

    ``workers``, ``progress(done_rows, total_rows)``, ``store`` (``*.zarr``), ``resume`` and
    ``scheduler`` work as for :func:`~skewpend.analysis.flipmap.flip_map`.
    """
    from .flipmap import _check_workers
    from .poincare import _require_conservative

    if not isinstance(params, Parameters):
        raise ParameterError(f"params must be a skewpend.Parameters, got {type(params).__name__}")
    if params.uses_alpha and params.alpha is None:  # alpha is the diagram's own axis
        params = params.replace(alpha=0.0)
    params = _check_params(params, "a chaos diagram")
    if not params.uses_alpha:
        raise ParameterError("a chaos diagram varies alpha, but params fix the second hinge axis (axis2) directly; "
                             "leave axis2 at its default to use alpha")
    _require_conservative(params, "a chaos diagram")
    alphas = _grid("alpha", alpha, n_alpha, 0.0, math.pi / 2, lo_open=False)
    if np.any(np.abs(alphas) > 2 * math.pi):
        raise ParameterError("alpha values must be angles in radians within [-2 pi, 2 pi]")
    t_end, renorm_every, transient = _check_times(t_end, renorm_every, transient)
    if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or not 1 <= samples <= 100_000:
        raise ParameterError(f"samples must be a whole number from 1 to 100000, got {samples!r}")
    rtol, atol = _check_tolerances(rtol, atol)
    max_steps = _check_max_steps(max_steps)
    explicit_workers = workers
    workers = _check_workers(workers)
    if progress is not None and not callable(progress):
        raise ParameterError("progress must be a callable progress(done_rows, total_rows)")
    if energy is None:
        top = potential_range(params.replace(alpha=0.0))
        if not top > 0:
            raise ParameterError("the potential energy is flat (g = 0?): give the energies explicitly")
    else:
        top = 1.0
    energies = _grid("energy", energy, n_energy, 0.0, top, lo_open=True)
    if np.any(energies <= 0):
        raise ParameterError("energy values must be positive (joules above the minimum of the potential)")
    n_cells = alphas.size * energies.size * int(samples)
    if n_cells > _MAX_CELLS:
        raise ParameterError(f"alpha x energy x samples = {n_cells} trajectories is too many (at most {_MAX_CELLS})")
    if threshold is None:
        threshold = default_threshold(params, t_end)
    else:
        try:
            threshold = float(threshold)
        except (TypeError, ValueError):
            raise ParameterError(f"threshold must be a positive number [1/s], got {threshold!r}") from None
        if not (math.isfinite(threshold) and threshold > 0):
            raise ParameterError(f"threshold must be a positive number [1/s], got {threshold!r}")
    if resume not in (True, False):
        raise ParameterError(f"resume must be True or False, got {resume!r}")
    if resume and store is None:
        raise ParameterError("resume needs a store: the path of the .zarr store to continue")
    if scheduler is not None and explicit_workers is not None:
        raise ParameterError("give workers or scheduler, not both (a cluster's workers run the rows)")

    from .. import __version__
    from .flipmap import fingerprint

    settings = _settings(params, alphas, energies, samples, t_end, renorm_every, transient, threshold, rtol, atol,
                         max_steps)
    fp = fingerprint(settings)
    store_path = None
    if store is not None:
        from ..numeric.store import store_target

        store_path, exists = store_target(store, resume=resume, what="a chaos diagram store")
        if exists:
            _open_store(store_path, settings, fp, writable=False).close()
    if scheduler is not None:
        from ..numeric.ensemble import check_scheduler, require_distributed

        check_scheduler(scheduler)
        require_distributed()

    from ..numeric.ensemble import connect_scheduler, run_chunks

    start = time.perf_counter()
    na, ne, S = alphas.size, energies.size, int(samples)
    job = _Job(params=params, alpha=tuple(alphas.tolist()), energy=tuple(energies.tolist()), samples=S, t_end=t_end,
               renorm_every=renorm_every, transient=transient, rtol=rtol, atol=atol, max_steps=max_steps,
               version=__version__)
    exponent = np.full((na, ne, S), np.nan)
    row_stats = np.zeros((na, len(CHUNK_STATS)))
    client, owned = (connect_scheduler(scheduler) if scheduler is not None else (None, False))
    st = None
    try:
        if store_path is not None:
            if os.path.lexists(store_path):
                st = _open_store(store_path, settings, fp, writable=True)
            else:
                st = _template(store_path, settings, fp, alphas, energies, S)
            done = st.done()
            if done.any():
                exponent[done] = st.read("exponent")[done]
                row_stats[done] = st.chunk_stats()[done]
        else:
            done = np.zeros(na, dtype=bool)
        resumed = int(done.sum())
        todo = [i for i in range(na) if not done[i]]
        count = [resumed]
        if progress is not None:
            progress(count[0], na)

        def collect(result):
            i, row, stats = result
            exponent[i], row_stats[i] = row, stats
            if st is not None:
                st.write_chunk(i, {"exponent": row[None], "fraction": _fraction(row, threshold)[None]}, stats)
            count[0] += 1
            if progress is not None:
                progress(count[0], na)

        if client is None:
            run_chunks(len(todo), lambda k, cancel: _compute_row(job, todo[k], cancel), workers=workers,
                       on_done=lambda k, result: collect(result), keep=False)
            threads = workers
        else:
            from ..numeric.ensemble import batches, cluster_threads, run_on_cluster

            threads = cluster_threads(client)
            tasks = batches(todo)

            def collect_task(k, results):
                for result in results:
                    collect(result)

            run_on_cluster(client, _cluster_task, [(job, b) for b in tasks], on_done=collect_task,
                           name="skewpend-chaos-diagram")
        totals = row_stats.sum(axis=0)
        stats = {
            "trajectories": int(totals[0]), "failed": int(totals[1]), "unreachable": int(totals[2]),
            "steps": int(totals[3]), "wall_time": time.perf_counter() - start, "workers": threads,
            "rows_resumed": resumed, "rows_computed": len(todo), "store": None if store_path is None else str(store_path),
            "scheduler": None if client is None else str(client.scheduler.address), "fingerprint": fp,
        }
        if st is not None:
            st.set_attrs(complete=True, chaos_diagram_stats=json.dumps(stats))
    finally:
        if st is not None:
            st.close()
        if owned:
            client.close(timeout=5)
    return ChaosDiagram(alpha=alphas, energy=energies, exponent=exponent, threshold=float(threshold), params=params,
                        settings=settings, stats=stats)


def _fraction(row: np.ndarray, threshold: float) -> np.ndarray:
    valid = np.count_nonzero(np.isfinite(row), axis=-1)
    chaotic = np.count_nonzero(np.nan_to_num(row, nan=-np.inf) > threshold, axis=-1)
    return np.where(valid > 0, chaotic / np.maximum(valid, 1), np.nan)


def _grid(name, values, n, lo, hi, *, lo_open: bool) -> np.ndarray:
    if values is not None:
        try:
            arr = np.asarray(values, dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise ParameterError(f"{name} must be a list of numbers, got {values!r}") from None
        if arr.size == 0 or arr.size > 1000 or not np.all(np.isfinite(arr)):
            raise ParameterError(f"{name} must be 1 to 1000 finite numbers, got {arr.size}")
        if np.any(np.diff(arr) <= 0):
            raise ParameterError(f"{name} values must be increasing")
        return arr
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 1000:
        raise ParameterError(f"n_{name} must be a whole number from 1 to 1000, got {n!r}")
    if lo_open:
        return lo + (hi - lo) * np.arange(1, n + 1) / n
    return np.linspace(lo, hi, n) if n > 1 else np.array([lo])


def _template(path, settings, fp, alphas, energies, samples):
    from ..numeric.store import RowStore

    return RowStore.create(
        path, kind=STORE_KIND, shape=(alphas.size, energies.size), chunk_rows=1, dims=("alpha", "energy"),
        arrays={"exponent": ("float64", np.nan, _VARIABLES["exponent"], True),
                "fraction": ("float64", np.nan, _VARIABLES["fraction"])},
        coords={"alpha": (alphas, _VARIABLES["alpha"]), "energy": (energies, _VARIABLES["energy"])},
        extra=("sample", np.arange(samples, dtype=float), _VARIABLES["sample"]),
        stats=CHUNK_STATS,
        attrs={"title": "chaos diagram of the skewed double pendulum (skewpend)", "fingerprint": fp,
               "settings": json.dumps(settings, sort_keys=True), "threshold": settings["threshold"]},
    )


def _open_store(path, settings, fp, *, writable):
    from ..numeric.store import RowStore

    return RowStore.open_matching(path, kind=STORE_KIND, fingerprint=fp, settings=settings, writable=writable)


def open_chaos_diagram(path) -> ChaosDiagram:
    """A :class:`ChaosDiagram` read back from a complete store ``*.zarr``."""
    from ..numeric.store import RowStore, check_store_path

    path = check_store_path(path, option="path")
    with RowStore.open(path, kind=STORE_KIND) as st:
        attrs = st.attrs
        if not attrs.get("complete"):
            raise ParameterError(f"{path} is not complete: resume the run that made it (--resume)")
        settings = json.loads(attrs["settings"])
        exponent = st.read("exponent")
        stats = json.loads(attrs.get("chaos_diagram_stats", "{}"))
    params = Parameters.from_mapping(settings["params"])
    return ChaosDiagram(alpha=np.asarray(settings["alpha"]), energy=np.asarray(settings["energy"]), exponent=exponent,
                        threshold=float(settings["threshold"]), params=params, settings=settings, stats=stats)
