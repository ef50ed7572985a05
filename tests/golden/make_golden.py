"""Golden values of today's N = 2 results (issue 37): compute them with the code of a commit and write
``tests/golden/values.json``; ``tests/test_golden.py`` recomputes each quantity with the same function
here and compares it within a tolerance derived from its method (stated there).

    python tests/golden/make_golden.py                  # the committed HEAD (git archive to a temporary folder)
    python tests/golden/make_golden.py --commit da6199b # another commit's code (the values of issue 37's start)
    python tests/golden/make_golden.py --working-tree   # the imported skewpend, edits included
    python tests/golden/make_golden.py --only simulate  # recompute one section, keep the others

By default the values come from the commit ``HEAD`` (or ``--commit``) exported by ``git archive`` (so another engineer's
unfinished edits in the shared working tree do not enter them); the file records that commit.  Rewrite
the values only when a change of a result is intended and explained in the commit message.

Each ``section_*`` function returns ``{case: {quantity: array}}``; every input is fixed here and every
random number seeded.  The values are stored as JSON numbers (repr: the float64 round-trips), NaN as
null, complex arrays as ``[..., 2]`` real arrays (real, imaginary).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent.parent
VALUES = HERE / "values.json"

#: The start of every simulation (the reference state: both rods high, energetic, chaotic in the long run).
Y0 = (1.2, -0.8, 0.0, 0.0)
#: A short span: with the largest Lyapunov exponent about 1 1/s an error grows ~e^3 = 20x over it, so the
#: end state is still a function of the code, not of rounding.
T_END = 3.0
#: The adaptive methods' tolerance, and the tighter one make_golden measures their global error with.
RTOL = 1e-10
RTOL_TIGHT = 1e-13
#: The fixed-step methods' step.
DT = 1e-3
ADAPTIVE = ("dop853", "taylor")
FIXED = ("rk4", "gauss")
STATE_SEED = 20261127


def _say(text: str) -> None:
    print(f"make_golden: {text}", file=sys.stderr, flush=True)


# -- the models ------------------------------------------------------------------------------------------
def models() -> dict:
    """The four models: the reference; a strongly skewed rigid body (alpha 1.2, centres of mass off the
    rods' lines, full inertia tensors, a tilted first axis); viscous damping and constant torques; Coulomb
    friction and a geared rotor (gr = -6, the DFKI lab's motors)."""
    import skewpend

    ref = skewpend.reference_parameters()
    rigid = skewpend.Parameters(
        a=0.9, b=0.7, m1=1.1, m2=0.6, alpha=1.2, g=9.81,
        com1=(0.02, 0.42, -0.015), com2=(-0.01, 0.33, 0.03),
        inertia1=((0.080, 0.004, -0.002), (0.004, 0.006, 0.003), (-0.002, 0.003, 0.078)),
        inertia2=((0.030, -0.002, 0.001), (-0.002, 0.004, -0.0015), (0.001, -0.0015, 0.029)),
        axis1=(0.1, -0.05, 1.0))
    damped = ref.replace(c1=0.05, c2=0.03, tau1=0.2, tau2=-0.1)
    friction = ref.replace(cf1=0.01, cf2=0.006, Ir=2e-4, gr=-6.0)
    return {"reference": ref, "rigid": rigid, "damped": damped, "friction": friction}


def states(n: int = 4) -> np.ndarray:
    """Seeded states ``(phi, psi, dphi, dpsi)``: angles in (-pi, pi), speeds in (-3, 3) rad/s."""
    rng = np.random.default_rng(STATE_SEED)
    return np.column_stack([rng.uniform(-math.pi, math.pi, (n, 2)), rng.uniform(-3.0, 3.0, (n, 2))])


def _complex(z) -> np.ndarray:
    z = np.asarray(z, dtype=complex)
    return np.stack([z.real, z.imag], axis=-1)


# -- 1. simulate and the compiled kernel -----------------------------------------------------------------
def simulate_case(params, method: str, *, tight: bool = False, y0=Y0, t_end: float = T_END) -> dict:
    """End state, first energy, end work and energy drift of one run from ``y0`` (:data:`Y0`) over ``t_end``."""
    import skewpend

    if method in ADAPTIVE:
        tol = RTOL_TIGHT if tight else RTOL
        tr = skewpend.simulate(params, y0, t_end, method=method, rtol=tol, atol=tol, throw=True)
    else:
        tr = skewpend.simulate(params, y0, t_end, method=method, dt=DT, throw=True)
    return {"end_state": np.asarray(tr.y[-1], float), "energy0": np.asarray(tr.energy[0], float),
            "end_work": np.asarray(tr.work[-1], float), "end_energy": np.asarray(tr.energy[-1], float),
            "energy_drift": np.asarray(tr.energy_drift, float)}


def section_simulate(names=None) -> dict:
    out = {}
    for name, p in chosen(names):
        for method in ADAPTIVE + FIXED:
            out[f"{name}/{method}"] = simulate_case(p, method)
        # the global error of the adaptive runs at RTOL: against DOP853 at RTOL_TIGHT (recorded, not compared)
        tight = simulate_case(p, "dop853", tight=True)["end_state"]
        for method in ADAPTIVE:
            err = float(np.abs(out[f"{name}/{method}"]["end_state"] - tight).max())
            out[f"{name}/{method}"]["global_error"] = np.asarray(err)
    return out


def kernel_and_vector(params):
    """The model's compiled kernel and its parameter array (the one place the test reaches them)."""
    from skewpend.numeric.kernels import kernel_module, parameter_vector

    return kernel_module(params), parameter_vector(params)


def section_kernel(names=None) -> dict:
    ys = states()
    out = {}
    for name, p in chosen(names):
        k, pv = kernel_and_vector(p)
        out[name] = {"states": ys, "energy": np.asarray(k.energies(ys, pv), float),
                     "momenta": np.asarray(k.momenta_many(ys, pv), float),
                     "tips": np.asarray(k.tips_many(ys, pv), float)}
    return out


# -- 4. the derived equations evaluated ------------------------------------------------------------------
def section_derive(names=("reference", "rigid")) -> dict:
    """M(q), f(q, q'), T and Pi of ``skewpend.derive(params)`` evaluated (lambdify) at the seeded states."""
    import sympy as sp

    import skewpend

    s = skewpend.SYMBOLS
    args = [s["phi"], s["psi"], s["dphi"], s["dpsi"]]
    ys = states()
    out = {}
    for name, p in models().items():
        if name not in names:
            continue
        eom = skewpend.derive(p)
        fns = {k: sp.lambdify(args, expr, "numpy") for k, expr in
               (("mass_matrix", eom.mass_matrix), ("forcing", eom.forcing),
                ("kinetic_energy", eom.kinetic_energy), ("potential_energy", eom.potential_energy))}
        out[name] = {"states": ys, **{k: np.array([np.asarray(f(*y), float).reshape(-1) for y in ys])
                                      for k, f in fns.items()}}
    return out


# -- 2. the analyses ---------------------------------------------------------------------------------------
def chosen(names=None):
    """The models of :func:`models` named in ``names`` (all of them for None), in their order."""
    return [(name, p) for name, p in models().items() if names is None or name in names]


def _shapes(v) -> np.ndarray:
    """Mode shapes as columns, each with its largest-magnitude component positive (sign-consistent)."""
    v = np.array(v, dtype=float)
    for k in range(v.shape[1]):
        if v[np.argmax(np.abs(v[:, k])), k] < 0:
            v[:, k] = -v[:, k]
    return v


def section_modes(names=None) -> dict:
    import skewpend

    out = {}
    for name, p in chosen(names):
        m = skewpend.normal_modes(p, about="down-down")  # the hanging rest (not phi = psi = 0 for every model)
        out[name] = {"equilibrium": np.asarray(m.equilibrium, float), "frequencies": m.frequencies, "shapes": _shapes(m.shapes), "damping_ratios": m.damping_ratios,
                     "eigenvalues": _complex(m.eigenvalue_pairs.ravel())}
    return out


def section_equilibria(names=None) -> dict:
    import skewpend

    out = {}
    for name, p in chosen(names):
        eq = skewpend.equilibria(p)
        for e in eq:
            out[f"{name}/{e.label}"] = {"q": np.asarray(e.q, float), "potential": np.asarray(e.potential, float),
                                        "morse_index": np.asarray(e.morse_index, float),
                                        "eigenvalues": _complex(e.eigenvalues)}
        out[f"{name}/count"] = {"points": np.asarray(len(eq), float)}
    return out


def lqr_design():
    import skewpend

    return skewpend.lqr(models()["reference"], "up-up", "both")


def section_control(design=None) -> dict:
    """The LQR gain (identity weights, both joints) at the reference's upright, its estimate rho, and
    the region of attraction on a 6 x 6 slice (phi, psi) over 3 s."""
    import skewpend

    d = design or lqr_design()
    r = skewpend.region_of_attraction(models()["reference"], n=6, design=d, t_end=3.0, workers=1)
    return {"lqr": {"gain": d.gain, "P": d.P, "closed_loop": _complex(d.eigenvalues), "rho": np.asarray(d.rho)},
            "roa": {"capture_time": r.capture_time, "outcome": r.outcome.astype(float)}}


def section_dynamics() -> dict:
    """Lyapunov spectrum (finite time, 5 s), flip map (6 x 6, 3 s), Poincare crossings, a periodic
    orbit and a chaos-diagram point of the reference model."""
    import skewpend

    ref = models()["reference"]
    out = {}
    ly = skewpend.lyapunov(ref, Y0, t_end=5.0, n_exponents=4, windows=1)
    out["lyapunov"] = {"exponents": ly.exponents}
    f = skewpend.flip_map(ref, 6, t_end=3.0, workers=1)
    out["flip_map"] = {"flip_time": f.flip_time, "which": f.which.astype(float)}
    sec = skewpend.poincare(ref, 5.0, n_orbits=2, n_crossings=4)
    out["poincare"] = {"q": sec.q, "p": sec.p, "t": sec.t, "states": sec.states, "seeds": sec.seeds}
    m = skewpend.normal_modes(ref)
    guess = 0.3 * m.shapes[:, 0] / np.abs(m.shapes[:, 0]).max()
    po = skewpend.periodic_orbit(ref, (guess[0], guess[1], 0.0, 0.0), float(m.periods[0]), throw=True)
    out["periodic_orbit"] = {"state": po.state, "period": np.asarray(po.period), "energy": np.asarray(po.energy),
                             "multipliers_abs": np.sort(np.abs(po.multipliers))}
    cd = skewpend.chaos_diagram(ref, alpha=[0.6], energy=[5.0], samples=2, t_end=10.0, workers=1)
    out["chaos_diagram"] = {"exponent": cd.exponent, "threshold": np.asarray(cd.threshold)}
    return out


# -- 3. identification -------------------------------------------------------------------------------------
def kaheman_parameters():
    """The authors' model in skewpend's terms (as tests/test_identify.py)."""
    from scipy.io import loadmat

    import skewpend

    mat = skewpend.example_data("kaheman2023") / "EstimatedParameters_DoublePendulum.mat"
    m1, m2, a1, a2, L1, I1, I2, k1, k2, g = [float(x) for x in loadmat(str(mat))["EstimatedParameters"].ravel()]
    return skewpend.Parameters(a=L1, b=2 * a2, m1=m1, m2=m2, alpha=0, g=g, c1=k1, c2=k2, com1=(0, a1, 0),
                               com2=(0, a2, 0), inertia1=((I1, 0, 0), (0, 0, 0), (0, 0, I1)),
                               inertia2=((I2, 0, 0), (0, 0, 0), (0, 0, I2)))


def _fit_values(r) -> dict:
    iv = np.asarray(r.intervals, float)
    out = {"names": list(r.names), "values": np.asarray(r.values, float), "half_width": (iv[:, 1] - iv[:, 0]) / 2}
    if r.ratios:
        keys = sorted(r.ratios)
        out["ratio_names"] = keys
        out["ratios"] = np.array([r.ratios[k] for k in keys])
        out["ratio_half_width"] = np.array([(r.ratio_intervals[k][1] - r.ratio_intervals[k][0]) / 2 for k in keys])
    return out


#: The output-error protocol the identification values were pinned at (the default before issue 53 made it the
#: angles the data measured and, for pieces of at most 3 s, whole pieces as the shooting segments).
PINNED_PROTOCOL = {"angles": "relative", "segment": 0.5}


def fit_kaheman() -> dict:
    """The free swing (26 fitting pieces, 4 held out), the output-error fit of :data:`PINNED_PROTOCOL`."""
    import skewpend

    data = skewpend.example_data("kaheman2023")
    fit = skewpend.Measurements.from_kaheman(data, which="fit")
    val = skewpend.Measurements.from_kaheman(data, which="validation")
    return _fit_values(skewpend.identify(fit, kaheman_parameters(), validation=val, **PINNED_PROTOCOL))


def fit_dfki() -> dict:
    """The driven rig's protocol (docs/guide/identification.md): runs 00-05, the lab's model h1.0 as the
    start, its 9 base parameters free, segments of 0.25 s (no held-out pieces: they only report)."""
    import skewpend
    from skewpend.analysis.measurements import dfki_lab_parameters

    rig = skewpend.example_data("dfki-design-C.0")
    fit = skewpend.Measurements.from_dfki([rig / f"trajectory_{i:02d}.csv" for i in range(6)])
    lab = dfki_lab_parameters(rig / "model_h1.0_parameters.yml")
    free = ["J1zz_b", "h1y_b", "J2zz", "h2y", "c1", "c2", "cf1", "cf2", "Ir"]
    return _fit_values(skewpend.identify(fit, lab, segment=0.25, free=free))


#: The synthetic skewed rig: skewed 0.5 rad, damped, driven by constant torques per piece (so the scale
#: is determined), six starts of 2 s at 1 kHz, angle noise 2e-3 rad (seeded).
SYNTHETIC_STARTS = [(0.6, -0.4, 0.0, 0.0), (-0.9, 0.7, 1.0, 0.0), (1.4, 0.3, -0.5, 1.0),
                    (-0.3, -1.1, 0.0, -1.5), (0.2, 1.5, 2.0, 0.0), (-1.2, -0.2, -1.0, 1.0)]
SYNTHETIC_TORQUES = [(0.3, -0.1), (-0.2, 0.15), (0.0, 0.2), (0.25, 0.0), (-0.3, -0.1), (0.1, 0.1)]
SYNTHETIC_NOISE = 2e-3
SYNTHETIC_SEED = 37


def synthetic_truth():
    import skewpend

    return skewpend.reference_parameters().replace(alpha=0.5, c1=0.02, c2=0.01)


def fit_synthetic() -> dict:
    import skewpend

    truth = synthetic_truth()
    rng = np.random.default_rng(SYNTHETIC_SEED)
    pieces = []
    for i, (y0, u) in enumerate(zip(SYNTHETIC_STARTS, SYNTHETIC_TORQUES)):
        tr = skewpend.simulate(truth.replace(tau1=u[0], tau2=u[1]), y0, 2.0, dt_out=1e-3, method="dop853",
                               rtol=1e-12, atol=1e-12, throw=True)
        q = np.asarray(tr.y)[:, :2] + rng.normal(0.0, SYNTHETIC_NOISE, (len(tr.t), 2))
        pieces.append({"t": np.asarray(tr.t), "q": q, "u": np.tile(u, (len(tr.t), 1)), "name": f"s{i}"})
    data = skewpend.Measurements.from_arrays(pieces, skip=("mean",))
    return _fit_values(skewpend.identify(data, truth.replace(c1=0.05, c2=0.0), **PINNED_PROTOCOL))


def section_identify() -> dict:
    return {"kaheman": fit_kaheman(), "dfki": fit_dfki(), "synthetic": fit_synthetic()}


# -- 5. chains of links (issue 52: pinned before the chain and the double pendulum become one model) ------
#: Chain models: a skewed triple pendulum (tilted axes, unequal rods), the triple with every term (an offset
#: centre of mass, a full inertia tensor, an offset hinge, damping, Coulomb friction, a geared rotor, constant
#: torques), the golden ``rigid`` double pendulum as the chain of two, and a ten-link chain (the compact form).
CHAIN_Y0 = {3: (1.0, -0.7, 0.5, 0.0, 0.4, -0.3), 10: tuple([0.4, -0.3] * 5 + [0.0] * 10)}


def chain_models() -> dict:
    from skewpend.symbolic.chain import Chain

    triple = Chain.from_lists(3, axis=[(0, 0, 1), (0.35, 0.0, 1.0), (0.0, 0.3, 1.0)], mass=[1.0, 0.7, 0.5],
                              length=[0.8, 0.6, 0.5])
    lossy = triple.replace_link(1, damping=0.03, coulomb=0.01, torque=0.15, rotor=2e-4, gear=-6.0,
                                com=(0.02, 0.38, -0.01))
    lossy = lossy.replace_link(2, damping=0.02, coulomb=0.005, torque=-0.1, rotor=2e-4, gear=-6.0,
                               inertia=((0.022, 0.001, -0.002), (0.001, 0.006, 0.001), (-0.002, 0.001, 0.020)))
    lossy = lossy.replace_link(3, offset=(0.01, 0.58, 0.02), damping=0.01)
    pair = Chain.from_parameters(models()["rigid"])
    ten = Chain.from_lists(10, axis=[(0.1 * (i % 3), 0.05 * (i % 2), 1.0) for i in range(10)],
                           length=[0.3] * 10, mass=[0.2 + 0.02 * i for i in range(10)])
    return {"triple": triple, "lossy": lossy, "pair": pair, "ten": ten}


def chain_simulate(chain, method: str, *, tight: bool = False) -> dict:
    """:func:`simulate_case` of a chain from its start in :data:`CHAIN_Y0` (1 s for ten links, else 3 s)."""
    out = simulate_case(chain, method, tight=tight, y0=CHAIN_Y0.get(chain.n, Y0), t_end=1.0 if chain.n == 10 else T_END)
    return {k: out[k] for k in ("end_state", "energy0", "end_energy")}


def chain_states(n: int, count: int = 4) -> np.ndarray:
    rng = np.random.default_rng(STATE_SEED + n)
    return np.column_stack([rng.uniform(-math.pi, math.pi, (count, n)), rng.uniform(-3.0, 3.0, (count, n))])


def chain_kernel_values(chain) -> dict:
    from skewpend.numeric.kernels import model_kernel, model_vector

    k, pv = model_kernel(chain), model_vector(chain)
    ys = chain_states(chain.n)
    return {"states": ys, "energy": np.asarray(k.energies(ys, pv), float),
            "momenta": np.asarray(k.momenta_many(ys, pv), float), "tips": np.asarray(k.tips_many(ys, pv), float)}


def chain_modes(chain) -> dict:
    import skewpend

    m = skewpend.normal_modes(chain)
    return {"equilibrium": np.asarray(m.equilibrium, float), "frequencies": np.asarray(m.frequencies, float),
            "damping_ratios": np.asarray(m.damping_ratios, float), "shapes": _shapes(m.shapes)}


def chain_equilibria(chain) -> dict:
    import skewpend

    eq = skewpend.equilibria(chain)
    out = {"count": {"points": np.asarray(len(eq), float)}}
    for e in eq:
        out[e.label] = {"q": np.asarray(e.q, float), "potential": np.asarray(e.potential, float),
                        "morse_index": np.asarray(e.morse_index, float), "eigenvalues": _complex(e.eigenvalues)}
    return out


def chain_dynamics(chain) -> dict:
    """The LQR gain at the upright (identity weights, every joint driven), the finite-time Lyapunov spectrum
    (5 s) and a 4 x 4 flip map (3 s) of the triple pendulum."""
    import skewpend

    y0 = CHAIN_Y0[chain.n]
    d = skewpend.lqr(chain, "-".join(["up"] * chain.n), "all")
    ly = skewpend.lyapunov(chain, y0, t_end=5.0, n_exponents=2 * chain.n, windows=1)
    f = skewpend.flip_map(chain, 4, t_end=3.0, workers=1)
    return {"lqr": {"gain": d.gain, "P": d.P, "closed_loop": _complex(d.eigenvalues)},
            "lyapunov": {"exponents": ly.exponents},
            # the joint numbered 1 .. n (0 none), as pinned at f3bff08 (a flip map's which is the angle's index since issue 52)
            "flip_map": {"flip_time": np.asarray(f.flip_time, float), "which": np.where(f.which >= 0, f.which + 1.0, 0.0)}}


def fit_kaheman_triple() -> dict:
    """The authors' triple pendulum: their model as the start, the output-error fit of :data:`PINNED_PROTOCOL`, 4
    held out."""
    import skewpend
    from skewpend.analysis.measurements import kaheman_published_chain

    data = skewpend.example_data("kaheman2023-triple")
    fit = skewpend.Measurements.from_kaheman(data, which="fit")
    val = skewpend.Measurements.from_kaheman(data, which="validation")
    return _fit_values(skewpend.identify(fit, kaheman_published_chain(data), validation=val, **PINNED_PROTOCOL))


def section_chain() -> dict:
    out: dict = {}
    for name, chain in chain_models().items():
        for method in (("dop853", "rk4") if name != "ten" else ("dop853",)):
            out[f"{name}/{method}"] = chain_simulate(chain, method)
        # the global error at RTOL against DOP853 at RTOL_TIGHT (recorded: the test's tolerance scales with it)
        tight = chain_simulate(chain, "dop853", tight=True)["end_state"]
        out[f"{name}/dop853"]["global_error"] = np.asarray(float(np.abs(out[f"{name}/dop853"]["end_state"] - tight).max()))
        out[f"{name}/kernel"] = chain_kernel_values(chain)

    # a chain's modes are about q = 0: the triple, and the triple with damping and geared rotors
    triple = chain_models()["triple"]
    damped = triple
    for i, c in enumerate((0.03, 0.02, 0.01), start=1):
        damped = damped.replace_link(i, damping=c, rotor=2e-4, gear=-6.0)
    out["triple/modes"] = chain_modes(triple)
    out["damped/modes"] = chain_modes(damped)
    for label, v in chain_equilibria(triple).items():
        out[f"triple/equilibria/{label}"] = v
    for key, v in chain_dynamics(chain_models()["triple"]).items():
        out[f"triple/{key}"] = v
    out["kaheman_triple/identify"] = fit_kaheman_triple()
    return out


SECTIONS = {"simulate": section_simulate, "kernel": section_kernel, "derive": section_derive,
            "modes": section_modes, "equilibria": section_equilibria, "control": section_control,
            "dynamics": section_dynamics, "identify": section_identify, "chain": section_chain}


# -- JSON ----------------------------------------------------------------------------------------------------
def encode(x):
    if isinstance(x, dict):
        return {k: encode(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)) and all(isinstance(v, str) for v in x):
        return list(x)
    a = np.asarray(x, dtype=float)
    return np.where(np.isnan(a), None, a.astype(object)).tolist() if a.ndim else (None if np.isnan(a) else float(a))


def decode(x):
    """A stored value back as a float array (null -> NaN); lists of names stay lists."""
    if isinstance(x, list) and x and all(isinstance(v, str) for v in x):
        return x
    return np.array(x, dtype=float) if isinstance(x, list) else np.asarray(np.nan if x is None else x, dtype=float)


def load(path: Path = VALUES) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))


