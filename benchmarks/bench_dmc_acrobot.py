"""The DeepMind Control Suite's acrobot swing-up (``suite.load("acrobot", "swingup")``) by skewpend's MPC.

The task, as dm_control's public source defines it (dm_control 1.0.52: ``dm_control/suite/acrobot.py``,
``dm_control/suite/acrobot.xml``, ``dm_control/utils/rewards.py``, ``dm_control/rl/control.py``):

* the model: ``acrobot.xml`` (two capsules of 1 kg and 1 m, hinges about ``y``, joint damping 0.05, gravity
  ``-z``, gravity 9.81), read by :func:`skewpend.interop.importer.read_mjcf` (``tests/data/dm_control_acrobot.xml``,
  the suite's file with its three visual includes inlined); its zero configuration points both arms **up**;
* the action: one number in ``[-1, 1]`` (``ctrlrange``) on the elbow's motor, ``gear`` 2: an elbow torque of at most
  2 N m, held over a step (``control.Environment``: one physics step an action, ``timestep`` 0.01 s, ``integrator``
  RK4);
* the start (``Balance.initialize_episode``): shoulder and elbow angles ``random.uniform(-pi, pi, 2)``, at rest
  (``reset_context``: ``mj_resetData``); ``random`` the task's ``np.random.RandomState(seed)``;
* the reward (``Balance._get_reward``, ``sparse=False``): ``rewards.tolerance(d, bounds=(0, 0.2), margin=1)`` with
  ``d`` the distance from the ``tip`` site (the lower arm's end) to the ``target`` site ``(0, 0, 4)`` (radius 0.2),
  the default sigmoid ``gaussian`` with ``value_at_margin`` 0.1: 1 for ``d <= 0.2``, else
  ``exp(-0.5 ((d - 0.2) sqrt(-2 ln 0.1))^2)``; read after each step (``Physics.step`` ends with ``mj_step1``: the
  kinematics of the new state);
* 1,000 steps (``_DEFAULT_TIME_LIMIT`` 10 s); the return is the sum of the 1,000 rewards.

Episode ``i`` is the task's start with ``random = seed + i`` (``--seed``, default 0: the reported run, starts 0-99).
skewpend runs it by its own fixed-step RK4 (``run_protocol``, ``Protocol(dt=0.01, t_final=10.0)``, the torque held
and clipped to 2 N m) with :class:`skewpend.MPC` on the imported chain, its goal ``q = (0, 0)`` (every arm up in
this model's angles: the MPC's default label assumes zero hanging), a solve every step; the return is computed from
skewpend's states by the reward above.  With ``--replay``, each episode's actions (torque / gear) are replayed
open-loop in dm_control's own physics from the task's own start, and its return compared.

The controller is two MPCs on the imported chain (:class:`SwingAndBalance`): a swing-up MPC (energy first, a 2 s
horizon, a weak goal LQR at its end) far from the goal, and the MPC's default problem (0.5 s, its goal LQR's
cost-to-go) within 0.5 rad and 4 rad/s of it (back to the swing-up beyond 1 rad).  Their settings
(:func:`settings`) and the switch were tuned on the starts ``random = 1000 ... 1015`` (``--seed 1000 --episodes
16``), never on the reported 0-99.

With ``--optimise``, the best return IPOPT finds near each episode's run (:func:`optimised_return`): how far the
controller's own way up is from a locally optimal one.

Run: ``python benchmarks/bench_dmc_acrobot.py --episodes 100 --seed 0 --replay`` (``pip install
"skewpend[bench]"`` for dm_control).  Timing figures depend on the machine's load (the solve is one thread).
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

XML = Path(__file__).resolve().parents[1] / "tests" / "data" / "dm_control_acrobot.xml"
GEAR = 2.0  # acrobot.xml: <motor gear="2" ctrlrange="-1 1">
TARGET_RADIUS = 0.2  # acrobot.xml: <site name="target" pos="0 0 4" size="0.2">
STEPS, DT = 1000, 0.01  # acrobot.py _DEFAULT_TIME_LIMIT 10 s; acrobot.xml <option timestep="0.01" integrator="RK4">
TD_MPC2 = 663.0  # TD-MPC2's acrobot-swingup return at 4 M steps (issue 54)


def settings():
    """The two MPCs' settings: the swing-up's (a long horizon, a weak goal LQR at its end) and the balance's."""
    from skewpend.analysis.mpc import MPCSettings

    # The MPC's energy term is divided by the goal's height in energy above the lowest rest (here 39.24 J, the arms
    # hanging at q = (pi, 0)). The weights were tuned when the MPC divided by 1 J on this model (it took q = 0 for the
    # hanging rest): 20 / J^2 and 0.13 / J^2 are the same costs as 20 * 39.24^2 and 0.13 * 39.24^2 (~200, the default).
    height = 39.24
    swing = MPCSettings(horizon=2.0, nodes=40, energy=20.0 * height ** 2, angle=0.3, speed=0.03, torque=1e-3,
                        terminal=(0.01, 0.001, 1e-5))
    balance = MPCSettings(horizon=0.5, nodes=20, energy=0.13 * height ** 2, angle=10.0, speed=1.0, torque=1e-3,
                          terminal=(10.0, 1.0, 1e-2))
    return swing, balance


