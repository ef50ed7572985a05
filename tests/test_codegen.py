"""Generated code in every language agrees with the symbolic equations (backends agree)."""

from __future__ import annotations

import ctypes
import json
import shutil
import subprocess

import numpy as np
import pytest
from helpers import sympy_reference

from skewpend import Parameters
from skewpend.numeric.codegen import PARAMETER_ORDER, generate, parameter_vector
from skewpend.numeric.conventions import parameter_vector as kernel_vector  # the compiled kernels' p: scalars and bodies
from skewpend.numeric.kernels import LIB_SUFFIX, kernel_module

GENERAL = Parameters(
    a=1.1, b=0.7, m1=0.9, m2=0.6, g=9.81, c1=0.05, c2=0.02, tau1=0.1, tau2=-0.2,
    axis1=(0.1, 0.0, 1.0), axis2=(1.0, 0.3, 2.0), com2=(0.03, 0.35, -0.01),
    inertia2=((0.03, 0.002, 0.0), (0.002, 0.004, 0.001), (0.0, 0.001, 0.03)),
)


_reference = sympy_reference  # accelerations and energy straight from SymPy


def _states(n=10, seed=0):
    return np.random.default_rng(seed).uniform(-3, 3, (n, 4))


CASES = [
    Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81),
    Parameters(a=0.5, b=1.5, m1=2.0, m2=0.3, alpha=2.0, g=3.7, c1=0.1, c2=0.3, tau1=0.2, tau2=0.0),
    GENERAL,
]


