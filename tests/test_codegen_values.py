"""Generated code carries numeric parameter values as its default parameter vector P.

`skewpend derive --format python|c|javascript` with numeric `--a --b --m1 --m2 --alpha --g`
prints them, exactly, as `P` / `SKEWPEND_P`, the default `p` of `rhs` and `energy`; a partial
set is refused with one line; no values leaves the output as before.
"""

from __future__ import annotations

import ctypes
import json
import math
import shutil
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp

from skewpend import Parameters, derive
from skewpend.cli import build_parameters
from skewpend.numeric.codegen import PARAMETER_ORDER, generate, parameter_vector
from skewpend.symbolic.derivation import SYMBOLS
from skewpend.parsing import UsageError

N = len(PARAMETER_ORDER)

CASES = {
    "thin": Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81),
    "damped": Parameters(a=0.5, b=1.5, m1=2.0, m2=0.3, alpha=math.radians(30), g=3.7, c1=0.1, c2=0.3, tau1=0.2, tau2=-0.05),
    "general": Parameters(  # axis2 given: alpha is not used and not needed
        a=1.1, b=0.7, m1=0.9, m2=0.6, g=9.81, c1=0.05, c2=0.02, tau1=0.1, tau2=-0.2,
        axis1=(0.1, 0.0, 1.0), axis2=(1.0, 0.3, 2.0), com2=(0.03, 0.35, -0.01),
        inertia2=((0.03, 0.002, 0.0), (0.002, 0.004, 0.001), (0.0, 0.001, 0.03)),
    ),
}
#: Tolerance of generated code vs the numeric derivation (relative to the size of the values).
TOL = 1e-12


def _numeric_accelerations(params: Parameters):
    """q'' from ``skewpend.derive(params)``: M(q) and f(q, q') evaluated, then numpy's solve."""
    eom = derive(params)
    s = SYMBOLS
    args = [s["phi"], s["psi"], s["dphi"], s["dpsi"]]
    M = sp.lambdify(args, eom.mass_matrix, "numpy")
    f = sp.lambdify(args, eom.forcing, "numpy")
    return lambda y: np.linalg.solve(np.array(M(*y), float), np.array(f(*y), float).ravel())


def _states(seed: int, n: int = 6):
    return np.random.default_rng(seed).uniform(-3, 3, (n, 4))


def _assert_close(got, want):
    got, want = np.asarray(got, float), np.asarray(want, float)
    np.testing.assert_allclose(got, want, rtol=TOL, atol=TOL * max(1.0, float(np.abs(want).max())))


def _run(*args):
    from helpers import without_stages

    proc = subprocess.run(
        [sys.executable, "-m", "skewpend.cli", *args], capture_output=True, text=True, timeout=120
    )
    proc.stderr = without_stages(proc.stderr)[0]  # the stage lines (issue 36) apart from the message
    return proc


@pytest.mark.parametrize("name", list(CASES))
def test_python_default_vector_equals_explicit_and_matches_derivation(name):
    params = CASES[name]
    ns: dict = {}
    exec(generate(params, "python"), ns)
    p = parameter_vector(params).tolist()
    assert ns["P"] == tuple(p)  # bit-exact round trip of every value
    acc = _numeric_accelerations(params)
    for y in _states(seed=10):
        y = y.tolist()
        default = ns["rhs"](0.0, y)
        assert default == ns["rhs"](0.0, y, p)  # same code, same numbers: identical
        assert ns["energy"](y) == ns["energy"](y, p)
        assert default[:2] == y[2:]
        _assert_close(default[2:], acc(y))


def test_cli_values_reach_the_python_code():
    """The user report: the options now take effect (bit-exact values, right dynamics)."""
    opts = {"a": "2", "b": "0.8", "m1": "1", "m2": "0.7", "alpha": "30deg", "g": "9.81", "c1": "0.05", "tau2": "-0.1"}
    proc = _run("derive", "--format", "python", *[x for k, v in opts.items() for x in (f"--{k}", v)])
    assert proc.returncode == 0, proc.stderr
    params = build_parameters(**{k: opts.get(k, "0" if k in ("c1", "c2", "tau1", "tau2") else None)
                                 for k in PARAMETER_ORDER},
                              com1=None, com2=None, inertia1=None, inertia2=None, axis1=None, axis2=None)
    ns: dict = {}
    exec(proc.stdout, ns)
    assert ns["P"] == tuple(parameter_vector(params).tolist())
    assert ns["P"][0] == 2.0 and ns["P"][4] == 30 * math.pi / 180 and ns["P"][9] == -0.1
    acc = _numeric_accelerations(params)
    for y in _states(seed=11):
        _assert_close(ns["rhs"](0.0, y)[2:], acc(y))
    assert "a = 2.0" in proc.stdout.split('"""')[1]  # the header names the values