#: The balance MPC takes over when the angles (wrapped) are within ENTER [rad] of the goal and the speeds within
#: SPEED [rad/s]; it hands back when they leave LEAVE [rad] (hysteresis).
ENTER, LEAVE, SPEED = 0.5, 1.0, 4.0


class SwingAndBalance:
    """Two MPCs on the same model: ``swing`` (energy first, long horizon) far from the goal ``q = 0``, ``balance``
    (the MPC's defaults: its goal LQR's cost-to-go ends a short horizon) near it; ``law(t, x)`` -> torques."""

    def __init__(self, swing, balance):
        self.swing, self.balance = swing, balance
        self.reset()

    def reset(self) -> None:
        self.swing.reset()
        self.balance.reset()
        self.near, self.times, self.cpu, self.switches, self._fallbacks = False, [], [], 0, 0

    def __call__(self, t, x):
        x = np.asarray(x, dtype=float)
        dq = np.mod(x[:2] + np.pi, 2 * np.pi) - np.pi
        dist, speed = float(np.linalg.norm(dq)), float(np.abs(x[2:]).max())
        near = dist < LEAVE if self.near else (dist < ENTER and speed < SPEED)
        if near != self.near:
            self.switches += 1
            entered = self.balance if near else self.swing
            self._fallbacks += entered.fallbacks  # reset() forgets them
            entered.reset()
            self.near = near
        start, cpu = time.perf_counter(), time.thread_time()
        out = (self.balance if near else self.swing)(t, x)
        self.times.append(time.perf_counter() - start)
        self.cpu.append(time.thread_time() - cpu)
        return out

    @property
    def fallbacks(self) -> int:
        return self._fallbacks + self.swing.fallbacks + self.balance.fallbacks


def reward(x: np.ndarray) -> np.ndarray:
    """The task's dense reward at states ``x`` (k, 4) (dm_control's angles): ``tolerance(d, (0, 0.2), margin=1)``."""
    q1, q2 = x[:, 0], x[:, 1]
    # tip - target: shoulder (0, 0, 2) + R_y(q1) (0, 0, 1) + R_y(q1 + q2) (0, 0, 1) - (0, 0, 4)
    dx = np.sin(q1) + np.sin(q1 + q2)
    dz = np.cos(q1) + np.cos(q1 + q2) - 2.0
    d = np.hypot(dx, dz)
    scale = math.sqrt(-2.0 * math.log(0.1))
    return np.where(d <= TARGET_RADIUS, 1.0, np.exp(-0.5 * ((d - TARGET_RADIUS) * scale) ** 2))


def start(seed: int) -> np.ndarray:
    """The task's start for ``random = seed``: ``RandomState(seed).uniform(-pi, pi, 2)``, at rest."""
    q = np.random.RandomState(seed).uniform(-np.pi, np.pi, 2)
    return np.r_[q, 0.0, 0.0]


def _env(seed: int, x0: np.ndarray):
    """dm_control's task with ``random = seed``, reset: its start checked equal to ``x0``."""
    from dm_control import suite

    env = suite.load("acrobot", "swingup", task_kwargs={"random": seed})
    env.reset()
    phys = env.physics
    if not (np.array_equal(phys.data.qpos, x0[:2]) and not np.any(phys.data.qvel)):
        raise SystemExit(f"dm_control's start for random={seed} is {phys.data.qpos}, not skewpend's {x0[:2]}")
    return env


def _state(env) -> np.ndarray:
    return np.r_[env.physics.data.qpos, env.physics.data.qvel]


def replay(seed: int, actions: np.ndarray, states: np.ndarray):
    """dm_control's return for ``actions`` (1000,) replayed open-loop from the task's start ``random = seed``, and
    the first step whose state is more than 1e-3 from skewpend's ``states`` (1001, 4: the start, then after each
    step) (None: never)."""
    env = _env(seed, states[0])
    total, parted = 0.0, None
    for k, a in enumerate(actions):
        total += env.step(np.array([a])).reward
        if parted is None and np.abs(_state(env) - states[k + 1]).max() > 1e-3:
            parted = k + 1
    return total, parted


