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

The work is cut into rows (one ``alpha`` each) on the grid driver, with the flip map's options and
guarantees (``store=``, ``resume=``, ``scheduler=``: bitwise the same whatever the workers or the chunking).
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from typing import Callable, ClassVar, Optional, Sequence, Tuple

import numpy as np

from ..errors import ParameterError
from ..numeric.grid import ArraySpec, GridJob, check_run_options, read_grid_result
from ..results import DatasetSpec, Result, canonical_json, grid_status
from ..symbolic.model import Parameters
from ..checks import MAX_STEPS, max_steps as check_max_steps, not_parameters, numeric_params, tolerances, whole
from .lyapunov import check_exponent_work, check_times, largest_exponents
from .poincare import ENERGY_LIMIT, EnergySurface, energy_minimum, mass_matrices, potential, section_seeds

__all__ = ["chaos_diagram", "ChaosDiagram", "ChaosJob", "open_chaos_diagram", "default_threshold", "STORE_KIND"]

STORE_KIND = "chaos-diagram"
#: Statistics per row (and per store chunk).
CHUNK_STATS = ("trajectories", "failed", "unreachable", "steps", "rejected", "wall_time")
_MAX_CELLS = 1_000_000  # alpha x energy x samples trajectories at most


@dataclass(frozen=True)
class ChaosDiagram(Result):
    """The result of :func:`chaos_diagram`.

    * ``alpha`` -- shape ``(na,)`` [rad]; ``energy`` -- shape ``(ne,)`` [J above the minimum of
      the potential at that alpha];
    * ``exponent`` -- shape ``(na, ne, samples)``: the largest Lyapunov exponent [1/s] of each
      sampled start (NaN: the start could not be placed on the surface, or its integration
      failed);
    * ``threshold`` [1/s]: exponents above it count as chaotic;
    * ``fraction`` -- shape ``(na, ne)``: the chaotic fraction of the valid samples;
    * the result protocol's fields: ``params`` (alpha replaced row by row), ``stats`` (``trajectories``,
      ``failed``, ``unreachable``, ``steps``, ``rejected``; the run's rows, store and cluster), ``status``
      (PARTIAL when trajectories failed).
    """

    alpha: np.ndarray
    energy: np.ndarray
    exponent: np.ndarray
    threshold: float

    result_kind: ClassVar[str] = "chaos diagram"

    @property
    def valid(self) -> np.ndarray:
        return np.count_nonzero(np.isfinite(self.exponent), axis=2)

    @property
    def fraction(self) -> np.ndarray:
        return _fraction(self.exponent, self.threshold)

    @property
    def mean_exponent(self) -> np.ndarray:
        out = np.full(self.exponent.shape[:2], np.nan)
        ok = self.valid > 0
        out[ok] = np.nanmean(self.exponent[ok], axis=-1)
        return out

    def table(self) -> str:
        """The chaotic fractions as a text table: rows alpha [deg], columns energy [J]; a cell
        without a single valid sample shows ``--``."""
        head = "alpha\\E [J] " + " ".join(f"{e:>6.3g}" for e in self.energy)
        lines = [head]
        for i, a in enumerate(self.alpha):
            cells = " ".join("    --" if not np.isfinite(f) else f"{f:6.2f}" for f in self.fraction[i])
            lines.append(f"{math.degrees(a):8.1f} deg " + cells)
        return "\n".join(lines)

    def _dataset(self) -> DatasetSpec:
        """``exponent`` on (alpha, energy, sample), ``fraction`` and ``mean_exponent`` on
        (alpha, energy), the protocol's attributes and the threshold."""
        return DatasetSpec(
            variables={
                "exponent": (("alpha", "energy", "sample"), self.exponent, dict(_VARIABLES["exponent"])),
                "fraction": (("alpha", "energy"), self.fraction, dict(_VARIABLES["fraction"])),
                "mean_exponent": (("alpha", "energy"), self.mean_exponent, {"units": "1/s"}),
            },
            coords={"alpha": (("alpha",), self.alpha, dict(_VARIABLES["alpha"])),
                    "energy": (("energy",), self.energy, dict(_VARIABLES["energy"])),
                    "sample": (("sample",), np.arange(self.exponent.shape[2]), dict(_VARIABLES["sample"]))},
            attrs={"title": ChaosJob.title, "threshold": self.threshold, **self._base_attrs()},
        )


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
    with np.errstate(all="ignore"):
        kernel.jac(np.zeros(5), parameter_vector(params), J)
    if not np.all(np.isfinite(J)):
        raise ParameterError("the linearised equations at rest are not finite for these parameters (a mass, length "
                             "or inertia too small or too large for double precision); use values of moderate size")
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

    kernel = kernel_module(params, chaos=True)
    u = np.linspace(-math.pi, math.pi, 181)
    Q = np.array(np.meshgrid(u, u, indexing="ij")).reshape(2, -1).T
    V = potential(kernel, parameter_vector(params), Q)
    return float(V.max() - V.min())