def test_a_changes_the_output():
    base = ["derive", "--format", "python", "--b", "0.8", "--m1", "1", "--m2", "0.7", "--alpha", "0.6", "--g", "9.81"]
    one, two = _run(*base, "--a", "1"), _run(*base, "--a", "2")
    assert one.returncode == two.returncode == 0
    assert one.stdout != two.stdout
    assert "P = (1.0, 0.8," in one.stdout and "P = (2.0, 0.8," in two.stdout
    plain = _run("derive", "--format", "python").stdout
    assert "P =" not in plain and "def rhs(t, y, p):" in plain  # no values: as before


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc)")
@pytest.mark.parametrize("name", ["damped", "general"])
def test_c_default_vector_compiles_and_matches(tmp_path, name):
    params = CASES[name]
    (tmp_path / "model.c").write_text(generate(params, "c"))
    (tmp_path / "use.c").write_text(
        '#include "model.c"\n'
        f"void get_p(double out[{N}]) {{ for (int i = 0; i < {N}; ++i) out[i] = SKEWPEND_P[i]; }}\n"
        "void rhs_default(const double y[4], double dydt[4]) { skewpend_rhs(y, SKEWPEND_P, dydt); }\n"
        "double energy_default(const double y[4]) { return skewpend_energy(y, SKEWPEND_P); }\n"
    )
    flags = ["-O2", "-shared", "-fPIC", "-std=c99", "-Wall", "-Wextra", "-Werror"]
    # alone (SKEWPEND_P unused there must not warn) and included by a user's file
    subprocess.run(["cc", *flags, "-o", str(tmp_path / "alone.so"), str(tmp_path / "model.c"), "-lm"], check=True)
    subprocess.run(["cc", *flags, "-o", str(tmp_path / "use.so"), str(tmp_path / "use.c"), "-lm"], check=True)
    so = ctypes.CDLL(str(tmp_path / "use.so"))
    dbl4, dbl10 = ctypes.c_double * 4, ctypes.c_double * N
    so.energy_default.restype = so.skewpend_energy.restype = ctypes.c_double
    got = dbl10()
    so.get_p(got)
    p = parameter_vector(params).tolist()
    assert list(got) == p  # bit-exact
    acc = _numeric_accelerations(params)
    ns: dict = {}
    exec(generate(params, "python"), ns)
    for y in _states(seed=12):
        out, out_p = dbl4(), dbl4()
        so.rhs_default(dbl4(*y), out)
        so.skewpend_rhs(dbl4(*y), dbl10(*p), out_p)
        assert list(out) == list(out_p)
        _assert_close(list(out)[2:], acc(y))
        assert so.energy_default(dbl4(*y)) == pytest.approx(ns["energy"](y.tolist()), rel=TOL, abs=TOL)


@pytest.mark.skipif(shutil.which("node") is None, reason="no Node.js")
@pytest.mark.parametrize("name", ["damped", "general"])
def test_javascript_default_vector_runs_and_matches(tmp_path, name):
    params = CASES[name]
    (tmp_path / "model.mjs").write_text(generate(params, "javascript"))
    states = _states(seed=13)
    p = parameter_vector(params).tolist()
    (tmp_path / "run.mjs").write_text(
        "import { rhs, energy, P } from './model.mjs';\n"
        f"const ys = {json.dumps(states.tolist())};\nconst p = {json.dumps(p)};\n"
        "console.log(JSON.stringify({P, rows: ys.map(y => [rhs(y), rhs(y, p), energy(y), energy(y, p)])}));\n"
    )
    res = json.loads(subprocess.run(["node", str(tmp_path / "run.mjs")], capture_output=True, text=True, check=True).stdout)
    assert res["P"] == p  # bit-exact through JavaScript's parser and printer
    acc = _numeric_accelerations(params)
    for y, (dy, dy_p, e, e_p) in zip(states, res["rows"]):
        assert dy == dy_p and e == e_p
        _assert_close(dy[2:], acc(y))


@pytest.mark.parametrize(
    "args, message",
    [
        (["--a", "2", "--alpha", "30deg"], "numeric a, alpha but not b, m1, m2, g; give all of a, b, m1, m2, alpha, g as numbers"),
        (["--a", "1", "--b", "1", "--m1", "1", "--m2", "1", "--axis2", "1,0,1"], "but not g; give all of a, b, m1, m2, g as"),
        (["--g", "9.81", "-f", "c"], "but not a, b, m1, m2, alpha;"),
        (["--c1", "0"], "--c1 with --format python needs --a --b --m1 --m2 --alpha --g as numbers too"),
        (["--tau2", "0.5", "-f", "javascript"], "--tau2 with --format javascript needs"),
        (["--a", "1", "--b", "1", "--m1", "1", "--m2", "1", "--alpha", "0", "--g", "1", "--c2", "sym"], "needs numbers for c2"),
        (["--com2", "0,d,0"], "symbolic: d"),
    ],
)
def test_partial_values_are_refused_with_one_line(args, message):
    proc = _run("derive", "--format", "python", *args) if "-f" not in args else _run("derive", *args)
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("skewpend: error:"), proc.stderr
    assert message in lines[0]
    if "give all of" in message:
        assert "or none of them" in lines[0]


def test_library_generate_refuses_partial_values():
    with pytest.raises(UsageError, match="but not b, m1, m2, alpha, g"):
        generate(Parameters(a=1.0), "python")
    with pytest.raises(UsageError, match="c1 = 0.05 would be ignored"):
        generate(Parameters(c1=0.05), "c")
    assert "SKEWPEND_P" not in generate(Parameters(), "c")  # all symbolic: p at run time only
