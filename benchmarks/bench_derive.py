"""Benchmark: skewpend's derivation against sympy.physics.mechanics, as whole fresh processes.

The skewed double pendulum (thin rods; a, b, m1, m2, g and the skew angle alpha all
symbolic) is derived in the form ``M(q) q'' = f(q, q')`` by

* ``skewpend``       -- ``skewpend.derive()`` (then touching ``mass_matrix`` and ``forcing``);
* ``kane``           -- ``KanesMethod``, raw (unsimplified) ``mass_matrix`` and ``forcing``, u = q';
* ``lagrange``       -- ``LagrangesMethod``, raw ``mass_matrix`` and ``forcing``;
* ``kane+simplify``  -- ``KanesMethod`` then ``sympy.simplify`` of every entry
  (only with ``--simplified``: slow, ~8 s per run here, more on slower machines).

Each method runs ``--repeat`` times (default 3) as a fresh ``python`` process (this very
script with a hidden ``--child`` argument); the wall-clock time of the whole process,
Python start-up and imports included, is measured and its median and minimum reported,
with the ratio of each median to skewpend's.  "ops" is ``sympy.count_ops`` summed over the
entries of M and f.  Untimed, in this process, the accelerations ``M^-1 f`` of every method
are compared with skewpend's at random numeric points (they must agree to ~1e-12).

Run from the project root (skewpend installed, e.g. in .venv)::

    .venv/bin/python benchmarks/bench_derive.py [--repeat N] [--simplified]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

METHODS = ("skewpend", "kane", "lagrange", "kane+simplify")


def build_skewpend():
    import skewpend
    from skewpend.symbolic.derivation import SYMBOLS as S

    eom = skewpend.derive()
    names = {n: S[n] for n in ("a", "b", "m1", "m2", "g", "alpha", "phi", "psi", "dphi", "dpsi")}
    return eom.mass_matrix, eom.forcing, names


def _mechanics_model():
    """The same pendulum in sympy.physics.mechanics: frames, points, bodies, gravity loads."""
    import sympy as sp
    from sympy.physics import mechanics as me

    a, b, m1, m2, g = sp.symbols("a b m1 m2 g", positive=True)
    alpha = sp.Symbol("alpha", real=True)
    q1, q2, u1, u2 = me.dynamicsymbols("q1 q2 u1 u2")
    N, A, B = me.ReferenceFrame("N"), me.ReferenceFrame("A"), me.ReferenceFrame("B")
    A.orient_axis(N, N.z, q1)  # rod 1: phi about k (j = N.y points down)
    B.orient_axis(A, sp.cos(alpha) * A.z + sp.sin(alpha) * A.x, q2)  # rod 2: psi about e0, fixed in A
    O = me.Point("O")
    O.set_vel(N, 0)
    H = O.locatenew("H", a * A.y)  # second hinge, end of rod 1
    G1 = O.locatenew("G1", a / 2 * A.y)
    G2 = H.locatenew("G2", b / 2 * B.y)
    for point, base, frame in ((G1, O, A), (H, O, A), (G2, H, B)):
        point.v2pt_theory(base, N, frame)
    bodies = [
        me.RigidBody("rod1", G1, A, m1, (m1 * a**2 / 12 * me.inertia(A, 1, 0, 1), G1)),
        me.RigidBody("rod2", G2, B, m2, (m2 * b**2 / 12 * me.inertia(B, 1, 0, 1), G2)),
    ]
    loads = [(G1, m1 * g * N.y), (G2, m2 * g * N.y)]
    names = dict(a=a, b=b, m1=m1, m2=m2, g=g, alpha=alpha, phi=q1, psi=q2)
    return N, bodies, loads, (q1, q2, u1, u2), names


def build_kane(simplify: bool = False):
    import sympy as sp
    from sympy.physics import mechanics as me

    N, bodies, loads, (q1, q2, u1, u2), names = _mechanics_model()
    kane = me.KanesMethod(N, q_ind=[q1, q2], u_ind=[u1, u2], kd_eqs=[q1.diff() - u1, q2.diff() - u2])
    kane.kanes_equations(bodies, loads)
    M, f = kane.mass_matrix, kane.forcing
    if simplify:
        M, f = M.applyfunc(sp.simplify), f.applyfunc(sp.simplify)
    return M, f, dict(names, dphi=u1, dpsi=u2)


def build_lagrange():
    from sympy.physics import mechanics as me

    N, bodies, loads, (q1, q2, _, _), names = _mechanics_model()
    lag = me.LagrangesMethod(me.Lagrangian(N, *bodies), [q1, q2], forcelist=loads, frame=N)
    lag.form_lagranges_equations()
    return lag.mass_matrix, lag.forcing, dict(names, dphi=q1.diff(), dpsi=q2.diff())


BUILDERS = {
    "skewpend": build_skewpend,
    "kane": build_kane,
    "lagrange": build_lagrange,
    "kane+simplify": lambda: build_kane(simplify=True),
}


def time_process(method: str, repeat: int) -> list:
    """Wall-clock seconds of ``repeat`` fresh processes each building ``method`` once."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, __file__, "--child", method], check=True)
        times.append(time.perf_counter() - t0)
    return times


