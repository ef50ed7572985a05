"""The rotary pendulum (examples/qube_servo2.toml, issue 54) swung up within the motor's voltage limit: the shortest
swing-up the optimiser finds, and the optimal swing-up tracked in closed loop.

1. Feasibility: ``shortest_swingup(chain, actuated=(1,), umax=kt V / R, goal=[0, pi], start=(0, 0.05, 0, 0),
   free=(1,))`` for each ``--volts`` -- from hanging (nudged 0.05 rad) to upright at rest, the arm's end angle
   free, bisected to ``--resolution`` s --, and the same shortest reach's torques applied open-loop in
   ``skewpend.simulate`` (Controller.tracking with no gain: the torques linear between knots): the largest gap
   between the simulation and the optimiser's knots (the RK4 step's error; the right-hand sides are one).
2. Closed loop: ``swingup_tracking(chain, --duration, ...)`` (the reach at 90 % of the limit, time-varying LQR,
   then the top's LQR), planned once from 0.05 rad, run from nudges of 0.05, -0.05, 0.02, 0.1 and 0 rad for 4 s,
   sampled every 2 ms and held: when the pendulum is within 0.1 rad of upright for good, its distance at 4 s, the
   largest torque over the limit, the arm's largest angle.

    python benchmarks/bench_rotary_swingup.py [--volts 3 10] [--duration 1.5] [--resolution 0.01] [--variants]

``--variants``: also the shortest at the run file's limit from hanging exactly and with the arm back at 0.
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

RUN_FILE = Path(__file__).resolve().parents[1] / "examples" / "qube_servo2.toml"
START = [0.0, 0.05, 0.0, 0.0]
NUDGES = (0.05, -0.05, 0.02, 0.1, 0.0)


def up_from(t, y, tolerance=0.1):
    """The time from which the pendulum stays within ``tolerance`` of upright (inf: not at the end)."""
    off = np.abs((y[:, 1] % (2 * math.pi)) - math.pi)
    out = np.flatnonzero(off >= tolerance)
    if not out.size:
        return 0.0, off
    return (math.inf if out[-1] == len(t) - 1 else float(t[out[-1] + 1])), off


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--volts", type=float, nargs="+", default=[3.0, 10.0])
    parser.add_argument("--duration", type=float, default=1.5, help="the tracked swing-up's duration [s] (at the "
                                                                     "run file's voltage limit)")
    parser.add_argument("--resolution", type=float, default=0.01)
    parser.add_argument("--knots", type=int, default=100)
    parser.add_argument("--skip-shortest", action="store_true")
    parser.add_argument("--variants", action="store_true", help="also at the run file's limit: from hanging exactly, "
                                                                  "and with the arm back at 0 at the end")
    args = parser.parse_args()

    import skewpend
    from skewpend.analysis.mpc import PERIOD
    from skewpend.analysis.trajopt import shortest_swingup, swingup_tracking
    from skewpend.config import Run
    from skewpend.numeric.control import Controller

    run = Run("simulate", str(RUN_FILE))
    chain, motor = run.chain(), run.motor
    print(f"rotary pendulum {RUN_FILE.name}: motor gain {motor.gain:.4g} N m/V, run file's limit "
          f"{motor.voltage_limit:g} V = {motor.torque_limit:.4g} N m", flush=True)
    if not args.skip_shortest:
        print("1. the shortest swing-up from hanging (0.05 rad) to upright at rest, the arm's end free:")
        for volts in args.volts:
            umax = motor.gain * volts
            t0 = time.perf_counter()
            r = shortest_swingup(chain, actuated=(1,), umax=umax, goal=[0.0, math.pi], start=START, free=(1,),
                                 durations=(0.1, 3.0), resolution=args.resolution, knots=args.knots)
            took = time.perf_counter() - t0
            if not r.ok:
                print(f"  {volts:g} V: none within 3 s ({r.message}); {took:.0f} s", flush=True)
                continue
            N = len(r.t) - 1
            law = Controller.tracking(r.duration / N, r.x, r.u, np.zeros((N + 1, chain.n, 2 * chain.n)),
                                      np.zeros((chain.n, 2 * chain.n)), r.goal, actuated=(1,), umax=umax)
            sim = skewpend.simulate(chain, r.x[0], r.duration, dt_out=r.duration / N, controller=law, rtol=1e-11,
                                    atol=1e-12)
            gap = np.max(np.abs(np.asarray(sim.y) - r.x), axis=0)
            print(f"  {volts:g} V (|u| <= {umax:.4g} N m): shortest {r.duration:.3f} s -- {r.message}; arm max "
                  f"{np.max(np.abs(r.x[:, 0])):.2f} rad, torque at the limit over "
                  f"{np.mean(np.abs(r.u[:, 0]) > 0.999 * umax):.0%} of the knots; open-loop in simulate vs the knots: "
                  f"angles {np.max(gap[:2]):.2g} rad, speeds {np.max(gap[2:]):.2g} rad/s ({N} knots); {took:.0f} s",
                  flush=True)
    if args.variants:
        for label, start, free in (("from hanging exactly (q = 0), the arm's end free", [0.0] * 4, (1,)),
                                   ("nudged 0.05 rad, the arm back at 0", START, ())):
            t0 = time.perf_counter()
            r = shortest_swingup(chain, actuated=(1,), umax=motor.torque_limit, goal=[0.0, math.pi], start=start,
                                 free=free, durations=(0.5, 3.0), resolution=args.resolution, knots=args.knots)
            print(f"  {motor.voltage_limit:g} V, {label}: shortest {r.duration:.3f} s -- {r.message}; "
                  f"{time.perf_counter() - t0:.0f} s", flush=True)
    umax = motor.torque_limit
    t0 = time.perf_counter()
    tracking = swingup_tracking(chain, args.duration, actuated=(1,), umax=umax, goal=[0.0, math.pi], start=START,
                                free=(1,))
    print(f"2. the {args.duration:g} s swing-up at 90 % of {motor.voltage_limit:g} V tracked (TVLQR, then the top's "
          f"LQR), sampled every {PERIOD * 1e3:g} ms; designed in {time.perf_counter() - t0:.0f} s:", flush=True)
    for nudge in NUDGES:
        applied = {}

        def law(t, x, applied=applied):
            k = int(np.floor(t / PERIOD + 0.5))
            if k not in applied:
                applied[k] = tracking(k * PERIOD, np.array(x))
            return applied[k]

        sim = skewpend.simulate(chain, [0.0, nudge, 0.0, 0.0], 4.0, dt_out=0.01,
                                controller=Controller.function(law, actuated=(1,), nq=2, hold=PERIOD))
        t, y = np.asarray(sim.t), np.asarray(sim.y)
        u = np.array([applied[k] for k in sorted(applied)])[:, 0]
        up, off = up_from(t, y)
        print(f"  nudge {nudge:+.2f} rad: within 0.1 rad of upright for good from {up:.2f} s, at 4 s {off[-1]:.1e} rad; "
              f"largest |V| {np.max(np.abs(motor.voltage(u))):.3f} V; arm max {np.max(np.abs(y[:, 0])):.2f} rad, at 4 s "
              f"{y[-1, 0]:+.2f} rad", flush=True)


if __name__ == "__main__":
    main()
