"""Poincare sections on an energy surface, and the energy surface itself.

``poincare(params, energy, section="phi=0")`` starts ``n_orbits`` orbits on the section at the
given energy and records ``n_crossings`` returns of each to the section (crossings of the
section coordinate through its value, modulo 2 pi, in the chosen direction).  Each crossing is
located on the DOP853 step that made it, by the 7th-order dense output and root finding on the
interpolant (``locate="dense"``, to ~1e-15 in the coordinate, the interpolant being accurate to
the tolerance), or independently by Hénon's trick (``locate="henon"``: integrating from the step's
start with the section coordinate as the independent variable).  The points are given in the
canonical coordinates of the other joint, ``(q, p_q)``, where the section map preserves area,
and in ``(q, q')``; each carries its energy error.

The energy surface of a conservative model (no damping, no torques): on the section
``q_c = v`` a point ``(q, p_q)`` of the other joint can be reached at energy ``E`` exactly when
``p_q^2 / (2 M_qq) + Pi <= E`` (the least kinetic energy with momentum ``p_q``, over the speed
of the section joint, is ``p_q^2 / (2 M_qq)``); the speed of the section joint is then fixed
by ``E`` up to its sign, which the direction chooses.  Seeds outside are reported in
``unreachable``, never dropped silently.
"""

from __future__ import annotations

import ctypes
import math
import re
import time
from dataclasses import dataclass
from typing import Any, Callable, ClassVar, Dict, List, Optional, Tuple

import numpy as np

from ..errors import IntegrationError, ParameterError
from ..io import atomic_path
from ..results import DatasetSpec, Result, agree, netcdf_reader, protocol_fields
from ..status import Status
from ..numeric.grid import check_workers
from ..parsing import parse_scalar, positive_number
from ..schema import LENGTH_NAMES
from ..symbolic.model import Parameters
from ..checks import MAX_STEPS, max_steps as check_max_steps, numeric_params, progress_callable, tolerances
from .lyapunov import check_exponent_work

__all__ = ["poincare", "PoincareSection", "parse_section", "energy_minimum", "section_seeds", "EnergySurface",
           "LOCATE_METHODS"]

LOCATE_METHODS = ("dense", "henon")
_COORDS = {"phi": 0, "psi": 1}
_TWO_PI = 2.0 * math.pi
#: Accepted steps per call into the compiled code (a few ms: Ctrl-C stops within that).
_BUDGET = 4000


#: Largest energy magnitude [J] a section or diagram accepts (the parameters' own bound: beyond
#: it the equations' products overflow).
ENERGY_LIMIT = 1e100

#: Points whose energy error exceeds this fraction of the energy above the minimum are not on
#: the energy surface any more: the section is reported PARTIAL (a tolerance far too loose).
MAX_RELATIVE_ENERGY_ERROR = 1e-3


def section_status(orbit_status: np.ndarray, stats: Dict[str, Any], room: float) -> Tuple[Status, str]:
    """The one rule for a section's outcome (see :class:`PoincareSection`)."""
    n = int(np.size(orbit_status))
    failed = int(np.count_nonzero((orbit_status != 0) & (orbit_status != int(Status.SHORT))))
    short = int(np.count_nonzero(orbit_status == int(Status.SHORT)))
    err = float(stats.get("max_energy_error", 0.0))
    problems = []
    if failed:
        problems.append(f"{failed} of {n} orbits failed (non-finite state, step size underflow or max_steps)")
    if not math.isfinite(err):
        problems.append("points with a non-finite energy were produced")
    elif not err <= MAX_RELATIVE_ENERGY_ERROR * max(room, 1e-300):
        problems.append(f"the energy error reaches {err:.3g} J, more than {MAX_RELATIVE_ENERGY_ERROR:g} of the "
                        f"energy above the minimum ({room:.3g} J): the points left the energy surface; use a "
                        "smaller rtol/atol")
    if problems:
        return Status.PARTIAL, "; ".join(problems)
    notes = []
    asked = int(stats.get("orbits_asked", n))
    if n < asked:
        notes.append(f"only {n} of the {asked} orbits asked for could be started on the section (the reachable "
                     "region is too small for more distinct seeds, or given seeds are unreachable)")
    if short:
        notes.append(f"{short} of {n} orbits reached t_max before the wanted crossings (fewer points)")
    if notes:
        return Status.SHORT, "; ".join(notes)
    return Status.SUCCESS, f"all {n} orbits made their crossings"


