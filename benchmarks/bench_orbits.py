"""Periodic orbits: skewpend's nonlinear normal modes, and one Newton solve against heyoka.py.

Model: the built-in one, ``skewpend.reference_parameters()`` (a=1, b=0.8, m1=1, m2=0.7,
alpha=0.6, g=9.81, conservative).

1. Both backbones: ``skewpend.nnm(p, mode=1)`` and ``mode=2`` at their defaults (pseudo-arclength
   continuation from the linear mode up to the flip energy, orbits at rtol = atol = 1e-12).  Warm:
   one untimed call of each first (the compiled kernels loaded; its time is shown as "first
   call"); best and median of ``--repeat`` interleaved runs (mode 1, mode 2, mode 1, ...), and the
   median of the per-run sums.  Goal (the issue): at least 200 orbits each, up to the flip energy,
   in <= 10 s together on this 2-core machine.

2. One orbit's Newton solve, side by side.  The orbit of the mode-2 family closest to 3 J (from
   ``nnm`` above) is perturbed: start x0 -> x0 + 1e-3 * s * (+1, -1, +1, -1), s = (A, A, wA, wA)
   with A = max(|phi0|, |psi0|) and w = 2 pi / T (the velocities of a start on the orbit are ~0,
   so a relative perturbation of them would be none), and period T -> T (1 + 1e-3).  The
   energy is kept at the orbit's.  Then it is solved

   a) by ``skewpend.periodic_orbit(p, guess, period_guess, energy=E)`` (its defaults: flow at
      rtol = atol = 1e-12 by the compiled variational equations ``sp_flow``);
   b) by the same single-shooting Gauss-Newton written here on heyoka.py: unknowns (x0, T);
      residuals the closure ``phi_T(x0) - x0`` (4), the phase condition
      ``<f(x_ref), x0 - x_ref> = 0`` (x_ref = the guess, as skewpend's) and the energy
      ``H(x0) = E``; the same scaling of unknowns and residuals as skewpend's (angles 1 rad,
      speeds w rad/s, period T, energy E), the same damping of wild steps and the same stopping
      rule (scaled residual < 1e-10 and step < 1e-7, then one last flow at the new point); the
      6 x 5 system by ``numpy.linalg.lstsq``.  The flow and its state-transition matrix come from
      ``hy.var_ode_sys(sys, hy.var_args.vars, order=1)`` in ``hy.taylor_adaptive(...,
      compact_mode=False, tol=1e-12)`` (``state[4 + 4 i + j] = d x_i / d x0_j``, checked with
      ``get_mindex``); f(x), H and grad H from one ``hy.cfunc`` (H = T + Pi of skewpend's
      derivation, its gradient by SymPy).

   Each method: median time per solve (each timed run is ``--solves`` solves; heyoka's JIT
   compilation, of the integrator and of the cfunc, is timed on its own -- cold, with heyoka's
   on-disk cache off, and from that cache -- and is not part of the per-solve time), Newton
   iterations (flows - 1), flows, integrator steps, and the periods found (they must agree to
   ~1e-9 relative).

The equations are not typed: they are skewpend's derivation (SymPy M(q), f(q, q')), q'' = M^-1 f,
converted with ``hy.from_sympy`` as in bench_lyapunov.py.  The machine may be shared: runs are
interleaved and medians reported.

Run:  python benchmarks/bench_orbits.py [--repeat 5] [--solves 10]
"""

from __future__ import annotations

import argparse
import os
import math
import platform
import time

import numpy as np

from _common import compile_times, cpu_model, version  # benchmarks/ is on sys.path when run

E_PICK = 3.0  # J: the mode-2 orbit to re-solve
PERTURB = 1e-3  # relative perturbation of the start and the period
HY_TOL = 1e-12
NEWTON_TOL, NEWTON_MAX = 1e-10, 25  # as skewpend.analysis.orbits
NAMES = ("phi", "psi", "dphi", "dpsi")
GOAL_ORBITS, GOAL_SECONDS = 200, 10.0
GOAL_SOLVE = 0.8  # issue 28: one Newton solve <= 0.8x heyoka's time (median)


