"""skewpend's leaderboard controller in the DFKI lab's own simulator and robustness benchmark, beside skewpend's.

The lab's package (``double_pendulum`` of dfki-ric-underactuated-lab/double_pendulum, not on PyPI) is imported
from ``--dfki DIR`` (its ``src/python``, e.g. from a checkout or a snapshot of the repository). For each robot:

1. skewpend's optimal swing-up tracked by TVLQR (``optimal_swingup``, ``tvlqr``), run by the lab's
   ``Simulator`` (its plant, ``plant.py``, with the model 1.1 numbers; its RK4 and clipping) through the
   DFKI interface (``get_control_output``), against skewpend's ``run_protocol``: the largest difference of
   the states over the 10 s, and the leaderboard score of each run;
   ``--controller mpc``: the model-predictive controller (``skewpend.MPC`` with the boards' settings,
   ``BOARD_SETTINGS``: the CLI's) instead, by the same interface;
2. ``--robustness``: the lab's ``benchmarker`` with the robustness board's settings (v2: 21 values, 10
   repetitions, 50 perturbations; the lab's unseeded noise) running ``SpeedObserver(tracking)`` (the speeds
   from the positions), its six criteria by the lab's ``benchmark_scores``, beside skewpend's
   ``robustness`` (seed 0). The lab's simulator is pure Python: about 5 minutes per robot on 2 cores.

    python benchmarks/bench_dfki_simulator.py --dfki DIR [--robots acrobot pendubot] [--robustness] [--controller mpc]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from _common import cpu_model, version  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dfki", type=Path, required=True, help="the lab's src/python (holds double_pendulum/)")
    ap.add_argument("--robots", nargs="+", default=["acrobot", "pendubot"])
    ap.add_argument("--robustness", action="store_true")
    ap.add_argument("--controller", choices=["tvlqr", "mpc"], default="tvlqr",
                    help="skewpend's controller: the optimal swing-up tracked by TVLQR, or the model-predictive one")
    args = ap.parse_args()
    sys.path.insert(0, str(args.dfki))
    from double_pendulum.model.model_parameters import model_parameters
    from double_pendulum.model.plant import DoublePendulumPlant
    from double_pendulum.simulation.simulation import Simulator

    from skewpend.analysis import leaderboard as lb
    from skewpend.analysis import robustness as rb
    from skewpend.analysis.trajopt import SpeedObserver, optimal_swingup, tvlqr
    from skewpend.datasets import example_data
    from skewpend.numeric.kernels import model_kernel, model_vector

    print(f"skewpend {version('skewpend')}, {cpu_model()}, {os.cpu_count()} cores")
    model = lb.dfki_model()
    for robot in args.robots:
        joints = lb.ROBOTS[robot]
        if args.controller == "mpc":
            from skewpend.analysis.mpc import BOARD_SETTINGS, MPC

            tracking = MPC(model, actuated=joints, settings=BOARD_SETTINGS)
        else:
            tracking = tvlqr(optimal_swingup(model, actuated=joints))
        mpar = model_parameters(filepath=str(example_data("dfki-design-C.1/model_1.1_parameters.yml")))
        mpar.set_torque_limit([0.0, 6.0] if joints == (2,) else [6.0, 0.0])
        plant = DoublePendulumPlant(model_pars=mpar)
        sim = Simulator(plant=plant)
        t0 = time.perf_counter()
        T, X, U = sim.simulate(t0=0.0, x0=[0.0, 0.0, 0.0, 0.0], tf=10.0, dt=0.002, controller=tracking,
                               integrator="runge_kutta")
        theirs_s = time.perf_counter() - t0
        X, U = np.asarray(X), np.asarray(U)
        ours = lb.run_protocol(model, tracking, actuated=joints)  # (the MPC: a call at t = 0 starts a new run)
        k = min(len(ours.x), len(X))
        diff = float(np.max(np.abs(X[:k] - ours.x[:k])))
        rows = len(U)
        heights = lb.tip_heights(model_kernel(model), model_vector(model), X[:rows])
        c = lb.criteria(np.asarray(T)[:rows], X[:rows], U, heights, lb.model_reach(model))
        print(f"{robot}: the lab's Simulator {theirs_s:.1f} s; largest state difference from run_protocol over "
              f"{k} rows {diff:.2e}; score there {c.score:.4f}, by run_protocol {ours.score:.4f}")
        if not args.robustness:
            continue
        from double_pendulum.analysis.benchmark import benchmarker
        from double_pendulum.analysis.benchmark_scores import (get_delay_score, get_measurement_noise_score,
                                                               get_model_score, get_perturbation_score,
                                                               get_unoise_score, get_uresponsiveness_score)
        from double_pendulum.analysis.utils import get_par_list

        s = rb.ROBUSTNESS
        mpar.set_motor_inertia(0.0)
        ben = benchmarker(controller=SpeedObserver(tracking), x0=[0.0] * 4, dt=0.002, t_final=10.0,
                          goal=[np.pi, 0.0, 0.0, 0.0], epsilon=[s.angle_tolerance] * 2 + [s.speed_tolerance] * 2,
                          check_only_final_state=True, integrator="runge_kutta")
        ben.set_model_parameter(model_pars=mpar)
        lists = {"Ir": np.linspace(0.0, s.rotor_max, s.values),
                 "b1": np.linspace(-s.damping_max, s.damping_max, s.values),
                 "b2": np.linspace(-s.damping_max, s.damping_max, s.values),
                 "cf1": np.linspace(-s.friction_max, s.friction_max, s.values),
                 "cf2": np.linspace(-s.friction_max, s.friction_max, s.values)}
        for key, nominal in (("m1r1", mpar.m[0] * mpar.r[0]), ("I1", mpar.I[0]), ("m2r2", mpar.m[1] * mpar.r[1]),
                             ("m2", mpar.m[1]), ("I2", mpar.I[1])):
            lists[key] = get_par_list(nominal, *s.relative, s.values)
        t0 = time.perf_counter()
        res = ben.benchmark(compute_model_robustness=True, compute_noise_robustness=True,
                            compute_unoise_robustness=True, compute_uresponsiveness_robustness=True,
                            compute_delay_robustness=True, compute_perturbation_robustness=True,
                            mpar_vars=list(rb.LAB_VARIATIONS), modelpar_var_lists=lists,
                            repetitions=s.repetitions, meas_noise_mode="vel",
                            meas_noise_sigma_list=np.linspace(0.0, s.velocity_noise_max, s.values),
                            u_noise_sigma_list=np.linspace(0.0, s.torque_noise_max, s.values),
                            u_responses=np.linspace(*s.responsiveness, s.values), delay_mode="posvel",
                            delays=np.linspace(0.0, s.delay_max, s.values),
                            perturbation_repetitions=s.perturbation_runs,
                            perturbations_per_joint=s.pulses_per_joint, perturbation_min_t_dist=s.pulse_gap,
                            perturbation_sigma_minmax=list(s.pulse_width),
                            perturbation_amp_minmax=list(s.pulse_amplitude))
        theirs_s = time.perf_counter() - t0
        scores = [get_model_score(res), get_measurement_noise_score(res), get_unoise_score(res),
                  get_uresponsiveness_score(res), get_delay_score(res), get_perturbation_score(res)]
        mine = rb.robustness(tracking, actuated=joints, speeds="positions")
        print(f"  the lab's benchmarker ({theirs_s:.0f} s) against skewpend's robustness ({mine.simulations} runs):")
        for key, theirs in zip(rb.CRITERIA, scores):
            print(f"    {key:16s} lab {theirs:6.3f}   skewpend {mine.criteria[key]:6.3f}")
        print(f"    {'score':16s} lab {np.mean(scores):6.3f}   skewpend {mine.score:6.3f}", flush=True)


if __name__ == "__main__":
    main()