def shadow(seed: int, actions: np.ndarray, states: np.ndarray):
    """dm_control's rewards along skewpend's trajectory: before each step dm_control's state is set to skewpend's
    (no accumulation of rounding), the action applied, its own step (RK4) taken and its reward read; the return and
    the largest one-step state difference."""
    env = _env(seed, states[0])
    phys = env.physics
    total, worst = 0.0, 0.0
    for k, a in enumerate(actions):
        phys.data.qpos[:] = states[k, :2]
        phys.data.qvel[:] = states[k, 2:]
        total += env.step(np.array([a])).reward
        worst = max(worst, float(np.abs(_state(env) - states[k + 1]).max()))
    return total, worst


def closed_loop(seed: int, law, x0: np.ndarray) -> float:
    """The controller ``law`` run in dm_control's physics (its states in, its action ``torque / gear`` out):
    the return there."""
    env = _env(seed, x0)
    law.reset()
    total = 0.0
    for k in range(STEPS):
        u = law(k * DT, _state(env))[1]
        total += env.step(np.array([np.clip(u / GEAR, -1.0, 1.0)])).reward
    return total


def optimised_return(chain, states: np.ndarray, torques: np.ndarray, max_iter: int = 500):
    """The best return IPOPT finds near one episode's run: the task's 1,000 RK4 steps of 0.01 s (the torque held over
    each, within 2 N m) as a multiple-shooting problem in skewpend's model (``trajopt.casadi_dynamics``), the
    return's sum of rewards its objective, started from the run's own states ``(1001, 4)`` and elbow torques
    ``(1000,)``.  A local optimum near the controller's way up: how much a better plan of the same swing-up would
    give.  Returns the return at the optimum (its states, within IPOPT's tolerance) and whether IPOPT converged."""
    from skewpend.analysis.trajopt import casadi_dynamics

    ca, _, step, _ = casadi_dynamics(chain, (2,))
    x, u = ca.SX.sym("x", 4), ca.SX.sym("u", 1)
    F = ca.Function("F", [x, u], [step(x, u, u, DT)]).map(STEPS)
    d = ca.sqrt((ca.sin(x[0]) + ca.sin(x[0] + x[1])) ** 2 + (ca.cos(x[0]) + ca.cos(x[0] + x[1]) - 2.0) ** 2 + 1e-12)
    scale = math.sqrt(-2.0 * math.log(0.1))
    R = ca.Function("R", [x], [ca.exp(-0.5 * (scale * ca.fmax(d - TARGET_RADIUS, 0.0)) ** 2)]).map(STEPS)
    opti = ca.Opti()
    X, U = opti.variable(4, STEPS + 1), opti.variable(1, STEPS)
    opti.subject_to(X[:, 0] == states[0])
    opti.subject_to(X[:, 1:] == F(X[:, :-1], U))
    opti.subject_to(opti.bounded(-GEAR, U, GEAR))
    opti.minimize(-ca.sum2(R(X[:, 1:])))
    opti.set_initial(X, states.T)
    opti.set_initial(U, torques[None, :])
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "max_iter": max_iter, "tol": 1e-8, "sb": "yes"})
    try:
        sol, ok = opti.solve(), True
    except RuntimeError:  # not converged in max_iter: the last iterate's return (its states nearly feasible)
        sol, ok = opti.debug, False
    return -float(sol.value(opti.f)), ok


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--episodes", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--replay", action="store_true", help="replay each episode's actions in dm_control's physics")
    ap.add_argument("--quiet", action="store_true", help="no line per episode")
    ap.add_argument("--optimise", action="store_true",
                    help="the best return IPOPT finds near each episode's run (optimised_return; about a minute each)")
    args = ap.parse_args()

    from skewpend.analysis import leaderboard as lb
    from skewpend.analysis.mpc import MPC
    from skewpend.interop.importer import read_mjcf

    model = read_mjcf(XML)
    chain = model.chain
    assert model.actuated == (2,) and model.gear == (GEAR,) and model.torque_limits == (GEAR,), model
    umax = model.torque_limits[0]
    swing, balance = (MPC(chain, actuated=(2,), umax=umax, goal=(0.0, 0.0), period=DT, settings=s) for s in settings())
    # the imported chain's zero points both arms up: the MPCs' goal must be q = 0 and the reward 1 there
    assert np.allclose(swing.goal, 0.0) and np.allclose(balance.goal, 0.0) and reward(np.zeros((1, 4)))[0] == 1.0
    for mpc in (swing, balance):
        print(f"{mpc!r}; goal {mpc.goal}; {mpc.settings}")
    law = SwingAndBalance(swing, balance)
    protocol = lb.Protocol(dt=DT, t_final=STEPS * DT, umax=umax)
    returns, replays, times, cpus, fallbacks, optimised = [], [], [], [], 0, []
    wall = time.perf_counter()
    for i in range(args.episodes):
        seed = args.seed + i
        x0 = start(seed)
        law.reset()
        run = lb.run_protocol(chain, law, actuated=(2,), umax=umax, protocol=protocol, x0=x0)
        if not run.ok:
            raise SystemExit(f"episode {i} (random={seed}): {run.message}")
        states = np.vstack([run.x[1:], run.final])  # the state after each step: the reward's
        ret = float(reward(states).sum())
        returns.append(ret)
        times.append(np.array(law.times))
        cpus.append(np.array(law.cpu))
        fallbacks += law.fallbacks
        line = f"episode {i:3d} (random={seed}): start q = ({x0[0]:+.3f}, {x0[1]:+.3f}), return {ret:8.2f}, switches {law.switches}"
        if args.replay:
            actions, path = run.u[:, 1] / GEAR, np.vstack([run.x, run.final])
            opened, parted = replay(seed, actions, path)
            shadowed, step_diff = shadow(seed, actions, path)
            closed = closed_loop(seed, law, x0)
            rel = [abs(v - ret) / max(abs(ret), 1e-12) for v in (opened, shadowed)]
            replays.append((opened, shadowed, closed, rel[0], rel[1], step_diff, STEPS if parted is None else parted))
            line += (f"; dm_control: open-loop {opened:7.2f} ({rel[0]:.1e}, parts at step {parted}), step by step "
                     f"{shadowed:7.2f} ({rel[1]:.1e}, one step {step_diff:.1e}), closed loop {closed:7.2f}")
        if args.optimise:
            best, converged = optimised_return(chain, np.vstack([run.x, run.final]), run.u[:, 1])
            optimised.append((best, converged))
            line += f"; optimised near it {best:8.2f} ({'converged' if converged else 'not converged'})"
        if not args.quiet:
            print(line, flush=True)
    r = np.array(returns)
    ms, cms = np.concatenate(times) * 1e3, np.concatenate(cpus) * 1e3
    print(f"\n{len(r)} episodes (random = {args.seed} ... {args.seed + len(r) - 1}), {time.perf_counter() - wall:.0f} s")
    print(f"return: mean {r.mean():.2f}, std {r.std(ddof=1) if len(r) > 1 else 0.0:.2f}, min {r.min():.2f}, "
          f"median {np.median(r):.2f}, max {r.max():.2f}; mean / TD-MPC2's {TD_MPC2:g} = {r.mean() / TD_MPC2:.3f}")
    if optimised:
        o, ok = (np.array(c) for c in zip(*optimised))
        up = r > 0.01 * STEPS  # the runs that swing up at all (a whirling elbow's return is ~0: no ratio of it)
        gains = o[up] / r[up] if up.any() else np.array([np.nan])
        print(f"optimised near each run (IPOPT, the run as its start; converged {int(ok.sum())} of {len(o)}, the others' "
              f"last iterate): mean {o.mean():.2f} ({o.mean() / r.mean():.3f} x the controller's), keeping the better of "
              f"run and optimum {np.maximum(o, r).mean():.2f}; over the {int(up.sum())} runs that swing up the ratio "
              f"ranges {gains.min():.3f} ... {gains.max():.3f}")
    if replays:
        opened, shadowed, closed, rel_open, rel_shadow, step_diff, parted = (np.array(c) for c in zip(*replays))
        k = int(np.argmax(rel_open))
        print(f"replay in dm_control, open-loop: largest relative return difference {rel_open.max():.2e} (episode {k}), "
              f"median {np.median(rel_open):.2e}; within 1 %: {int(np.sum(rel_open <= 0.01))} of {len(r)}; mean return "
              f"{opened.mean():.2f}; the states part (> 1e-3) at step {int(parted.min())} at the earliest, median "
              f"{int(np.median(parted))}")
        print(f"replay in dm_control, step by step (its state set to skewpend's before each step): largest relative "
              f"return difference {rel_shadow.max():.2e}, largest one-step state difference {step_diff.max():.2e}")
        print(f"the same controller closed-loop in dm_control's physics: mean return {closed.mean():.2f} (std "
              f"{closed.std(ddof=1) if len(r) > 1 else 0.0:.2f}, min {closed.min():.2f}); mean / skewpend's mean "
              f"{closed.mean() / r.mean():.4f}; mean / TD-MPC2's = {closed.mean() / TD_MPC2:.3f}")
    print(f"solves {ms.size} (skewpend's runs; the control step is {DT * 1e3:g} ms): CPU time (the thread's) median "
          f"{np.median(cms):.3f} ms, p99 {np.percentile(cms, 99):.3f} ms, max {cms.max():.3f} ms; wall time median "
          f"{np.median(ms):.3f} ms, p99 {np.percentile(ms, 99):.3f} ms, max {ms.max():.3f} ms; fallbacks {fallbacks}")


if __name__ == "__main__":
    main()
