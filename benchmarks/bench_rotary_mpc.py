"""The rotary pendulum (examples/qube_servo2.toml, issue 54 item 4) under the model-predictive controller: swing-up
from hanging and balance from near the top within the motor's voltage limit, for several MPCSettings.

Each run: ``mpc_swingup(chain, target=[0, pi], actuated=(1,), umax=kt Vmax / R, y0=...)`` for ``--t-end`` s (the
pendulum nudged 0.05 rad off hanging, or 0.05 rad off upright for the balance runs).  Printed per run: whether
the pendulum came within 0.1 rad of upright and stayed (from when), its final distance from upright, the arm's
largest angle (full turns of the arm are what the energy term buys, see docs/guide/rotary-pendulum.md), the MPC's
fallbacks and median solve time.

    python benchmarks/bench_rotary_mpc.py [--volts 3] [--t-end 4]
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

RUN_FILE = Path(__file__).resolve().parents[1] / "examples" / "qube_servo2.toml"

#: (name, settings, start): the defaults (the horizon 4.7 time constants of the top's unstable mode, 0.32 s); short horizons (a greedy energy controller); horizons as long as a
#: swing-up (the first call a trajectory optimisation of 300 Gauss-Newton steps); balance from 0.05 rad off the top.
RUNS = (
    ("default (20 nodes; 0.32 s here)", {}, "hanging"),
    ("short 0.15 s, 6 nodes", dict(horizon=0.15, nodes=6), "hanging"),
    ("short 0.15 s, energy 1000, angle 30", dict(horizon=0.15, nodes=6, energy=1000.0, angle=30.0, speed=0.01), "hanging"),
    ("long 1.5 s, 30 nodes, no energy term", dict(horizon=1.5, nodes=30, energy=0.0, angle=10.0, speed=0.1, first=300,
                                                  iterations=3), "hanging"),
    ("long 1.2 s, 30 nodes, energy 10", dict(horizon=1.2, nodes=30, energy=10.0, angle=10.0, speed=0.1, first=300,
                                             iterations=2), "hanging"),
    ("default (20 nodes; 0.32 s here)", {}, "top"),
    ("short 0.1 s, 5 nodes, no energy term", dict(horizon=0.1, nodes=5, energy=0.0), "top"),
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--volts", type=float, default=None, help="the voltage limit (default: the run file's)")
    parser.add_argument("--t-end", type=float, default=4.0)
    args = parser.parse_args()

    from skewpend.analysis.mpc import MPCSettings, mpc_swingup
    from skewpend.config import Run

    run = Run("simulate", str(RUN_FILE))
    chain, motor = run.chain(), run.motor
    volts = motor.voltage_limit if args.volts is None else args.volts
    umax = motor.gain * volts
    arm, pendulum = chain.links
    # about the vertical with the pendulum hanging: the arm's, the pendulum's own and its mass at the arm's end
    arm_inertia = arm.inertia[1][1] + pendulum.inertia[1][1] + pendulum.mass * pendulum.offset[0] ** 2
    goal_energy = chain.links[1].mass * chain.g * 2 * chain.links[1].com[1]  # the pendulum from hanging to upright
    print(f"rotary pendulum {RUN_FILE.name}: |V| <= {volts:g} V, |u| <= {umax:.4g} N m, {args.t_end:g} s")
    for name, settings, start in RUNS:
        y0 = [0.0, 0.05, 0.0, 0.0] if start == "hanging" else [0.0, math.pi - 0.05, 0.0, 0.0]
        t0 = time.perf_counter()
        r = mpc_swingup(chain, target=[0.0, math.pi], actuated=(1,), umax=umax, y0=y0, t_end=args.t_end,
                        settings=MPCSettings(**settings))
        t, y = np.asarray(r.trajectory.t), np.asarray(r.trajectory.y)
        off = np.abs((y[:, 1] % (2 * math.pi)) - math.pi)
        out = np.flatnonzero(off >= 0.1)
        held = "never" if out.size and out[-1] == len(t) - 1 else f"{t[out[-1] + 1] if out.size else 0.0:.2f} s"
        late = t >= t[-1] / 2  # the run's second half: where the energy went
        turning = 0.5 * arm_inertia * float(np.mean(y[late, 2] ** 2))
        print(f"  from {start:7s} {name:40s} within 0.1 rad of upright for good from {held:>6s}; closest {np.min(off):.3f} "
              f"rad, final {off[-1]:.3f} rad; arm max {np.max(np.abs(y[:, 0])):.2f} rad, its turning energy over the second "
              f"half {turning / goal_energy:.2f} x the goal's; fallbacks {r.mpc.fallbacks}; solve median "
              f"{1e3 * np.median(r.mpc.solve_times):.2f} ms; {time.perf_counter() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
