"""The one linear solve (issue 37, goal 4): LDL^T of a symmetric positive-definite matrix, printed by
``codegen.ldlt_factor_steps`` / ``ldlt_solve_steps`` / ``ldlt_inverse_steps`` / ``spd_mul_steps`` into
every generated function (the compiled kernels and their SIMD lanes, the Taylor series, the standalone
Python, C and JavaScript, the explorer).

* the printed steps compiled as C (as the kernels are: without floating-point contraction) against
  NumPy's LU solve on seeded random SPD matrices n = 1 .. 8, within the forward-error bound of a
  backward-stable solve, ``|x - x_ref| <= c n eps cond(M) |x|`` (c = 10); fused (``fma``, as the
  Taylor kernels print them) within the same bound;
* the same steps run as Python give the C bits (same operations, same order, both IEEE double): the
  exports give the kernels' numbers;
* the inverse from the factors times M is the identity within the same bound; the symmetric product
  agrees with NumPy's;
* the generated kernels, the Taylor series and the exports print no Cramer solve; every kernel
  function that solves prints the LDL^T.
"""

from __future__ import annotations

import ctypes
import subprocess

import numpy as np
import pytest

import skewpend
from skewpend.numeric import codegen, explorer_source
from skewpend.numeric.kernels import CFLAGS, LIB_SUFFIX, find_compiler

EPS = np.finfo(float).eps
NMAX = 8


def _names(n):
    return [f"m{i}{j}" for i in range(n) for j in range(i + 1)], [f"b{i}" for i in range(n)], [f"x{i}" for i in range(n)]


def _c_function(name, n, steps, inputs, outputs):
    lines = [f"void {name}(const double *in, double *out) {{"]
    lines += [f"    const double {v} = in[{k}];" for k, v in enumerate(inputs)]
    lines += [f"    const double {t} = {e};" for t, e in steps]
    lines += [f"    out[{k}] = {v};" for k, v in enumerate(outputs)] + ["}"]
    return "\n".join(lines)


def _sources():
    out = ["#include <math.h>", "#define SP_FMA(a, b, c) fma(a, b, c)"]
    for n in range(1, NMAX + 1):
        M, b, x = _names(n)
        inv = [f"s{i}{j}" for i in range(n) for j in range(i + 1)]
        for fused in (False, True):
            tag = "f" if fused else "p"
            out.append(_c_function(f"solve{tag}{n}", n, codegen.ldlt_steps(M, b, x, fused=fused), M + b, x))
            out.append(_c_function(f"inverse{tag}{n}", n, codegen.ldlt_factor_steps(M, fused=fused)
                                   + codegen.ldlt_inverse_steps(n, inv, fused=fused), M, inv))
            out.append(_c_function(f"mul{tag}{n}", n, codegen.spd_mul_steps(M, b, x, fused=fused), M + b, x))
    return "\n".join(out)


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    d = tmp_path_factory.mktemp("spd")
    src, so = d / "t.c", d / f"t{LIB_SUFFIX}"
    src.write_text(_sources())
    cmd = [*find_compiler(), *CFLAGS, "-o", str(so), str(src), "-lm"]
    subprocess.run(cmd, check=True, capture_output=True)
    return ctypes.CDLL(str(so))


def _call(lib, name, inputs, n_out):
    a, out = np.ascontiguousarray(inputs, dtype=float), np.zeros(n_out)
    P = ctypes.POINTER(ctypes.c_double)
    getattr(lib, name)(a.ctypes.data_as(P), out.ctypes.data_as(P))
    return out


def _packed(M):
    n = M.shape[0]
    return np.array([M[i, j] for i in range(n) for j in range(i + 1)], dtype=float)


def _unpack(v, n):
    S = np.zeros((n, n))
    S[np.tril_indices(n)] = v
    return S + np.tril(S, -1).T


def _spd(rng, n):
    """A random SPD matrix with a spread of eigenvalues (condition up to ~1e4)."""
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    w = 10.0 ** rng.uniform(-2, 2, n)
    M = (Q * w) @ Q.T
    return (M + M.T) / 2


def _py_solve(M, b):
    """The printed steps run as Python (what the standalone Python export and the JavaScript do)."""
    n = len(b)
    names, bs, xs = _names(n)
    env = dict(zip(names, _packed(M)))
    env.update(zip(bs, (float(v) for v in b)))
    for target, expr in codegen.ldlt_steps(names, bs, xs):
        env[target] = eval(expr, {}, env)
    return np.array([env[x] for x in xs])