def _git(*args: str) -> str:
    return subprocess.run(["git", "-C", str(ROOT), *args], check=True, capture_output=True, text=True).stdout.strip()


def _reexec_at_commit(commit: str, argv) -> int:
    """Export the commit's ``src`` (and ``data``) with ``git archive`` and run this script on it."""
    sha = _git("rev-parse", "--verify", f"{commit}^{{commit}}")
    with tempfile.TemporaryDirectory(prefix="skewpend-golden-") as tmp:
        _say(f"exporting commit {sha[:12]} (git archive {sha[:12]} src data) to {tmp}")
        archive = subprocess.run(["git", "-C", str(ROOT), "archive", sha, "src", "data"], check=True,
                                 capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", tmp], input=archive, check=True)
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(Path(tmp) / "src"), os.environ.get("PYTHONPATH", "")]),
               "SKEWPEND_GOLDEN_COMMIT": sha}
        env.setdefault("SKEWPEND_CACHE_DIR", str(ROOT / ".skewpend-test-cache"))
        return subprocess.run([sys.executable, __file__, "--working-tree", *argv], env=env).returncode


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--commit", default="HEAD", help="the commit whose code computes the values (default HEAD)")
    ap.add_argument("--working-tree", action="store_true", help="compute with the imported skewpend (edits included)")
    ap.add_argument("--only", choices=sorted(SECTIONS), action="append", help="recompute these sections only")
    ap.add_argument("--out", type=Path, default=VALUES, help="the JSON file (default tests/golden/values.json)")
    args = ap.parse_args(argv)
    if not args.working_tree:
        rest = list(argv if argv is not None else sys.argv[1:])
        return _reexec_at_commit(args.commit, rest)
    import skewpend

    commit = os.environ.get("SKEWPEND_GOLDEN_COMMIT")
    source = "git archive of the commit"
    if commit is None:
        commit = _git("rev-parse", "HEAD")
        dirty = _git("status", "--porcelain", "--", "src")
        source = "working tree" + (" with uncommitted changes in src/" if dirty else " (src/ as committed)")
    _say(f"computing golden values with skewpend {skewpend.__version__} from {Path(skewpend.__file__).parent} "
         f"({source}, commit {commit[:12]})")
    doc = load(args.out) if (args.only and args.out.exists()) else {}
    sections = doc.get("sections", {})
    # the commit each section was computed at (sections recomputed alone keep the others' commits)
    made_at = doc.get("section_commits", {name: doc.get("commit", commit) for name in sections})
    for name in args.only or SECTIONS:
        start = time.perf_counter()
        _say(f"section {name} ...")
        sections[name] = encode(SECTIONS[name]())
        made_at[name] = commit
        _say(f"section {name}: {time.perf_counter() - start:.1f} s")
    if "simulate" in sections:
        for key, v in sections["simulate"].items():
            if "global_error" in v:
                _say(f"  {key}: global error of the end state at rtol {RTOL:g} (against dop853 at {RTOL_TIGHT:g}): "
                     f"{v['global_error']:.2g}")
    doc = {"about": "golden values of skewpend's N = 2 results (issue 37); made by tests/golden/make_golden.py, "
                    "compared by tests/test_golden.py within tolerances derived from each method",
           "commit": commit, "source": source, "skewpend_version": skewpend.__version__,
           "numpy": np.__version__, "python": sys.version.split()[0], "section_commits": made_at, "sections": sections}
    tmp = args.out.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    tmp.replace(args.out)
    _say(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