def parse_section(section) -> Tuple[str, float]:
    """``"phi=0"``, ``"psi=0.5"``, ``"psi=30deg"`` -> ``("phi", 0.0)``: the joint whose angle is
    fixed on the section and its value [rad] (taken modulo 2 pi)."""
    if not isinstance(section, str):
        raise ParameterError(f"section must be a string like 'phi=0' or 'psi=30deg', got {section!r}")
    m = re.fullmatch(r"\s*(phi|psi)\s*=\s*(\S+)\s*", section)
    if not m:
        raise ParameterError(f"section must be 'phi=VALUE' or 'psi=VALUE' (radians, or with a deg suffix), got {section!r}")
    try:  # radians, a deg suffix or a multiple of pi (pi, -pi, pi/2, 2pi, 0.5*pi)
        value = parse_scalar(m.group(2).lower(), f"section {m.group(1)}", angle=True)
    except ParameterError:
        value = None
    if value is None:
        raise ParameterError(f"section {m.group(1)}: the value must be a number in radians, with a deg suffix, or a "
                             f"multiple of pi (e.g. phi=0, psi=30deg, phi=pi/2), got {m.group(2)!r}")
    return m.group(1), float(value)


def mass_matrices(kernel, p, q: np.ndarray) -> np.ndarray:
    """M(q) for rows of angles q (m, 2): shape (m, 2, 2), from the generated momenta p = M q' with
    q' the unit vectors (column j of M is the momenta of q' = e_j), in one compiled call."""
    q = np.asarray(q, dtype=float)
    m = q.shape[0]
    rows = np.zeros((m, 2, 5))
    rows[:, :, :2] = q[:, None, :]
    rows[:, 0, 2] = 1.0
    rows[:, 1, 3] = 1.0
    columns = kernel.momenta_many(rows.reshape(2 * m, 5), p).reshape(m, 2, 2)  # [i, j, :] = M(q_i) e_j
    return np.ascontiguousarray(columns.transpose(0, 2, 1))


def potential(kernel, p, q: np.ndarray) -> np.ndarray:
    rows = np.zeros((q.shape[0], 5))
    rows[:, :2] = q
    return kernel.energies(rows, p)


def energy_minimum(kernel, p, *, samples: int = 121) -> Tuple[float, np.ndarray]:
    """The least potential energy [J] and where: a grid over the torus refined by Nelder-Mead
    from the best grid points (the generated energy at rest)."""
    from scipy.optimize import minimize

    u = np.linspace(-math.pi, math.pi, samples, endpoint=False)
    Q = np.array(np.meshgrid(u, u, indexing="ij")).reshape(2, -1).T
    V = potential(kernel, p, Q)
    best = np.argsort(V)[:4]
    f = lambda q: float(potential(kernel, p, np.asarray(q, dtype=float).reshape(1, 2))[0])  # noqa: E731
    results = [minimize(f, Q[i], method="Nelder-Mead", options={"xatol": 1e-12, "fatol": 1e-15, "maxiter": 4000})
               for i in best]
    r = min(results, key=lambda r: r.fun)
    return float(r.fun), np.asarray(r.x)