def accelerations(M, f, names: dict, point: dict):
    """``M^-1 f`` at a numeric point given by name (parameters, angles, speeds)."""
    import numpy as np
    from sympy.physics.mechanics import msubs

    sub = {names[k]: v for k, v in point.items()}
    Mn = np.array(msubs(M, sub).evalf(), dtype=float)
    fn = np.array(msubs(f, sub).evalf(), dtype=float).ravel()
    return np.linalg.solve(Mn, fn)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="processes per method (default 3)")
    parser.add_argument("--simplified", action="store_true", help="also time KanesMethod + simplify (slow)")
    parser.add_argument("--child", choices=METHODS, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:  # the timed work of one fresh process
        BUILDERS[args.child]()
        return

    import numpy as np
    import sympy as sp

    methods = [m for m in METHODS if m != "kane+simplify" or args.simplified]
    print(f"python {sys.version.split()[0]}, sympy {sp.__version__}, {args.repeat} fresh process(es) per method")
    times = {}
    for m in methods:
        times[m] = time_process(m, args.repeat)
        print(f"  timed {m:<14} {', '.join(f'{t:.2f}' for t in times[m])} s", flush=True)

    # Untimed, in this process: sizes of the results and the cross-check of the accelerations.
    results = {m: BUILDERS[m]() for m in methods}
    ops = {m: sum(sp.count_ops(x) for x in (*M, *f)) for m, (M, f, _) in results.items()}
    rng = np.random.default_rng(0)
    points = []
    for _ in range(5):
        a, b, m1, m2 = rng.uniform(0.2, 2.0, 4)
        alpha, phi, psi = rng.uniform(-np.pi, np.pi, 3)
        dphi, dpsi = rng.uniform(-4.0, 4.0, 2)
        points.append(dict(a=a, b=b, m1=m1, m2=m2, g=9.81, alpha=alpha, phi=phi, psi=psi, dphi=dphi, dpsi=dpsi))
    ref = [accelerations(*results["skewpend"], p) for p in points]
    diff = {
        m: max(float(np.max(np.abs(accelerations(*results[m], p) - r))) for p, r in zip(points, ref))
        for m in methods[1:]
    }

    base = statistics.median(times["skewpend"])
    print(f"\n{'method':<15}{'median s':>10}{'min s':>9}{'ops':>9}{'x skewpend':>12}")
    for m in methods:
        med = statistics.median(times[m])
        print(f"{m:<15}{med:>10.3f}{min(times[m]):>9.3f}{ops[m]:>9}{med / base:>12.2f}")
    print(f"\nmax |M^-1 f - M_skewpend^-1 f_skewpend| over {len(points)} random points (seed 0):")
    for m, d in diff.items():
        flag = "ok" if d < 1e-9 else "MISMATCH -- skewpend's accelerations disagree: likely a bug in skewpend"
        print(f"  {m:<14} {d:.2e}  {flag}")


if __name__ == "__main__":
    main()
