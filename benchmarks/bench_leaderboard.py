"""skewpend's optimal swing-ups on the RealAIGym leaderboard, side by side with the best published entries.

For each robot (acrobot, pendubot) and skew angle (``--alphas``, default 0 15 30 60 deg): skewpend's optimal
swing-up (``optimal_swingup``: IPOPT on the generated dynamics) tracked by time-varying LQR (``tvlqr``), run
and scored by the leaderboard's protocol (``run_protocol``: RK4, 0.002 s, 10 s, 6 N m); the design's wall
time (2 cores), the criteria, the score, the ratio to the best published score (leaderboards v2), whether the
end effector stays up through the last second, the robustness board's score (v2, 722 runs, seed 0, the speeds
from the positions) and its ratio to the best published one, and how many times faster than real time the
compiled tracking law runs in ``skewpend.simulate`` (RK4 at 0.002 s; DOP853 at its default tolerances).

``--published DIR`` (a clone of dfki-ric-underactuated-lab/real_ai_gym_leaderboard) also recomputes the
criteria of every published simulation_v2 trajectory (``sim_swingup.csv``) with skewpend's scorer and prints
the largest relative difference from the lab's own ``scores.csv``.

    python benchmarks/bench_leaderboard.py [--alphas 0 15 30 60] [--published DIR]
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _common import cpu_model, version  # noqa: E402


def published(root: Path) -> None:
    from skewpend.analysis.leaderboard import criteria, dfki_model, read_csv, tip_heights
    from skewpend.numeric.kernels import model_kernel, model_vector

    model = dfki_model()
    kernel, p = model_kernel(model), model_vector(model)
    print("\npublished trajectories (simulation_v2) rescored by skewpend:")
    for robot in ("acrobot", "pendubot"):
        for entry in sorted((root / "data" / robot / "simulation_v2").iterdir()):
            t, x, u = read_csv(entry / "sim_swingup.csv")
            c = criteria(t, x, u, tip_heights(kernel, p, x), 0.5)
            mine = [float(c.success), c.swingup_time, c.energy, c.tau_cost, c.tau_smoothness, c.velocity_cost, c.score]
            theirs = [float(v) for v in (entry / "scores.csv").read_text().splitlines()[1].split(",")]
            worst = max(abs(a - b) / max(abs(b), 1e-300) for a, b in zip(mine, theirs))
            print(f"  {robot:9s} {entry.name:18s} score {c.score:.6f} (lab {theirs[-1]:.6f}), largest relative "
                  f"difference of the criteria {worst:.1e}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--alphas", type=float, nargs="+", default=[0.0, 15.0, 30.0, 60.0])
    ap.add_argument("--published", type=Path, default=None)
    args = ap.parse_args()
    from skewpend.analysis import leaderboard as lb
    from skewpend.analysis.trajopt import optimal_swingup, tvlqr

    print(f"skewpend {version('skewpend')}, {cpu_model()}, {os.cpu_count()} cores")
    from skewpend import simulate
    from skewpend.analysis import robustness as rb

    print(f"{'robot':9s} {'alpha':>6s} {'design s':>8s} {'time s':>7s} {'energy':>7s} {'tau':>6s} {'smooth':>8s} "
          f"{'vel':>7s} {'score':>6s} {'/best':>6s} {'up':>3s} {'robust':>6s} {'/best':>6s} {'rk4 x':>6s} {'dop x':>6s}")
    for robot in ("acrobot", "pendubot"):
        name, best = lb.PUBLISHED[robot]["simulation"]
        for alpha in args.alphas:
            model = lb.dfki_model(math.radians(alpha))
            lb.run_protocol(model, lambda t, x: (0.0, 0.0), protocol=lb.Protocol(t_final=0.01))  # compile first
            t0 = time.perf_counter()
            traj = optimal_swingup(model, actuated=lb.ROBOTS[robot])
            tracking = tvlqr(traj) if traj.ok else None
            design = time.perf_counter() - t0
            if tracking is None:
                print(f"{robot:9s} {alpha:6.0f} {design:8.1f}  {traj.message}")
                continue
            run = lb.run_protocol(model, tracking, actuated=lb.ROBOTS[robot])
            c = run.criteria
            last = run.t >= run.t[-1] - 1.0
            up = bool(np.all(run.heights[last] > 0.9 * run.reach))
            r = rb.robustness(tracking, actuated=lb.ROBOTS[robot], alpha=math.radians(alpha), speeds="positions")
            rname, _, rbest = rb.PUBLISHED_ROBUSTNESS[robot]
            ctl = tracking.controller()
            speed = []
            for kw in (dict(method="rk4", dt=0.002), dict(method="dop853")):
                simulate(model, t_end=10.0, y0=(0, 0, 0, 0), controller=ctl, dt_out=0.01, **kw)  # warm
                t1 = time.perf_counter()
                simulate(model, t_end=10.0, y0=(0, 0, 0, 0), controller=ctl, dt_out=0.01, **kw)
                speed.append(10.0 / (time.perf_counter() - t1))
            print(f"{robot:9s} {alpha:6.0f} {design:8.1f} {c.swingup_time:7.3f} {c.energy:7.3f} {c.tau_cost:6.3f} "
                  f"{c.tau_smoothness:8.5f} {c.velocity_cost:7.2f} {c.score:6.3f} {c.score / best:6.3f} "
                  f"{'yes' if up else 'no':>3s} {r.score:6.3f} {r.score / rbest:6.3f} {speed[0]:6.0f} {speed[1]:6.0f}",
                  flush=True)
        print(f"  best published ({robot}): simulation {name} {best:.3f}, robustness {rname} {rbest:.3f}")
    if args.published is not None:
        published(args.published)


if __name__ == "__main__":
    main()