@dataclass(frozen=True)
class EnergySurface:
    """The energy surface ``E`` of a conservative model seen on the section ``q_c = value``:
    ``coord`` is the section joint (0 phi, 1 psi), ``other`` the other; ``e_min`` the least
    potential energy; ``reach(q, p_q)`` the margin ``E - Pi - p_q^2 / (2 M_qq)`` (>= 0: reachable)."""

    kernel: Any
    p: np.ndarray
    energy: float
    coord: int
    value: float
    e_min: float

    @property
    def other(self) -> int:
        return 1 - self.coord

    def _q(self, x: np.ndarray) -> np.ndarray:
        q = np.empty((x.size, 2))
        q[:, self.coord] = self.value
        q[:, self.other] = x
        return q

    def _at(self, x, p_other):
        """``(x, p_other, q, M(q), E - Pi(q))`` of seeds on the section."""
        x = np.atleast_1d(np.asarray(x, dtype=float))
        q = self._q(x)
        return (x, np.atleast_1d(np.asarray(p_other, dtype=float)), q, mass_matrices(self.kernel, self.p, q),
                self.energy - potential(self.kernel, self.p, q))

    def reach(self, x, p_other) -> np.ndarray:
        _, p_other, _, M, K = self._at(x, p_other)
        return K - p_other**2 / (2.0 * M[:, self.other, self.other])

    def bounds(self, samples: int = 721) -> Tuple[float, float]:
        """(least potential on the section, the largest |p_q| reachable) over a fine grid."""
        q = self._q(np.linspace(-math.pi, math.pi, samples))
        V = potential(self.kernel, self.p, q)
        Moo = mass_matrices(self.kernel, self.p, q)[:, self.other, self.other]
        k = np.clip(self.energy - V, 0.0, None)
        return float(V.min()), float(np.sqrt(2.0 * k * Moo).max())

    def states(self, x, p_other, direction: int) -> np.ndarray:
        """The states (phi, psi, dphi, dpsi) of reachable seeds: the section joint's speed from
        the energy, its sign from ``direction`` (0 counts as +1)."""
        x, p_other, q, M, K = self._at(x, p_other)
        c, o = self.coord, self.other
        det = M[:, 0, 0] * M[:, 1, 1] - M[:, 0, 1] ** 2
        disc = (2.0 * K * M[:, o, o] - p_other**2) / det
        speed_c = (1.0 if direction >= 0 else -1.0) * np.sqrt(np.clip(disc, 0.0, None))
        speed_o = (p_other - M[:, o, c] * speed_c) / M[:, o, o]
        y = np.zeros((x.size, 4))
        y[:, :2] = q
        y[:, 2 + c] = speed_c
        y[:, 2 + o] = speed_o
        return y


def _van_der_corput(index: np.ndarray, base: int) -> np.ndarray:
    """The radical inverse of each whole number in ``index`` in ``base``: its digits mirrored about
    the point (6 = 110 in base 2 -> 0.011 = 0.375), digit by digit in the order and the arithmetic
    of SciPy's ``qmc.Halton(scramble=False)`` (``_qmc_cy.van_der_corput``), so the same bits."""
    out = np.zeros(index.shape)
    quotient = index.astype(np.int64)
    b2r = 1.0 / base
    while np.any(quotient > 0):
        out += (quotient % base) * b2r
        b2r /= base
        quotient //= base
    return out


def halton2(start: int, n: int) -> np.ndarray:
    """Points ``start .. start + n - 1`` of the unscrambled two-dimensional Halton sequence (bases 2
    and 3), shape (n, 2): what ``scipy.stats.qmc.Halton(d=2, scramble=False)`` gives after
    ``fast_forward(start)`` -- here without importing ``scipy.stats`` (0.4 s, a tenth of a report's
    first-run overhead); tests compare the two."""
    index = np.arange(start, start + n, dtype=np.int64)
    return np.column_stack([_van_der_corput(index, 2), _van_der_corput(index, 3)])


def section_seeds(surface: EnergySurface, n: int, *, margin: float = 1e-9) -> np.ndarray:
    """``n`` seeds ``(q, p_q)`` spread over the reachable region of the section: the points of
    a Halton sequence in its bounding box that fall inside (deterministic)."""
    _, pmax = surface.bounds()
    scale = abs(surface.energy - surface.e_min) + 1e-300
    seeds: List[Tuple[float, float]] = []
    start = 1  # skip the corner point (0, 0)
    for _ in range(200):
        count = max(64, 4 * n)
        u = halton2(start, count)
        start += count
        x = -math.pi + _TWO_PI * u[:, 0]
        pq = pmax * (2.0 * u[:, 1] - 1.0)
        inside = surface.reach(x, pq) > margin * scale
        seeds.extend(zip(x[inside], pq[inside]))
        if len(seeds) >= n:
            break
    return np.asarray(seeds[:n], dtype=np.float64).reshape(-1, 2)


