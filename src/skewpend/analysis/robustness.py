"""The RealAIGym leaderboard's robustness evaluation ("v2"), for any controller of its plant at any skew.

The lab's robustness board (``double_pendulum``'s ``leaderboard/*/robustness_v2``, its
``analysis/benchmark.py`` and ``simulation/simulation.py``) runs a controller by the leaderboard's
protocol (:mod:`skewpend.analysis.leaderboard`) on its plant made imperfect in six ways, one at a time,
and counts the swing-ups that end at the goal:

* **model** -- the simulated plant's parameters varied one at a time (the controller keeps the nominal
  model), 21 values each: the rotor inertia ``Ir`` in [0, 1e-4] kg m^2, ``m1 r1``, ``I1`` (about the
  joint), ``m2 r2``, ``m2``, ``I2`` in [0.75, 1.25] times the nominal value (``m r`` by its ``r``), the
  damping ``b`` in [-0.1, 0.1] N m s and the Coulomb friction ``cf`` in [-0.2, 0.2] N m of each joint
  (negative values inject energy: the plant's run-time numbers, which skewpend refuses as a model);
* **velocity noise** -- Gaussian noise on the measured speeds, sigma in [0, 0.5] rad/s (21 values, 10
  runs each; a value passes when more than half its runs succeed);
* **torque noise** -- Gaussian noise on the applied torque before the clip, sigma in [0, 1.1] N m
  (likewise);
* **torque response** -- the motor applies ``u_prev + k (u - u_prev)``, ``k`` in [0.1, 2] (21 runs);
* **delay** -- the law sees the state 0 to 20 steps old (0 to 0.04 s, 21 runs);
* **perturbations** -- 50 random profiles of three Gaussian torque pulses per joint (centres at least
  1 s apart in [1, 9] s, widths 0.05-0.1 s, amplitudes 0.5-5 N m of either sign) added after the clip
  (on the actuated joint: the lab's plant drops a passive joint's torque).

A run succeeds when its final state is within 0.35 rad of the goal in each angle (the first wrapped
to [0, 2 pi), the others to [-pi, pi)) and 1 rad/s in each speed; each criterion is the fraction of
its runs (or values) that pass, the score their mean.  The lab draws its noise unseeded; here one
seeded generator draws it all (``seed``), so an evaluation is reproducible.  For a skewed rig
(``alpha``) the same variations apply to the same bodies, the second hinge turned.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Dict, Optional, Tuple

import numpy as np

from ..errors import ParameterError
from .leaderboard import PROTOCOL, Disturbance, Protocol, dfki_model, lab_values, run_protocol

__all__ = ["ROBUSTNESS", "RobustnessSettings", "Robustness", "CRITERIA", "LAB_VARIATIONS", "robustness",
           "model_variations", "perturbation_profile", "at_goal", "PUBLISHED_ROBUSTNESS"]

#: The lab's parameters that the model criterion varies, by the lab's names (its own schema; ``m1r1``: r1
#: varied at fixed m1).
LAB_VARIATIONS = ("Ir", "m1r1", "I1", "b1", "cf1", "m2r2", "m2", "I2", "b2", "cf2")
#: The six criteria, in the lab's order.
CRITERIA = ("model", "velocity_noise", "torque_noise", "torque_response", "delay", "perturbation")

#: The published robustness v2 entries (real_ai_gym_leaderboard's ``*_simulation_robustness_leaderboard_v2``):
#: the six criteria (fractions) and the score of the best entry of each robot.
PUBLISHED_ROBUSTNESS: Dict[str, Tuple[str, Tuple[float, ...], float]] = {
    "acrobot": ("History SAC", (0.581, 0.238, 1.0, 1.0, 0.905, 0.78), 0.751),
    "pendubot": ("AR-EAPO", (0.876, 0.810, 1.0, 1.0, 0.810, 0.98), 0.913),
}


@dataclass(frozen=True)
class RobustnessSettings:
    """The robustness board's settings (the lab's ``benchmark_controller.py``)."""

    values: int = 21                          #: values per varied quantity
    repetitions: int = 10                     #: runs per noise level
    perturbation_runs: int = 50
    relative: Tuple[float, float] = (0.75, 1.25)
    rotor_max: float = 1e-4                   #: Ir [kg m^2]
    damping_max: float = 0.1                  #: |b| [N m s]
    friction_max: float = 0.2                 #: |cf| [N m]
    velocity_noise_max: float = 0.5           #: [rad/s]
    torque_noise_max: float = 1.1             #: [N m]
    responsiveness: Tuple[float, float] = (0.1, 2.0)
    delay_max: float = 0.04                   #: [s]
    pulses_per_joint: int = 3
    pulse_gap: float = 1.0                    #: least time between pulse centres [s]
    pulse_width: Tuple[float, float] = (0.05, 0.1)       #: sigma [s]
    pulse_amplitude: Tuple[float, float] = (0.5, 5.0)    #: |A| [N m]
    angle_tolerance: float = 0.35             #: [rad]
    speed_tolerance: float = 1.0              #: [rad/s]


#: The lab's settings.
ROBUSTNESS = RobustnessSettings()


def at_goal(x, settings: RobustnessSettings = ROBUSTNESS) -> bool:
    """The lab's success test of a final state ``x`` (2 n,): the first angle within the tolerance of pi
    (wrapped to [0, 2 pi)), the others of 0 (wrapped to [-pi, pi)), every speed below its tolerance."""
    x = np.asarray(x, dtype=float)
    n = x.size // 2
    first = np.mod(x[0], 2 * np.pi)
    rest = np.mod(x[1:n] + np.pi, 2 * np.pi) - np.pi
    return bool(abs(first - np.pi) < settings.angle_tolerance and np.all(np.abs(rest) < settings.angle_tolerance)
                and np.all(np.abs(x[n:]) < settings.speed_tolerance))


def model_variations(name: str, nominal: Dict[str, float], settings: RobustnessSettings = ROBUSTNESS):
    """The varied plants of one of :data:`LAB_VARIATIONS`: a list of ``(value, lab_values, overrides)``, the
    value varied, the lab's numbers of that plant and the run-time entries set past the model's checks
    (a negative damping or friction: ``{"c1": -0.05}``)."""
    if name not in LAB_VARIATIONS:
        raise ParameterError(f"the model criterion varies {', '.join(LAB_VARIATIONS)}; got {name!r}")
    n = settings.values
    lo, hi = settings.relative
    out = []
    joint = name[-1]
    if name == "Ir":
        grid = np.linspace(0.0, settings.rotor_max, n)
    elif name[0] in "bc":
        top = settings.damping_max if name[0] == "b" else settings.friction_max
        grid = np.linspace(-top, top, n)
    elif name.endswith("r" + joint):  # m1r1, m2r2: r varied, m kept
        grid = np.linspace(lo, hi, n) * nominal["m" + joint] * nominal["r" + joint]
    else:
        grid = np.linspace(lo, hi, n) * nominal[name]
    for value in grid:
        v = dict(nominal)
        overrides: Dict[str, float] = {}
        if name[0] in "bc":
            key = ("c" if name[0] == "b" else "cf") + joint  # skewpend's run-time names
            v[name] = abs(float(value)) if name[0] == "b" else max(abs(float(value)), 1e-12)  # friction's code on
            overrides[key] = float(value)
        elif name.endswith("r" + joint) and name.startswith("m"):
            v["r" + joint] = float(value) / nominal["m" + joint]
        else:
            v[name] = float(value)
        out.append((float(value), v, overrides))
    return out


def perturbation_profile(rng: np.random.Generator, steps: int, dt: float, joints: int,
                         settings: RobustnessSettings = ROBUSTNESS) -> np.ndarray:
    """One random perturbation (steps, joints) [N m] as the lab draws it: ``pulses_per_joint`` Gaussian
    pulses per joint, their centres increasing by ``pulse_gap`` plus up to the spare time shared out, then
    shuffled among the joints; widths and amplitudes uniform in their ranges, the sign random."""
    m = joints * settings.pulses_per_joint
    t_final = steps * dt
    spare = (t_final - (m + 1) * settings.pulse_gap) / m
    if spare < 0:
        raise ParameterError(f"{m} pulses {settings.pulse_gap:g} s apart do not fit in {t_final:g} s")
    mu = np.cumsum(settings.pulse_gap + rng.random(m) * spare)
    rng.shuffle(mu)
    mu = mu.reshape(joints, settings.pulses_per_joint)
    w0, w1 = settings.pulse_width
    sigma = w0 + rng.random((joints, settings.pulses_per_joint)) * (w1 - w0)
    a0, a1 = settings.pulse_amplitude
    amp = rng.uniform(-(a1 - a0), a1 - a0, (joints, settings.pulses_per_joint))
    amp += a0 * np.sign(amp)
    t = np.arange(steps) * dt
    out = np.zeros((steps, joints))
    for j in range(joints):
        for i in range(settings.pulses_per_joint):
            out[:, j] += amp[j, i] * np.exp(-((t - mu[j, i]) ** 2) / (2 * sigma[j, i] ** 2))
    return out


@dataclass(frozen=True)
class Robustness:
    """A robustness evaluation: ``criteria`` (:data:`CRITERIA` -> fraction passed), ``runs`` (criterion ->
    the successes, a value's runs in a row for the noise criteria), ``model`` (varied parameter -> its 21
    successes); ``score`` the mean of the criteria."""

    criteria: Dict[str, float]
    runs: Dict[str, np.ndarray] = field(repr=False)
    model: Dict[str, np.ndarray] = field(repr=False)
    simulations: int = 0

    @property
    def score(self) -> float:
        return float(np.mean([self.criteria[k] for k in CRITERIA]))


def robustness(law, *, actuated=(2,), alpha: float = 0.0, values: Optional[Dict[str, float]] = None,
               umax: float = PROTOCOL.umax, protocol: Protocol = PROTOCOL,
               settings: RobustnessSettings = ROBUSTNESS, seed: int = 0,
               speeds: str = "measured", progress: Optional[Callable[[str, int, int], None]] = None) -> Robustness:
    """The robustness evaluation of ``law`` (a :class:`~skewpend.analysis.trajopt.Tracking`, a
    :class:`~skewpend.Controller` or a Python ``law(t, x)``, designed on the nominal plant) on the
    leaderboard's plant (the lab's numbers ``values``, default design C.1 model 1.1; the second hinge turned
    by ``alpha`` [rad]) with the motors on ``actuated``: every run of the six criteria (see the module),
    the noise drawn by one generator seeded with ``seed``; ``speeds`` what the law takes for the speeds
    (:func:`~skewpend.analysis.leaderboard.run_protocol`).  ``progress(criterion, done, total)`` is called
    after each run."""
    nominal = lab_values() if values is None else dict(values)
    plant = dfki_model(alpha, nominal).as_chain()  # the model the protocol runs (leaderboard.FORM), made once
    steps, dt = protocol.steps, protocol.dt
    rng = np.random.default_rng(seed)
    n = plant.n  # the plant's joints (each gets its pulses)
    total = (len(LAB_VARIATIONS) * settings.values + 2 * settings.values * settings.repetitions
             + 2 * settings.values + settings.perturbation_runs)
    count = [0]

    def run(stage: str, sim=None, overrides=None, disturbance=None) -> bool:
        r = run_protocol(plant, law, actuated=actuated, umax=umax, protocol=protocol, plant=sim,
                         plant_values=overrides, disturbance=disturbance, speeds=speeds)
        count[0] += 1
        if progress is not None:
            progress(stage, count[0], total)
        return r.ok and at_goal(r.final, settings)

    model_runs: Dict[str, np.ndarray] = {}
    for name in LAB_VARIATIONS:
        model_runs[name] = np.array([run("model", dfki_model(alpha, v), over)
                                     for _, v, over in model_variations(name, nominal, settings)])
    runs: Dict[str, np.ndarray] = {"model": np.concatenate(list(model_runs.values()))}
    for key, top in (("velocity_noise", settings.velocity_noise_max), ("torque_noise", settings.torque_noise_max)):
        runs[key] = np.array([[run(key, disturbance=Disturbance(**{key: float(sigma)}, seed=int(rng.integers(2**63 - 1))))
                               for _ in range(settings.repetitions)] for sigma in np.linspace(0.0, top, settings.values)])
    runs["torque_response"] = np.array([run("torque_response", disturbance=Disturbance(responsiveness=float(k)))
                                        for k in np.linspace(*settings.responsiveness, settings.values)])
    delays = np.rint(np.linspace(0.0, settings.delay_max, settings.values) / dt).astype(int)
    runs["delay"] = np.array([run("delay", disturbance=Disturbance(delay=int(d))) for d in delays])
    runs["perturbation"] = np.array([run("perturbation", disturbance=Disturbance(
        perturbation=perturbation_profile(rng, steps, dt, n, settings))) for _ in range(settings.perturbation_runs)])
    # a noise level passes when more than half its runs succeed
    criteria = {k: float(np.mean(runs[k].mean(axis=1) > 0.5) if k.endswith("_noise") else runs[k].mean())
                for k in CRITERIA}
    return Robustness(criteria, runs, model_runs, count[0])