# ----------------------------------------------------------------------------- timing
def measure(fns, repeat, inner=1):
    """Warm-up call each (timed, returned as 'first'), then ``repeat`` interleaved timed runs of
    ``inner`` calls each: {label: (best, median, per-run times, first, result)}, times per call."""
    times = {lab: [] for lab in fns}
    first, out = {}, {}
    for lab, fn in fns.items():
        t0 = time.perf_counter()
        out[lab] = fn()
        first[lab] = time.perf_counter() - t0
    for _ in range(repeat):
        for lab, fn in fns.items():
            t0 = time.perf_counter()
            for _ in range(inner):
                out[lab] = fn()
            times[lab].append((time.perf_counter() - t0) / inner)
    return {lab: (min(t), float(np.median(t)), t, first[lab], out[lab]) for lab, t in times.items()}


# ----------------------------------------------------------------------------- heyoka
def equations(params):
    """skewpend's derived equations for heyoka: the system, and [f(x) (4), H, dH/dx (4)] as expressions."""
    import heyoka as hy
    import sympy as sp

    from skewpend import SYMBOLS, derive

    eom = derive(params.replace(c1=0.0, c2=0.0, tau1=0.0, tau2=0.0))
    M, f = eom.mass_matrix, eom.forcing
    det = M[0, 0] * M[1, 1] - M[0, 1] ** 2
    qdd = [sp.N((M[1, 1] * f[0] - M[0, 1] * f[1]) / det, 17), sp.N((M[0, 0] * f[1] - M[0, 1] * f[0]) / det, 17)]
    H = sp.N(eom.kinetic_energy + eom.potential_energy, 17)
    X = [SYMBOLS[n] for n in NAMES]
    v = hy.make_vars(*NAMES)
    names = dict(zip(X, v))
    rhs = [v[2], v[3], hy.from_sympy(qdd[0], names), hy.from_sympy(qdd[1], names)]
    sys_ = list(zip(v, rhs))
    extras = rhs + [hy.from_sympy(H, names)] + [hy.from_sympy(sp.diff(H, x), names) if sp.diff(H, x) != 0
                                                else hy.expression(0.0) for x in X]
    return sys_, extras, v


def check_layout(ta):
    """state[4 + 4 i + j] must be d x_i / d x0_j (multiindex [i, e_j]): the STM is state[4:].reshape(4, 4)."""
    sl = ta.get_vslice(order=1)
    want = [[i] + [int(k == j) for k in range(4)] for i in range(4) for j in range(4)]
    assert (sl.start, sl.stop) == (4, 20) and [list(ta.get_mindex(n)) for n in range(4, 20)] == want, "layout"


class HeyokaShooting:
    """Single-shooting Gauss-Newton as skewpend's ``_newton`` (fixed energy, no arclength row)."""

    def __init__(self, ta, cf):
        self.ta, self.cf = ta, cf
        self.flows = self.steps = 0

    def shoot(self, x0, T):
        ta = self.ta
        ta.time = 0.0
        st = ta.state  # writable view
        st[:4] = x0
        st[4:] = np.eye(4).ravel()
        res = ta.propagate_until(T)
        self.flows += 1
        self.steps += res[3]
        return st[:4].copy(), st[4:].reshape(4, 4).copy()

    def solve(self, x0, T, E, ref):
        self.flows = self.steps = 0
        x0, T = np.array(x0, dtype=float), float(T)
        w = 2 * math.pi / T
        su = np.array([1.0, 1.0, w, w, T])  # unknowns' units: angle, speed, period (skewpend's _scales_for)
        se = max(abs(E), 1e-300)
        f_ref = self.cf(ref)[:4]
        n_ref = float(np.linalg.norm(f_ref / su[:4])) or 1.0
        for it in range(1, NEWTON_MAX + 1):
            y, stm = self.shoot(x0, T)
            ev0, evT = self.cf(x0), self.cf(y)
            r = np.r_[(y - x0) / su[:4], float(f_ref @ (x0 - ref)) / n_ref, (ev0[4] - E) / se]
            J = np.vstack([
                np.hstack([(stm - np.eye(4)) * su[None, :4] / su[:4, None], (evT[:4] * su[4] / su[:4])[:, None]]),
                np.r_[f_ref * su[:4] / n_ref, 0.0],
                np.r_[ev0[5:9] * su[:4] / se, 0.0],
            ])
            residual = float(np.max(np.abs(r)))
            du, *_ = np.linalg.lstsq(J, -r, rcond=None)
            step = float(np.max(np.abs(du)))
            if step > 0.5:
                du *= 0.5 / step
            x0 = x0 + du[:4] * su[:4]
            T = T + du[4] * su[4]
            if residual < NEWTON_TOL and step < 1e3 * NEWTON_TOL:
                y, stm = self.shoot(x0, T)
                return {"state": x0, "period": T, "monodromy": stm, "iterations": it, "residual": residual,
                        "flows": self.flows, "steps": self.steps}
        raise RuntimeError("heyoka Gauss-Newton did not converge")