@dataclass(frozen=True)
class PoincareSection(Result):
    """The result of :func:`poincare`.

    Points (one per crossing, all orbits concatenated; ``orbit[i]`` says whose):

    * ``q``, ``p`` -- the other joint's angle (wrapped to ``[-pi, pi)``) [rad] and canonical
      momentum [J s]: the area-preserving coordinates of the section;
    * ``dq`` -- the other joint's speed [rad/s];
    * ``t`` -- the crossing time [s]; ``states`` -- the full state (phi, psi, dphi, dpsi), shape (N, 4);
    * ``energy_error`` -- ``E(state) - energy`` [J].

    Orbits: ``seeds`` (n, 2) = their starts ``(q, p_q)`` on the section, ``crossings`` (n,) how
    many each made, ``orbit_status`` (n,) the :class:`~skewpend.status.Status` code of each: 0 =
    all wanted crossings, 5 (SHORT) = ``t_max`` reached first, 1-3 failures.  ``unreachable``:
    seeds given that cannot lie on the surface (reported, not used).  ``coord_names`` =
    (section joint, other joint); ``params``, ``settings``, ``stats``.

    The result protocol: ``status`` is SUCCESS when every orbit made its crossings with an
    energy error below :data:`MAX_RELATIVE_ENERGY_ERROR` of the energy above the minimum;
    PARTIAL when orbits failed or the points left the energy surface (a tolerance far too
    loose); SHORT when orbits reached ``t_max`` first -- ``message`` says which and how many.
    """

    q: np.ndarray
    p: np.ndarray
    dq: np.ndarray
    t: np.ndarray
    states: np.ndarray
    energy_error: np.ndarray
    orbit: np.ndarray
    seeds: np.ndarray
    crossings: np.ndarray
    orbit_status: np.ndarray
    unreachable: np.ndarray

    result_kind: ClassVar[str] = "Poincare section"

    @property
    def coord_names(self) -> Tuple[str, str]:
        c = self.settings["coordinate"]
        return c, ("psi" if c == "phi" else "phi")

    @property
    def n_points(self) -> int:
        return int(self.q.size)

    def boundary(self, *, canonical: bool = True, samples: int = 721):
        """The edge of the energy surface on the section: ``(q, lower, upper)`` with ``q`` from
        -pi to pi [rad] and ``lower``, ``upper`` the least and the largest value of the drawn
        coordinate that energy allows there, NaN where ``Pi > E``.

        ``canonical``: the momentum ``p_q`` [J s], ``|p_q| <= sqrt(2 M_qq (E - Pi))`` (the least
        kinetic energy at a given ``p_q`` has the section joint at rest, so the crossing direction
        does not matter).  Otherwise the speed ``q'`` [rad/s]: the least kinetic energy at a given
        ``q'`` is ``q'^2 (M_qq - M_qc^2 / M_cc) / 2`` when the section joint's speed that attains
        it, ``-M_qc q' / M_cc``, has the sign the direction asks for (or the direction is 0), and
        ``M_qq q'^2 / 2`` (section joint at rest) when not -- so the edge is lopsided."""
        from ..numeric.kernels import kernel_module, parameter_vector

        c = 0 if self.settings["coordinate"] == "phi" else 1
        o = 1 - c
        surface = EnergySurface(kernel_module(self.params, chaos=True), parameter_vector(self.params),
                                float(self.settings["energy"]), c, float(self.settings["value"]), math.nan)
        x, _, _, M, room = surface._at(np.linspace(-math.pi, math.pi, samples), 0.0)
        room = np.where(room >= 0, room, np.nan)
        if canonical:
            upper = np.sqrt(2.0 * room * M[:, o, o])
            return x, -upper, upper
        reduced = np.sqrt(2.0 * room / (M[:, o, o] - M[:, o, c] ** 2 / M[:, c, c]))
        full = np.sqrt(2.0 * room / M[:, o, o])
        d = int(self.settings.get("direction", 0))
        # q' > 0 is reached with the section joint moving at -M_qc q' / M_cc: allowed if d * that >= 0
        coupling = M[:, o, c]
        upper = np.where((d == 0) | (-d * coupling >= 0), reduced, full)
        lower = -np.where((d == 0) | (d * coupling >= 0), reduced, full)
        return x, lower, upper

    def orbit_points(self, k: int) -> Tuple[np.ndarray, np.ndarray]:
        """``(q, p)`` of orbit ``k``."""
        sel = self.orbit == k
        return self.q[sel], self.p[sel]

    def _dataset(self) -> DatasetSpec:
        """On dimension ``point`` (and ``orbit`` for the seeds and their outcomes)."""
        _, other = self.coord_names
        return DatasetSpec(
            variables={
                other: (("point",), self.q, {"units": "rad", "long_name": f"{other} on the section"}),
                f"p_{other}": (("point",), self.p, {"units": "J s", "long_name": f"canonical momentum of {other}"}),
                f"d{other}": (("point",), self.dq, {"units": "rad/s"}),
                "t": (("point",), self.t, {"units": "s", "long_name": "crossing time"}),
                "orbit_index": (("point",), self.orbit, {}),
                "energy_error": (("point",), self.energy_error, {"units": "J"}),
                "seed_q": (("orbit",), self.seeds[:, 0], {"units": "rad"}),
                "seed_p": (("orbit",), self.seeds[:, 1], {"units": "J s"}),
                "crossings": (("orbit",), self.crossings, {}),
                "status": (("orbit",), self.orbit_status, {"long_name": "outcome of each orbit (skewpend.Status)"}),
            },
            coords={},
            attrs={"title": "Poincare section of the skewed double pendulum (skewpend)", **self._base_attrs()},
        )

    def to_csv(self, path) -> None:
        """The points as CSV (orbit, t, q, p_q, q', energy_error), written atomically."""
        _, other = self.coord_names
        header = f"orbit,t,{other},p_{other},d{other},energy_error"
        table = np.column_stack([self.orbit, self.t, self.q, self.p, self.dq, self.energy_error])
        with atomic_path(path) as tmp:
            np.savetxt(tmp, table, delimiter=",", header=header, comments="", fmt=["%d"] + ["%.17g"] * 5)