@pytest.mark.parametrize("n", range(1, NMAX + 1))
def test_solve_against_numpy(lib, n):
    rng = np.random.default_rng(37 + n)
    for _ in range(20):
        M, b = _spd(rng, n), rng.standard_normal(n)
        ref = np.linalg.solve(M, b)
        bound = 10 * n * EPS * np.linalg.cond(M) * np.max(np.abs(ref))
        for tag in ("p", "f"):
            assert np.max(np.abs(_call(lib, f"solve{tag}{n}", np.concatenate([_packed(M), b]), n) - ref)) <= bound


@pytest.mark.parametrize("n", range(1, 6))
def test_printed_steps_give_the_same_bits_in_python_and_c(lib, n):
    rng = np.random.default_rng(370 + n)
    for _ in range(50):
        M, b = _spd(rng, n), rng.standard_normal(n)
        assert np.array_equal(_py_solve(M, b), _call(lib, f"solvep{n}", np.concatenate([_packed(M), b]), n))


@pytest.mark.parametrize("n", range(1, 7))
def test_inverse_and_product(lib, n):
    rng = np.random.default_rng(3700 + n)
    M = _spd(rng, n)
    for tag in ("p", "f"):
        S = _unpack(_call(lib, f"inverse{tag}{n}", _packed(M), n * (n + 1) // 2), n)
        assert np.max(np.abs(S @ M - np.eye(n))) <= 10 * n * EPS * np.linalg.cond(M)
        b = rng.standard_normal(n)
        x = _call(lib, f"mul{tag}{n}", np.concatenate([_packed(S), b]), n)
        assert np.max(np.abs(x - S @ b)) <= 4 * n * EPS * np.max(np.abs(S)) * np.max(np.abs(b))


def test_n2_steps_are_the_documented_ones():
    steps = codegen.ldlt_steps(["M11", "M12", "M22"], ["f1", "f2"], ["ddphi", "ddpsi"])
    # one reciprocal a pivot, then the substitutions
    assert steps == [("iD1", "1.0 / M11"), ("L21", "M12 * iD1"), ("iD2", "1.0 / (M22 - M12 * L21)"),
                     ("z2", "f2 - L21 * f1"), ("ddpsi", "z2 * iD2"), ("ddphi", "f1 * iD1 - L21 * ddpsi")]
    # fused, as the Taylor series prints it: the same operations, each product fused with its sum
    fused = codegen.ldlt_steps(["M11", "M12", "M22"], ["f1", "f2"], ["x1", "x2"], fused=True)
    assert fused[2] == ("iD2", "1.0 / (SP_FMA(-M12, L21, M22))") and fused[-1] == ("x1", "SP_FMA(-L21, x2, f1 * iD1)")
    assert codegen.spd_mul_steps(["S11", "S21", "S22"], ["r1", "r2"], ["a1", "a2"]) == [
        ("a1", "S21 * r2 + S11 * r1"), ("a2", "S22 * r2 + S21 * r1")]
    with pytest.raises(ValueError, match="packed triangle"):
        codegen.ldlt_steps(["M11", "M12"], ["f1", "f2"], ["x1", "x2"])


def test_the_solve_keeps_its_range():
    """Masses and lengths far from 1: the pivots' own reciprocals stay finite where a shared one
    (1/(M11 det M), ~1e600 here) would overflow to zero accelerations."""
    M = np.array([[3e200, 1e100], [1e100, 0.5]])
    b = np.array([2e200, 1.0])
    names, bs, xs = _names(2)
    env = dict(zip(names, _packed(M)))
    env.update(zip(bs, b))
    for target, expr in codegen.ldlt_steps(names, bs, xs):
        env[target] = eval(expr, {}, env)
    x = np.array([env[v] for v in xs])
    ref = np.linalg.solve(M, b)
    assert np.all(np.isfinite(x)) and np.allclose(x, ref, rtol=1e-12, atol=0)


def test_no_cramer_solve_is_printed():
    """Every generated solve goes through the one LDL^T (no determinant formula left)."""
    from skewpend.numeric.conventions import structure_of
    from skewpend.numeric.kernel_source import kernel_c_source
    from skewpend.numeric.taylor_source import exact_system, taylor_c_source

    P = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
    src = kernel_c_source(structure_of(P), flip=True)
    assert "det" not in src.replace("determin", "")
    # one factorisation each: rhs, rhs_jac, velocities, ham_rhs, the flip and the capture lanes
    assert src.count("const double sp_m_iD2 = ") == 6
    series = taylor_c_source(exact_system(structure_of(P)), 12)
    assert "rdet" not in series and series.count("const double sp_fiD2 = ") == 1  # M[0], once a step
    for language in ("python", "c", "javascript"):
        code = codegen.generate(P, language)
        assert "det" not in code and "iD2" in code
    assert "det" not in explorer_source.explorer_js(P).replace("determin", "")
    assert "iD2" in explorer_source.explorer_js(P)