# ----------------------------------------------------------------------------- main
def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--solves", type=int, default=10, help="Newton solves per timed run (part 2)")
    args = ap.parse_args()
    import heyoka as hy

    import skewpend

    p = skewpend.reference_parameters()
    from skewpend.analysis.orbits import flip_energy

    E_flip = flip_energy(p)
    print("Periodic orbits, skewed double pendulum (reference parameters): "
          f"a={p.a:g} b={p.b:g} m1={p.m1:g} m2={p.m2:g} alpha={p.alpha:g} g={p.g:g}")
    print(f"  flip energy {E_flip:.6g} J; orbits at rtol = atol = 1e-12 (skewpend), tol {HY_TOL:g} (heyoka)")
    print(f"  cpu        {cpu_model()}")
    print(f"  python     {platform.python_version()}   numpy {version('numpy')}   sympy {version('sympy')}")
    print(f"  skewpend   {version('skewpend')}   heyoka {version('heyoka')}")

    # -- 1. both backbones
    fam = measure({1: lambda: skewpend.nnm(p, mode=1), 2: lambda: skewpend.nnm(p, mode=2)}, args.repeat)
    together = [a + b for a, b in zip(fam[1][2], fam[2][2])]
    print(f"\n1. Backbones: skewpend.nnm(p, mode=1|2) to the flip energy; warm, best and median of "
          f"{args.repeat} interleaved runs")
    print(f"{'':14s} {'first s':>8s} {'best s':>8s} {'median s':>9s} {'orbits':>7s} {'flows':>6s} {'steps':>8s}"
          f"  {'E range [J]':22s} {'status'}")
    for m in (1, 2):
        _, med, _, first, f = fam[m]
        print(f"{'mode ' + str(m):14s} {first:8.3f} {fam[m][0]:8.3f} {med:9.3f} {len(f):7d} {f.stats['flows']:6d} "
              f"{f.stats['steps']:8d}  {f.energies[0]:.3g} .. {f.energies[-1]:.6g}{'':6s} {f.status.name}")
    n1, n2 = len(fam[1][4]), len(fam[2][4])
    reach = all(f[4].ok and f[4].energies.max() >= E_flip * (1 - 1e-9) for f in fam.values())
    med_tog = float(np.median(together))
    ok = n1 >= GOAL_ORBITS and n2 >= GOAL_ORBITS and reach and med_tog <= GOAL_SECONDS
    print(f"{'together':14s} {fam[1][3] + fam[2][3]:8.3f} {min(together):8.3f} {med_tog:9.3f} {n1 + n2:7d}")
    print(f"  goal: >= {GOAL_ORBITS} orbits each up to the flip energy in <= {GOAL_SECONDS:g} s together: "
          f"{'met' if ok else 'NOT met'} ({n1} and {n2} orbits, {med_tog:.2f} s)")
    for m in (1, 2):
        f = fam[m][4]
        ev = "; ".join(f"{e.kind} at {e.energy:.4g} J" for e in f.events) or "none"
        print(f"  mode {m}: frequency {f.frequencies[0]:.6g} -> {f.frequencies[-1]:.6g} rad/s; events: {ev}")

    # -- 2. one Newton solve, side by side
    f2 = fam[2][4]
    k = int(np.argmin(np.abs(f2.energies - E_PICK)))
    x_orb, T_orb, E = f2.states[k].copy(), float(f2.periods[k]), float(f2.energies[k])
    A, w = float(np.max(np.abs(x_orb[:2]))), 2 * math.pi / T_orb
    guess = x_orb + PERTURB * np.array([A, A, w * A, w * A]) * np.array([1.0, -1.0, 1.0, -1.0])
    T_guess = T_orb * (1 + PERTURB)

    sys_, extras, v = equations(p)
    vsys = hy.var_ode_sys(sys_, hy.var_args.vars, order=1)
    c_ta, d_ta, ta = compile_times(lambda: hy.taylor_adaptive(vsys, list(guess), tol=HY_TOL, compact_mode=False))
    check_layout(ta)
    c_cf, d_cf, cf = compile_times(lambda: hy.cfunc(extras, v))
    hs = HeyokaShooting(ta, cf)

    def sk():
        return skewpend.periodic_orbit(p, guess, T_guess, energy=E, throw=True)

    def he():
        return hs.solve(guess, T_guess, E, guess)

    res = measure({"skewpend": sk, "heyoka": he}, args.repeat, inner=args.solves)
    so, ho = res["skewpend"][4], res["heyoka"][4]
    print(f"\n2. One orbit's Newton solve: mode 2 orbit #{k} at E = {E:.6g} J, T = {T_orb:.12g} s; start and "
          f"period perturbed by {PERTURB:g} relative")
    print(f"   warm; per solve, best and median of {args.repeat} interleaved runs of {args.solves} solves")
    print(f"{'method':44s} {'best ms':>8s} {'median ms':>10s} {'iters':>6s} {'flows':>6s} {'steps':>7s}  period [s]")
    print(f"{'heyoka compile var_ode_sys (cold JIT)':44s} {c_ta * 1e3:8.1f} {c_ta * 1e3:10.1f}   "
          f"(from heyoka's disk cache: {d_ta * 1e3:.0f} ms)")
    print(f"{'heyoka compile cfunc f, H, grad H (cold JIT)':44s} {c_cf * 1e3:8.1f} {c_cf * 1e3:10.1f}   "
          f"(from heyoka's disk cache: {d_cf * 1e3:.0f} ms)")
    st = so.stats
    print(f"{'skewpend periodic_orbit (sp_flow, 1e-12)':44s} {res['skewpend'][0] * 1e3:8.2f} "
          f"{res['skewpend'][1] * 1e3:10.2f} {st['newton_iterations']:6d} {st['flows']:6d} {st['steps']:7d}  "
          f"{so.period:.15g}")
    print(f"{'heyoka var_ode_sys Gauss-Newton (tol 1e-12)':44s} {res['heyoka'][0] * 1e3:8.2f} "
          f"{res['heyoka'][1] * 1e3:10.2f} {ho['iterations']:6d} {ho['flows']:6d} {ho['steps']:7d}  "
          f"{ho['period']:.15g}")
    dT = so.period - ho["period"]
    print(f"\n  periods: skewpend - heyoka = {dT:+.3e} s ({abs(dT) / ho['period']:.1e} relative; "
          f"want ~1e-9);  vs nnm's orbit: skewpend {abs(so.period - T_orb) / T_orb:.1e}, "
          f"heyoka {abs(ho['period'] - T_orb) / T_orb:.1e} relative")
    print(f"  starts:  max |skewpend - heyoka| = {np.max(np.abs(so.state - ho['state'])):.2e};  "
          f"energies H(x0) - E: skewpend {so.energy - E:+.1e}, heyoka {cf(ho['state'])[4] - E:+.1e} J")
    print(f"  sigma = trace(monodromy) - 2: skewpend {so.sigma:.9f}, heyoka {np.trace(ho['monodromy']) - 2:.9f}")
    print(f"  skewpend / heyoka time per solve: best {res['skewpend'][0] / res['heyoka'][0]:.2f}x, "
          f"median {res['skewpend'][1] / res['heyoka'][1]:.2f}x;  goal (issue 28) <= {GOAL_SOLVE:g}x (median): "
          f"{'met' if res['skewpend'][1] / res['heyoka'][1] <= GOAL_SOLVE else 'NOT met'}")
    print(f"load average at the end: {os.getloadavg()[0]:.2f} (the machine may be shared)")


if __name__ == "__main__":
    main()