@dataclass(frozen=True)
class ChaosJob(GridJob):
    """A chaos diagram as a job of the grid driver: one row per alpha (small and picklable)."""

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
    threshold: float = math.nan

    kind: ClassVar[str] = STORE_KIND
    what: ClassVar[str] = "a chaos diagram"
    stat_names: ClassVar[Tuple[str, ...]] = CHUNK_STATS
    title: ClassVar[str] = "chaos diagram of the skewed double pendulum (skewpend)"

    def shape(self):
        return len(self.alpha), len(self.energy)

    def arrays(self):
        return {"exponent": ArraySpec("float64", np.nan, _VARIABLES["exponent"], trailing=True),
                "fraction": ArraySpec("float64", np.nan, _VARIABLES["fraction"])}

    def coords(self):
        return {"alpha": (np.asarray(self.alpha, dtype=float), _VARIABLES["alpha"]),
                "energy": (np.asarray(self.energy, dtype=float), _VARIABLES["energy"])}

    def trailing(self):
        return "sample", np.arange(self.samples, dtype=float), _VARIABLES["sample"]

    def settings(self):
        params = self.params
        return {
            "params": params.replace(alpha=0.0).to_dict() if params.uses_alpha else params.to_dict(),
            "alpha": [float(a) for a in self.alpha], "energy": [float(e) for e in self.energy],
            "samples": int(self.samples), "t_end": self.t_end, "renorm_every": self.renorm_every,
            "transient": self.transient, "threshold": self.threshold, "rtol": self.rtol, "atol": self.atol,
            "max_steps": int(self.max_steps), "section": "phi=0", "direction": 1, "seeds": "halton",
            "skewpend_version": self.version,
        }

    def store_attrs(self):
        return {"threshold": self.threshold}

    def chunk_rows(self, chunk_size):
        return 1

    def progress_per_row(self):
        return 1

    def compute(self, state, rows, cancel=None):
        ne, S = len(self.energy), self.samples
        exponent = np.full((rows.size, ne, S), np.nan)
        stats = np.zeros((rows.size, len(CHUNK_STATS)))
        for r, i in enumerate(rows.tolist()):
            exponent[r], stats[r] = self._row(i, cancel)
        return {"exponent": exponent, "fraction": _fraction(exponent, self.threshold)}, stats

    def _row(self, i: int, cancel=None):
        """Row ``i`` (one alpha): exponents ``(ne, samples)`` and statistics."""
        from ..numeric.kernels import kernel_module, parameter_vector

        start = time.perf_counter()
        params = self.params.replace(alpha=float(self.alpha[i]))
        kernel = kernel_module(params, chaos=True)
        p = parameter_vector(params)
        e_min, _ = energy_minimum(kernel, p)
        ne, S = len(self.energy), self.samples
        out = np.full((ne, S), np.nan)
        stats = np.zeros(len(CHUNK_STATS))
        for j, de in enumerate(self.energy):
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
            lam, status, steps, rejected = largest_exponents(
                kernel, p, starts, t_end=self.t_end, renorm_every=self.renorm_every, transient=self.transient,
                rtol=self.rtol, atol=self.atol, max_steps=self.max_steps, cancel=cancel)
            out[j, : lam.size] = lam
            stats[[0, 1, 3, 4]] += (lam.size, np.count_nonzero(status != 0), steps.sum(), rejected.sum())
        stats[5] = time.perf_counter() - start
        return out, stats

    def result(self, run) -> "ChaosDiagram":
        totals = run.totals(CHUNK_STATS)
        info = run.info
        stats = {
            **{k: int(totals[k]) for k in CHUNK_STATS if k != "wall_time"}, "wall_time": info["wall_time"],
            "workers": info["workers"], "rows_resumed": info["chunks_resumed"], "rows_computed": info["chunks_computed"],
            "rows_repaired": info["chunks_repaired"], "store": info["store"], "scheduler": info["scheduler"],
            "fingerprint": info["fingerprint"],
        }
        status, message = grid_status(stats["failed"], stats["trajectories"])
        if stats["unreachable"]:
            message += (f"; {stats['unreachable']} of the {len(self.alpha) * len(self.energy) * self.samples} starts "
                        "asked for could not be placed on their energy surface (the fractions count the others)")
        alphas, energies = (values for values, _ in self.coords().values())
        return ChaosDiagram(alpha=alphas, energy=energies, exponent=run.data["exponent"], threshold=float(self.threshold),
                            params=self.params, settings=self.settings(), stats=stats, status=status, message=message)

    def result_attrs(self, result):
        # the caller's parameters: the settings keep the grid's (alpha 0, replaced by each column's)
        return {"chaos_diagram_stats": canonical_json(result.stats),
                "chaos_diagram_params": canonical_json(result.params.to_dict())}


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
    ``scheduler`` work as for :func:`~skewpend.analysis.flipmap.flip_map` (a :class:`ChaosJob`
    on :func:`skewpend.numeric.grid.run_grid`).  Trajectories that fail make the diagram's
    ``status`` PARTIAL.
    """
    from .. import __version__
    from ..numeric.grid import run_grid  # looked up here: a test's stand-in for the driver is called
    exact = params.exact_model() if hasattr(params, "exact_model") else None  # a chain of two is the double pendulum
    if exact is None:
        raise ParameterError(not_parameters(params, "a chaos diagram"))
    params = exact
    if params.uses_alpha and params.alpha is None:  # alpha is the diagram's own axis
        params = params.replace(alpha=0.0)
    params = numeric_params(params, "a chaos diagram")
    if not params.uses_alpha:
        raise ParameterError("a chaos diagram varies alpha, but params fix the second hinge axis (axis2) directly; "
                             "leave axis2 at its default to use alpha")
    params.require_conservative("a chaos diagram")
    alphas = _grid("alpha", alpha, n_alpha, 0.0, math.pi / 2, lo_open=False)
    if np.any(np.abs(alphas) > 2 * math.pi):
        raise ParameterError("alpha values must be angles in radians within [-2 pi, 2 pi]")
    t_end, renorm_every, transient = check_times(t_end, renorm_every, transient)
    samples = whole("samples", samples, 1, 100_000)
    rtol, atol = tolerances(rtol, atol)
    max_steps = check_max_steps(max_steps)
    workers = check_run_options(workers=workers, scheduler=scheduler, store=store, resume=resume, progress=progress,
                                unit="rows")
    if energy is None:
        top = potential_range(params.replace(alpha=0.0))
        if not top > 0:
            raise ParameterError("the potential energy is flat (g = 0?): give the energies explicitly")
    else:
        top = 1.0
    energies = _grid("energy", energy, n_energy, 0.0, top, lo_open=True)
    if np.any(energies <= 0):
        raise ParameterError("energy values must be positive (joules above the minimum of the potential)")
    if np.any(energies > ENERGY_LIMIT):
        raise ParameterError(f"energy values must be at most {ENERGY_LIMIT:g} J, got {float(energies.max()):g}")
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
    _check_feasible(params.replace(alpha=float(alphas[-1])), float(energies[-1]), t_end=t_end, rtol=rtol, atol=atol,
                    max_steps=max_steps)
    job = ChaosJob(params=params, alpha=tuple(alphas.tolist()), energy=tuple(energies.tolist()), samples=int(samples),
                   t_end=t_end, renorm_every=renorm_every, transient=transient, rtol=rtol, atol=atol,
                   max_steps=max_steps, version=__version__, threshold=float(threshold))
    return run_grid(job, workers=workers, scheduler=scheduler, store=store, resume=bool(resume), progress=progress)


def _check_feasible(params: Parameters, energy: float, *, t_end: float, rtol: float, atol: float,
                    max_steps: int) -> None:
    """Refuse up front a diagram whose trajectories cannot finish within ``max_steps``: the trial
    runs start at rest high up and from the bottom with the top energy as kinetic energy."""
    from ..numeric.kernels import kernel_module, parameter_vector

    kernel = kernel_module(params, chaos=True)
    p = parameter_vector(params)
    e_min, q_min = energy_minimum(kernel, p)
    m11 = float(mass_matrices(kernel, p, np.asarray(q_min, dtype=float).reshape(1, 2))[0, 0, 0])
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        speed = math.sqrt(2.0 * energy / m11) if m11 > 0 and math.isfinite(energy / m11) else math.inf
    if not math.isfinite(speed):
        raise ParameterError(f"energy {energy:g} J is too large for these bodies (the speeds overflow)")
    probe = [(2.5, 2.5, 0.0, 0.0), (float(q_min[0]), float(q_min[1]), speed, 0.0)]
    check_exponent_work((kernel, p), probe, params=params, t_end=t_end, rtol=rtol, atol=atol, max_steps=max_steps,
                        what="this chaos diagram")


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
    n = whole(f"n_{name}", n, 1, 1000)
    if lo_open:
        return lo + (hi - lo) * np.arange(1, n + 1) / n
    return np.linspace(lo, hi, n) if n > 1 else np.array([lo])


def open_chaos_diagram(path) -> ChaosDiagram:
    """A :class:`ChaosDiagram` read back from a complete store ``*.zarr`` or a file ``*.nc``
    (:meth:`ChaosDiagram.to_netcdf`)."""
    def build(arrays, attrs, settings, stats):
        given = attrs.get("chaos_diagram_params") or attrs.get("params")  # the store's, the file's
        params = Parameters.from_mapping(json.loads(given) if given else settings["params"])
        exponent = np.asarray(arrays["exponent"], dtype=float)
        status, message = grid_status(int(stats.get("failed", 0)), int(stats.get("trajectories", exponent.size)))
        return ChaosDiagram(alpha=np.asarray(settings["alpha"]), energy=np.asarray(settings["energy"]), exponent=exponent,
                            threshold=float(settings["threshold"]), params=params, settings=settings, stats=stats,
                            status=status, message=message)

    return read_grid_result(path, build, store_kind=STORE_KIND, result_kind=ChaosDiagram.result_kind,
                            what="a chaos diagram", store_keys=("settings", "chaos_diagram_stats"))
