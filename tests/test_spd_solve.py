"""The one linear solve (issue 37, goal 4): ``spd_solve.h`` (LDL^T of a symmetric positive-definite
matrix; every compiled kernel and the Taylor series use it) and ``codegen.ldlt_steps`` (the same steps
printed for the standalone Python, C and JavaScript).

* against NumPy's LU solve on seeded random SPD matrices n = 1 .. 8, within the forward-error bound of
  a backward-stable solve, ``|x - x_ref| <= c n eps cond(M) |x|`` (c = 10);
* ``ldlt_steps`` run as Python gives the header's bits (same operations, same order, both IEEE double,
  the header compiled without contraction, as the kernels are);
* the inverse from the factors times M is the identity within the same bound; the symmetric product
  agrees with NumPy's;
* the generated kernels and exports print no Cramer solve any more.
"""

from __future__ import annotations

import ctypes
import subprocess
from pathlib import Path

import numpy as np
import pytest

import skewpend
from skewpend.numeric import codegen
from skewpend.numeric.kernels import CFLAGS, LIB_SUFFIX, find_compiler

HEADER_DIR = Path(skewpend.__file__).resolve().parent / "numeric"
EPS = np.finfo(float).eps

_C = r"""
#include "spd_solve.h"
/* runtime n (the loops), and n = 2 as the kernels call it (constant: unrolled) */
void t_solve(int n, double *a, double *b) { sp_spd_solve(n, a, b); }
void t_solve2(double *a, double *b) { sp_spd_solve(2, a, b); }
void t_inverse(int n, double *a, double *inv) { sp_ldlt_factor(n, a); sp_ldlt_inverse(n, a, inv); }
void t_mul(int n, const double *s, const double *b, double *x) { sp_spd_mul(n, s, b, x); }
"""


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    d = tmp_path_factory.mktemp("spd")
    src, so = d / "t.c", d / f"t{LIB_SUFFIX}"
    src.write_text(_C)
    cmd = [*find_compiler(), *CFLAGS, "-I", str(HEADER_DIR), "-o", str(so), str(src), "-lm"]
    subprocess.run(cmd, check=True, capture_output=True)
    out = ctypes.CDLL(str(so))
    P = ctypes.POINTER(ctypes.c_double)
    out.t_solve.argtypes = [ctypes.c_int, P, P]
    out.t_solve2.argtypes = [P, P]
    out.t_inverse.argtypes = [ctypes.c_int, P, P]
    out.t_mul.argtypes = [ctypes.c_int, P, P, P]
    return out


def _ptr(a):
    return a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))


def _packed(M):
    n = M.shape[0]
    return np.array([M[i, j] for i in range(n) for j in range(i + 1)], dtype=float)


def _spd(rng, n):
    """A random SPD matrix with a spread of eigenvalues (condition up to ~1e4)."""
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    w = 10.0 ** rng.uniform(-2, 2, n)
    M = (Q * w) @ Q.T
    return (M + M.T) / 2


def _c_solve(lib, M, b, two=False):
    a, x = _packed(M), np.array(b, dtype=float)
    (lib.t_solve2(_ptr(a), _ptr(x)) if two else lib.t_solve(len(b), _ptr(a), _ptr(x)))
    return x


def _py_solve(M, b):
    n = len(b)
    names = [f"m{i}{j}" for i in range(n) for j in range(i + 1)]
    env = dict(zip(names, _packed(M)))
    env.update({f"b{i}": float(v) for i, v in enumerate(b)})
    xs = [f"x{i}" for i in range(n)]
    for target, expr in codegen.ldlt_steps(names, [f"b{i}" for i in range(n)], xs):
        env[target] = eval(expr, {}, env)  # the printed arithmetic, run as Python
    return np.array([env[x] for x in xs])


@pytest.mark.parametrize("n", range(1, 9))
def test_solve_against_numpy(lib, n):
    rng = np.random.default_rng(37 + n)
    for _ in range(20):
        M, b = _spd(rng, n), rng.standard_normal(n)
        ref = np.linalg.solve(M, b)
        bound = 10 * n * EPS * np.linalg.cond(M) * np.max(np.abs(ref))
        assert np.max(np.abs(_c_solve(lib, M, b) - ref)) <= bound
        if n == 2:
            assert np.max(np.abs(_c_solve(lib, M, b, two=True) - ref)) <= bound


@pytest.mark.parametrize("n", range(1, 6))
def test_printed_steps_give_the_header_bits(lib, n):
    rng = np.random.default_rng(370 + n)
    for _ in range(50):
        M, b = _spd(rng, n), rng.standard_normal(n)
        c = _c_solve(lib, M, b)
        assert np.array_equal(_py_solve(M, b), c)
        if n == 2:
            assert np.array_equal(_c_solve(lib, M, b, two=True), c)


@pytest.mark.parametrize("n", range(1, 7))
def test_inverse_and_product(lib, n):
    rng = np.random.default_rng(3700 + n)
    M = _spd(rng, n)
    a, inv = _packed(M), np.zeros(n * (n + 1) // 2)
    lib.t_inverse(n, _ptr(a), _ptr(inv))
    S = np.zeros((n, n))
    S[np.tril_indices(n)] = inv
    S = S + np.tril(S, -1).T
    assert np.max(np.abs(S @ M - np.eye(n))) <= 10 * n * EPS * np.linalg.cond(M)
    b, x = rng.standard_normal(n), np.zeros(n)
    lib.t_mul(n, _ptr(inv), _ptr(b), _ptr(x))
    assert np.max(np.abs(x - S @ b)) <= 4 * n * EPS * np.max(np.abs(S)) * np.max(np.abs(b))


def test_n2_steps_are_the_documented_ones():
    steps = codegen.ldlt_steps(["M11", "M12", "M22"], ["f1", "f2"], ["ddphi", "ddpsi"])
    # one reciprocal for both pivots (D1 D2 = det M), then the substitutions
    assert steps == [("dD", "M11 * M22 - M12 * M12"), ("w", "1.0 / (M11 * dD)"), ("iD1", "dD * w"),
                     ("L21", "M12 * iD1"), ("iD2", "M11 * M11 * w"),
                     ("z2", "f2 - L21 * f1"), ("ddpsi", "z2 * iD2"), ("ddphi", "f1 * iD1 - L21 * ddpsi")]
    with pytest.raises(ValueError, match="packed triangle"):
        codegen.ldlt_steps(["M11", "M12"], ["f1", "f2"], ["x1", "x2"])


def test_no_cramer_solve_is_printed():
    """Every generated solve goes through the one LDL^T (no determinant formula left)."""
    from skewpend.numeric.conventions import geometry_of
    from skewpend.numeric.kernel_source import kernel_c_source

    P = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
    src = kernel_c_source(geometry_of(P), flip=True)
    assert '#include "spd_solve.h"' in src
    assert "det" not in src.replace("determin", "")
    assert src.count("sp_ldlt_factor(2,") == 6  # rhs, rhs_jac, velocities, ham_rhs, flip and capture lanes
    for language in ("python", "c", "javascript"):
        code = codegen.generate(P, language)
        assert "det" not in code and "iD2" in code
    assert "det" not in codegen.explorer_js(P).replace("determin", "")