@pytest.mark.parametrize("params", CASES, ids=["thin", "damped", "general"])
def test_python_source_matches_sympy(params):
    ns: dict = {}
    exec(generate(params, "python"), ns)
    acc, en = _reference(params)
    p = parameter_vector(params).tolist()
    for y in _states():
        np.testing.assert_allclose(ns["rhs"](0.0, y, p)[2:], acc(y), rtol=1e-11, atol=1e-11)
        assert ns["energy"](y, p) == pytest.approx(en(y), rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("params", CASES, ids=["thin", "damped", "general"])
def test_compiled_kernel_matches_sympy(params):
    k = kernel_module(params)
    acc, en = _reference(params)
    p = kernel_vector(params)
    out = np.empty(5)
    for y in _states(seed=1):
        k.rhs(np.append(y, 0.0), p, out)
        np.testing.assert_allclose(out[:2], y[2:], rtol=0, atol=0)
        np.testing.assert_allclose(out[2:4], acc(y), rtol=1e-11, atol=1e-11)
        # power of the non-potential forces
        Q = np.array([params.tau1 - params.c1 * y[2], params.tau2 - params.c2 * y[3]])
        assert out[4] == pytest.approx(Q @ y[2:], abs=1e-12)
        assert k.energy(y, p) == pytest.approx(en(y), rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("params", CASES, ids=["thin", "damped", "general"])
def test_jacobian_matches_finite_differences(params):
    k = kernel_module(params)
    p = kernel_vector(params)
    J = np.empty((5, 5))
    f0, f1 = np.empty(5), np.empty(5)
    for y in _states(4, seed=2):
        y5 = np.append(y, 0.0)
        k.jac(y5, p, J)
        num = np.empty((5, 5))
        for c in range(5):
            h = 1e-6 * max(1.0, abs(y5[c]))
            yp, ym = y5.copy(), y5.copy()
            yp[c] += h
            ym[c] -= h
            k.rhs(yp, p, f0)
            k.rhs(ym, p, f1)
            num[:, c] = (f0 - f1) / (2 * h)
        np.testing.assert_allclose(J, num, rtol=1e-6, atol=1e-6)


def test_hamiltonian_form_is_consistent():
    """p = M q', q' = M^-1 p, and dp/dt from ham_rhs equals d(M q')/dt along the motion."""
    params = CASES[1]
    k = kernel_module(params)
    p = kernel_vector(params)
    for y in _states(5, seed=3):
        y5 = np.append(y, 0.0)
        mom, vel = np.empty(2), np.empty(2)
        k.momenta(y5, p, mom)
        z = np.concatenate([y[:2], mom, [0.0]])
        k.velocities(z, p, vel)
        np.testing.assert_allclose(vel, y[2:], rtol=1e-12, atol=1e-12)
        dz = np.empty(5)
        k.ham_rhs(z, p, dz)
        # d/dt (M q') by finite differences along y' = rhs(y)
        dy = np.empty(5)
        k.rhs(y5, p, dy)
        h = 1e-6
        mp, mm = np.empty(2), np.empty(2)
        k.momenta(y5 + h * dy, p, mp)
        k.momenta(y5 - h * dy, p, mm)
        np.testing.assert_allclose(dz[2:4], (mp - mm) / (2 * h), rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(dz[:2], y[2:], rtol=1e-12, atol=1e-12)


@pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")
def test_c_source_compiles_and_matches(tmp_path):
    params = GENERAL
    src = tmp_path / "model.c"
    src.write_text(generate(params, "c"))
    lib = tmp_path / "libmodel.so"
    cc = shutil.which("cc") or shutil.which("gcc")
    subprocess.run([cc, "-O2", "-shared", "-fPIC", "-std=c99", "-Wall", "-Werror", "-o", str(lib), str(src), "-lm"], check=True)
    so = ctypes.CDLL(str(lib))
    dbl4, dbl10 = ctypes.c_double * 4, ctypes.c_double * len(PARAMETER_ORDER)
    so.skewpend_energy.restype = ctypes.c_double
    acc, en = _reference(params)
    p = dbl10(*parameter_vector(params))
    for y in _states(seed=4):
        out = dbl4()
        so.skewpend_rhs(dbl4(*y), p, out)
        np.testing.assert_allclose(list(out)[2:], acc(y), rtol=1e-11, atol=1e-11)
        assert so.skewpend_energy(dbl4(*y), p) == pytest.approx(en(y), rel=1e-12, abs=1e-12)


@pytest.mark.skipif(shutil.which("node") is None, reason="no Node.js")
def test_javascript_source_runs_and_matches(tmp_path):
    params = CASES[0]
    mod = tmp_path / "model.mjs"
    mod.write_text(generate(params, "javascript"))
    states = _states(seed=5)
    p = parameter_vector(params).tolist()
    script = tmp_path / "run.mjs"
    script.write_text(
        "import { rhs, energy } from './model.mjs';\n"
        f"const ys = {json.dumps(states.tolist())};\nconst p = {json.dumps(p)};\n"
        "console.log(JSON.stringify(ys.map(y => [rhs(y, p), energy(y, p)])));\n"
    )
    res = json.loads(subprocess.run(["node", str(script)], capture_output=True, text=True, check=True).stdout)
    acc, en = _reference(params)
    for y, (dy, e) in zip(states, res):
        np.testing.assert_allclose(dy[2:], acc(y), rtol=1e-11, atol=1e-11)
        assert e == pytest.approx(en(y), rel=1e-12, abs=1e-12)


def test_parameter_order_is_documented_in_generated_code():
    for lang in ("python", "c", "javascript"):
        assert ", ".join(PARAMETER_ORDER) in generate(Parameters(), lang)


def test_kernel_is_cached_on_disk(tmp_path, monkeypatch):
    import skewpend.numeric.kernels as cg

    monkeypatch.setenv("SKEWPEND_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(cg, "_LOADED", {})
    params = Parameters(a=1, b=1, m1=1, m2=1, alpha=0.1, g=9.81, com2=(0.0, 0.45, 0.0))
    first = kernel_module(params)
    libs = list((tmp_path / "kernels").glob(f"skewpend_*{LIB_SUFFIX}"))
    sources = list((tmp_path / "kernels").glob("skewpend_*.c"))
    assert len(libs) == 1 and len(sources) == 1 and sources[0].read_text().startswith("/* Generated by skewpend")
    assert first.origin == "compiled" and first.path == libs[0]
    # a different numeric value of a scalar parameter reuses the same kernel
    assert kernel_module(params.replace(a=2.0)) is first
    assert list((tmp_path / "kernels").glob("*.tmp")) == []


def test_numeric_values_become_the_default_parameter_vector():
    """Every language spells the values exactly (shortest round-trip decimals) in PARAMETER_ORDER."""
    params = CASES[1]
    literal = ", ".join(repr(x) for x in parameter_vector(params).tolist())
    py, c, js = (generate(params, lang) for lang in ("python", "c", "javascript"))
    assert f"P = ({literal})" in py and "def rhs(t, y, p=P):" in py and "def energy(y, p=P):" in py
    assert f"static const double SKEWPEND_P[{len(PARAMETER_ORDER)}] = {{{literal}}};" in c
    assert f"export const P = [{literal}];" in js and "export function rhs(y, p = P) {" in js
    for src in (py, c, js):
        assert "Values (the default parameter vector P): a = 0.5, b = 1.5," in src


def test_symbolic_parameters_give_no_default_vector():
    for lang in ("python", "c", "javascript"):
        src = generate(Parameters(), lang)
        assert "SKEWPEND_P" not in src and "P =" not in src and "Values" not in src


# -- the return codes: one list (skewpend.status), the C #defines generated from it -----------------
def test_generated_return_codes_equal_the_status_enums():
    import re

    from skewpend.numeric.kernel_source import status_defines
    from skewpend.status import CallCode, Status

    defined = {}
    for line in status_defines():
        m = re.match(r"#define (SP_\w+) \(?(-?\d+)\)?\s", line)
        if m:
            defined[m.group(1)] = int(m.group(2))
    expected = {f"SP_STATUS_{s.name}": int(s) for s in Status}
    expected.update({f"SP_CALL_{c.name}": int(c) for c in CallCode})
    assert defined == expected


def test_templates_return_only_named_codes():
    """integrators.c and chaos.c return the generated SP_STATUS_/SP_CALL_ names, never a bare
    integer code (the helpers returning a 0/1 truth value are the exceptions listed here)."""
    import re
    from pathlib import Path

    import skewpend

    numeric = Path(skewpend.__file__).parent / "numeric"
    boolean = {"all_finite", "lyap_qr", "var_start", "henon_locate", "dense_locate", "dop_dense_eval", "sp_flipped"}
    for name in ("integrators.c", "chaos.c", "dop853_core.h"):
        fn = None
        for line in (numeric / name).read_text().splitlines():
            m = re.match(r"^(?:static |SP_MULTIVERSION )?(?:inline )?\w+ (?:\w+ )*\**(?:DOP_NAME\()?(\w+)\)?\(", line)
            if m:
                fn = m.group(1)
            if re.search(r"\breturn -?\d+;", line):
                assert fn in boolean, f"{name}: {fn} returns a bare code: {line.strip()}"


def test_dop853_core_is_written_once():
    """One DOP853 core, included by the plain and the variational integrators; no copy by text."""
    from pathlib import Path

    import skewpend

    numeric = Path(skewpend.__file__).parent / "numeric"
    assert '#include "dop853_core.h"' in (numeric / "integrators.c").read_text()
    assert '#include "dop853_core.h"' in (numeric / "chaos.c").read_text()
    assert "static int DOP_NAME(dop_advance)(" in (numeric / "dop853_core.h").read_text()
    for name in ("integrators.c", "chaos.c"):
        assert "static int dop_advance(" not in (numeric / name).read_text()