@netcdf_reader(PoincareSection.result_kind)
def read_poincare_section(path, variables, attrs) -> PoincareSection:
    """A :class:`PoincareSection` from its ``*.nc`` file (``read_poincare_section(path)``, for
    :func:`skewpend.open_result`): the file keeps the other joint's angle, momentum and speed at
    each crossing; the full states are rebuilt (the section joint at the section, its speed from
    the momentum, or where that does not fix it from the energy) and their energies must be the
    stored ones."""
    from ..numeric.kernels import kernel_module, parameter_vector
    from .orbits import energy_function

    proto = protocol_fields(path, attrs, Parameters)
    params, settings = proto["params"], proto["settings"]
    name = str(settings["coordinate"])
    c = 0 if name == "phi" else 1
    o = 1 - c
    other = ("psi", "phi")[c]
    q, p, dq, error = (np.asarray(variables[k], dtype=float) for k in (other, f"p_{other}", f"d{other}", "energy_error"))
    # the full states: the section joint at the section (its angle wrapped), its speed from the
    # other joint's momentum p = M_oc q_c' + M_oo q_o' (or, where M_oc vanishes, from the energy)
    kernel = kernel_module(params, chaos=True)
    pv = parameter_vector(params)
    states = np.zeros((q.size, 4))
    states[:, c] = math.remainder(float(settings["value"]), 2 * math.pi)
    states[:, o] = q
    states[:, 2 + o] = dq
    if q.size:
        M = mass_matrices(kernel, pv, states[:, :2])
        Moc, Moo, Mcc = M[:, o, c], M[:, o, o], M[:, c, c]
        coupled = np.abs(Moc) > 1e-6 * np.sqrt(np.abs(Moo * Mcc))
        with np.errstate(all="ignore"):
            states[:, 2 + c] = np.where(coupled, (p - Moo * dq) / np.where(coupled, Moc, 1.0), 0.0)
        H = energy_function(params)
        if not coupled.all():
            kinetic_rest = float(settings["energy"]) + error[~coupled] - H(states[~coupled])  # the section joint's share
            sign = np.where(int(settings.get("direction", 1)) < 0, -1.0, 1.0)
            states[~coupled, 2 + c] = sign * np.sqrt(np.clip(2 * kinetic_rest / Mcc[~coupled], 0.0, None))
        agree(path, "crossings' energy", float(settings["energy"]) + error, H(states),
              scale=abs(float(settings["energy"]) - float(proto["stats"].get("e_min", 0.0))))
    n_unreachable = int(proto["stats"].get("unreachable", 0))
    return PoincareSection(
        q=q, p=p, dq=dq, t=np.asarray(variables["t"], dtype=float), states=states, energy_error=error,
        orbit=np.asarray(variables["orbit_index"]).astype(np.int64),
        seeds=np.column_stack([variables["seed_q"], variables["seed_p"]]).astype(float),
        crossings=np.asarray(variables["crossings"]).astype(np.int64), orbit_status=np.asarray(variables["status"]).astype(np.int32),
        unreachable=np.full((n_unreachable, 2), np.nan), **proto)


def poincare(
    params: Parameters,
    energy: float,
    *,
    section: str = "phi=0",
    direction: int = 1,
    n_orbits: int = 50,
    n_crossings: int = 500,
    seeds=None,
    locate: str = "dense",
    t_max: Optional[float] = None,
    rtol: Optional[float] = 1e-12,
    atol: Optional[float] = 1e-12,
    max_steps: int = MAX_STEPS,
    workers: Optional[int] = None,
    progress: Optional[Callable[[int, int], None]] = None,
) -> PoincareSection:
    """The Poincare section ``section`` (``"phi=VALUE"`` or ``"psi=VALUE"``, modulo 2 pi) of the
    orbits at ``energy`` [J] (the energy of :func:`simulate`: ``T + Pi``; see ``stats["e_min"]``
    for the least possible), crossed in ``direction`` (+1: the section joint's angle increasing,
    -1 decreasing, 0 both).

    ``n_orbits`` orbits start on the section -- from ``seeds`` (an array of ``(q, p_q)`` of the
    other joint) or, by default, spread over the reachable region -- and are followed for
    ``n_crossings`` crossings each, or until ``t_max`` [s] (default: 200 small-oscillation periods
    per crossing wanted).  DOP853 at ``rtol``/``atol`` (default 1e-12); ``locate``: ``"dense"`` or
    ``"henon"`` (see the module).  Orbits run on ``workers`` threads; ``progress(done, total)``
    counts crossings.

    Refused with one clear :class:`~skewpend.errors.ParameterError`: damping or torques (the
    energy would not be constant), an energy below the minimum, a section the motion cannot
    reach at that energy.
    """
    from ..numeric.driver import drive
    from ..numeric.ensemble import Cancelled, run_chunks
    from ..numeric.kernels import State, kernel_module, parameter_vector

    params = numeric_params(params, "a Poincare section")
    params.require_conservative("a Poincare section")  # the energy surface needs E = T + Pi constant
    if isinstance(energy, bool):
        raise ParameterError(f"energy must be a number of joules, got {energy!r}")
    try:
        energy = float(energy)
    except (TypeError, ValueError):
        raise ParameterError(f"energy must be a number of joules, got {energy!r}") from None
    if not math.isfinite(energy):
        raise ParameterError(f"energy must be a finite number of joules, got {energy!r}")
    if abs(energy) > ENERGY_LIMIT:
        raise ParameterError(f"energy must be at most {ENERGY_LIMIT:g} J in magnitude (as every parameter), "
                             f"got {energy:g}")
    name, value = parse_section(section)
    if direction not in (-1, 0, 1) or isinstance(direction, bool):
        raise ParameterError(f"direction must be +1, -1 or 0 (both), got {direction!r}")
    if locate not in LOCATE_METHODS:
        raise ParameterError(f"locate must be one of {', '.join(LOCATE_METHODS)}, got {locate!r}")
    for label, v, cap in (("n_orbits", n_orbits, 100_000), ("n_crossings", n_crossings, 10_000_000)):
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 1 <= v <= cap:
            raise ParameterError(f"{label} must be a whole number from 1 to {cap}, got {v!r}")
    if int(n_orbits) * int(n_crossings) > 10_000_000:
        raise ParameterError(f"n_orbits x n_crossings = {int(n_orbits) * int(n_crossings)} points is too many (at most 1e7)")
    t_max = positive_number("t_max", t_max, allow_none=True)
    rtol, atol = tolerances(rtol, atol)
    max_steps = check_max_steps(max_steps)
    workers = check_workers(workers)
    progress_callable(progress)

    coord = _COORDS[name]
    kernel = kernel_module(params, chaos=True)
    p = parameter_vector(params)
    surface = EnergySurface(kernel, p, energy, coord, value, energy_minimum(kernel, p)[0])
    scale = max(abs(surface.e_min), abs(energy), 1e-300)
    if energy < surface.e_min - 1e-12 * scale:
        raise ParameterError(f"energy {energy:.6g} J is below the minimum of the potential energy, {surface.e_min:.6g} J; "
                             f"allowed: energy >= {surface.e_min:.6g} J")
    v_section, _ = surface.bounds()
    if v_section >= energy:
        raise ParameterError(
            f"the motion never reaches the section {section!r} at energy {energy:.6g} J: the potential energy on it is "
            f"at least {v_section:.6g} J; choose a higher energy or another section value"
        )
    if seeds is None:
        seeds_ok = section_seeds(surface, int(n_orbits))
        unreachable = np.empty((0, 2))
        if seeds_ok.shape[0] == 0:
            raise ParameterError(f"no orbit can be started on the section {section!r} at energy {energy:.6g} J "
                                 f"(the reachable region is too thin); choose a higher energy")
    else:
        try:
            given = np.asarray(seeds, dtype=float).reshape(-1, 2)
        except (TypeError, ValueError):
            raise ParameterError("seeds must be an array of (q, p_q) pairs of the other joint") from None
        if given.shape[0] == 0 or not np.all(np.isfinite(given)):
            raise ParameterError("seeds must be a non-empty array of finite (q, p_q) pairs of the other joint")
        ok = surface.reach(given[:, 0], given[:, 1]) >= 0
        seeds_ok, unreachable = given[ok], given[~ok]
        if seeds_ok.shape[0] == 0:
            raise ParameterError(f"none of the {given.shape[0]} seeds can lie on the energy surface {energy:.6g} J at the "
                                 f"section {section!r} (each needs p^2/(2 M) + Pi <= E)")
    starts = surface.states(seeds_ok[:, 0], seeds_ok[:, 1], direction)
    n = starts.shape[0]
    want = int(n_crossings)
    reach = sum(float(getattr(params, k)) for k in LENGTH_NAMES)  # numeric: checked above
    period = 2.0 * math.pi * math.sqrt(reach / max(float(params.g), 1e-12))  # a swing, roughly
    t_max = 200.0 * period * want if t_max is None else t_max
    # an orbit takes about one swing per crossing (t_max only bounds it): refuse what cannot finish
    expected = min(t_max, want * period)
    check_exponent_work((kernel, p), starts[:3], params=params, t_end=expected, rtol=rtol, atol=atol,
                        max_steps=max_steps, what="this Poincare section",
                        time_name=f"{want} crossings at about one swing ({period:.3g} s) each: t",
                        advice="ask for fewer crossings, or a larger max_steps")
    method = LOCATE_METHODS.index(locate)
    value_wrapped = math.remainder(value, _TWO_PI)
    done = [0]
    start = time.perf_counter()

    def work(k, cancel):
        state = State.at(0.0, list(starts[k]) + [0.0])
        rows = np.empty((min(want, 8192), 5))
        dp = ctypes.POINTER(ctypes.c_double)
        m = ctypes.c_int64(0)
        got = []

        def between() -> None:  # the engine's cancel event, between two bounded calls
            if cancel.is_set():
                raise Cancelled()

        rc = drive(lambda budget: kernel.lib.sp_section(
                       ctypes.byref(state), p.ctypes.data_as(dp), coord, value_wrapped, _TWO_PI, int(direction),
                       method, want, t_max, rtol, atol, max_steps, budget, rows.ctypes.data_as(dp), rows.shape[0],
                       ctypes.byref(m)),
                   budget=_BUDGET, take=lambda: got.append(rows[: m.value].copy()) if m.value else None,
                   between=between, name="sp_section")
        table = np.concatenate(got) if got else np.empty((0, 5))
        return table, rc, int(state.naccept), int(state.nreject), int(state.aux)

    tables: list = [None] * n
    status = np.zeros(n, dtype=np.int32)
    steps, rejected, fallbacks = np.zeros((3, n), dtype=np.int64)

    def on_done(k, result):
        tables[k], status[k], steps[k], rejected[k], fallbacks[k] = result
        done[0] += want
        if progress is not None:
            progress(done[0], n * want)

    run_chunks(n, work, workers=workers, on_done=on_done, keep=False)
    counts = np.array([t.shape[0] for t in tables], dtype=np.int64)
    table = np.concatenate(tables) if n else np.empty((0, 5))
    orbit = np.repeat(np.arange(n), counts)
    states = table[:, 1:5]
    o = 1 - coord
    rows5 = np.zeros((states.shape[0], 5))
    rows5[:, :4] = states
    e = kernel.energies(rows5, p)
    mom = kernel.momenta_many(rows5, p)  # one compiled call (the same C as kernel.momenta, row by row)
    q_other = np.mod(states[:, o] + math.pi, _TWO_PI) - math.pi
    failed = int(np.count_nonzero((status != 0) & (status != 5)))
    settings = {
        "energy": energy, "section": f"{name}={value:g}", "coordinate": name, "value": value, "direction": int(direction),
        "n_orbits": int(n_orbits), "n_crossings": want, "locate": locate, "t_max": t_max, "rtol": rtol, "atol": atol,
        "max_steps": max_steps, "seeds": "given" if seeds is not None else "halton",
    }
    stats = {
        "points": int(table.shape[0]), "orbits": n, "orbits_asked": int(n_orbits) if seeds is None else int(n + unreachable.shape[0]),
        "unreachable": int(unreachable.shape[0]),
        "orbits_short": int(np.count_nonzero(status == int(Status.SHORT))), "failed": failed, "steps": int(steps.sum()),
        "rejected": int(rejected.sum()), "e_min": surface.e_min, "henon_fallbacks": int(fallbacks.sum()),
        "max_energy_error": float(np.max(np.abs(e - energy))) if e.size else 0.0,
        "wall_time": time.perf_counter() - start, "workers": workers,
    }
    outcome, message = section_status(status, stats, energy - surface.e_min)
    result = PoincareSection(
        q=q_other, p=mom[:, o], dq=states[:, 2 + o], t=table[:, 0], states=states, energy_error=e - energy, orbit=orbit,
        seeds=seeds_ok, crossings=counts, orbit_status=status, unreachable=unreachable, params=params,
        settings=settings, stats=stats, status=outcome, message=message,
    )
    if table.shape[0] == 0:
        raise IntegrationError(f"no orbit crossed the section {section!r} within t_max = {t_max:g} s")
    return result
