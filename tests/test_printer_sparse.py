"""The printer of CasADi functions (``numeric.recursive.function_lines``) writes every entry of every output in each
of its languages, also where CasADi keeps no entry (a structural zero: an expression that cannot depend on
anything, as the Hessian's row of an angle that moves no weight -- the rotary pendulum's arm, issue 54): 0.0
there, each nonzero in its own dense place (column-major), never an unset name (Python's NameError,
JavaScript's ``undefined``, C's garbage) nor a nonzero shifted into a zero's place."""

from __future__ import annotations

import ctypes
import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from skewpend.numeric.recursive import function_lines

ROOT = Path(__file__).resolve().parent.parent
#: Inputs at which the printed code is compared with CasADi's own evaluation (seeded, away from zero so that
#: no nonzero entry happens to vanish).
X = np.random.default_rng(54).uniform(0.3, 1.3, size=(5, 3))


@pytest.fixture(scope="module")
def sparse_function():
    """``f(x, p)``: a column with structural zeros in its middle and at its end, a 3 x 2 Jacobian with
    structural zeros (column-major), a 2 x 1 of structural zeros only, and the input ``p`` unread."""
    ca = pytest.importorskip("casadi")
    x, p = ca.SX.sym("x", 3), ca.SX.sym("p", 2)
    column = ca.vertcat(x[0] * x[1], ca.SX(1, 1), ca.sin(x[2]), ca.SX(1, 1))
    jac = ca.jacobian(ca.vertcat(x[0] ** 2, x[1] * x[0], ca.cos(x[0])), x[:2])  # (0, 1) and (2, 1) zero
    fn = ca.Function("f", [x, p], [column, jac, ca.SX(2, 1)])
    assert [fn.nnz_out(k) for k in range(3)] == [2, 4, 0] and [fn.numel_out(k) for k in range(3)] == [4, 6, 2]
    return fn


def _names(fn):
    return [[f"o{k}_{j}" for j in range(fn.numel_out(k))] for k in range(fn.n_out())]


def _expected(fn, x):
    """CasADi's own dense values of every output (column-major, as the printer's entries)."""
    return [np.asarray(v, dtype=float).ravel(order="F") for v in fn(x, [0.5, 0.25])]


def _check(fn, got):
    for x, outs in zip(X, got):
        for out, want in zip(outs, _expected(fn, x)):
            assert len(out) == len(want)
            np.testing.assert_allclose(out, want, rtol=1e-14, atol=0)  # zeros exactly 0.0
    # the test can fail: the structural zeros sit between nonzeros, so a printer that writes nonzero k to
    # entry k (or leaves an entry unset) gives other values
    assert any(v == 0.0 for v in _expected(fn, X[0])[0]) and _expected(fn, X[0])[0][2] != 0.0


def test_python_writes_every_entry(sparse_function):
    fn, names = sparse_function, _names(sparse_function)
    body = function_lines(fn, ["x", "p"], names, "    ", True, "python")
    assert sum(line.strip().endswith("= 0.0") for line in body) == 2 + 2 + 2
    ret = "[" + ", ".join("[" + ", ".join(out) + "]" for out in names) + "]"
    scope = {"math": math}
    exec("\n".join(["def f(x, p):", *body, f"    return {ret}"]), scope)
    _check(fn, [scope["f"](list(x), [0.5, 0.25]) for x in X])


@pytest.mark.skipif(shutil.which("cc") is None and shutil.which("gcc") is None, reason="no C compiler")
def test_c_writes_every_entry(tmp_path, sparse_function):
    """Into an output array filled with NaN first (what an unset entry would keep), compiled with -Wall -Werror
    (an unset declared local is -Wuninitialized)."""
    fn, names = sparse_function, _names(sparse_function)
    sizes = [fn.numel_out(k) for k in range(fn.n_out())]
    arrays = [[f"out[{sum(sizes[:k]) + j}]" for j in range(n)] for k, n in enumerate(sizes)]
    local = function_lines(fn, ["x", "p"], names, "    ", True, "c")  # declared locals, copied out
    src = ["#include <math.h>", "void f_locals(const double *x, const double *p, double *out)", "{", "    (void)p;",
           *local, *(f"    {a} = {n};" for out_a, out_n in zip(arrays, names) for a, n in zip(out_a, out_n)), "}",
           "void f_array(const double *x, const double *p, double *out)", "{", "    (void)p;",
           *function_lines(fn, ["x", "p"], arrays, "    ", False, "c"), "}", ""]
    (tmp_path / "f.c").write_text("\n".join(src))
    cc = shutil.which("cc") or shutil.which("gcc")
    subprocess.run([cc, "-O2", "-shared", "-fPIC", "-std=c99", "-Wall", "-Werror", "-o", str(tmp_path / "f.so"),
                    str(tmp_path / "f.c"), "-lm"], check=True, timeout=60)
    lib = ctypes.CDLL(str(tmp_path / "f.so"))
    for entry in (lib.f_locals, lib.f_array):
        got = []
        for x in X:
            out = (ctypes.c_double * sum(sizes))(*([math.nan] * sum(sizes)))
            entry((ctypes.c_double * 3)(*x), (ctypes.c_double * 2)(0.5, 0.25), out)
            flat = list(out)
            got.append([flat[sum(sizes[:k]):sum(sizes[:k + 1])] for k in range(len(sizes))])
        _check(fn, got)


@pytest.mark.skipif(shutil.which("node") is None, reason="no Node.js")
def test_javascript_writes_every_entry(tmp_path, sparse_function):
    fn, names = sparse_function, _names(sparse_function)
    body = function_lines(fn, ["x", "p"], names, "  ", True, "javascript")
    ret = "[" + ", ".join("[" + ", ".join(out) + "]" for out in names) + "]"
    (tmp_path / "run.mjs").write_text("\n".join([
        "function f(x, p) {", *body, f"  return {ret};", "}",
        f"const xs = {json.dumps(X.tolist())};",
        # undefined would print as null in JSON: the comparison then fails on it
        "console.log(JSON.stringify(xs.map(x => f(x, [0.5, 0.25]))));", ""]))
    res = json.loads(subprocess.run(["node", str(tmp_path / "run.mjs")], capture_output=True, text=True, check=True,
                                    timeout=60).stdout)
    assert all(v is not None for outs in res for out in outs for v in out)
    _check(fn, res)


def test_names_that_do_not_match_an_output_are_refused(sparse_function):
    """One name per dense entry: giving the nonzeros' count instead is a ValueError, not a silent shift."""
    names = _names(sparse_function)
    names[0] = names[0][:2]
    with pytest.raises(ValueError, match="output 0 has 4 entries, given 2 names"):
        function_lines(sparse_function, ["x", "p"], names, "    ", True, "python")


@pytest.mark.skipif(shutil.which("node") is None, reason="no Node.js")
def test_the_rotary_pendulum_s_page_linearisation_has_its_zeros_from_the_printer(tmp_path):
    """The explorer's ``linear()`` of ``examples/qube_servo2.toml`` (printed without densifying: K0's row and
    column of the arm's angle are structural zeros) gives the library's M0 and K0, the arm's row 0.0."""
    from skewpend.config import Run
    from skewpend.numeric.explorer_source import explorer_js
    from skewpend.numeric.recursive import linear_matrices

    chain = Run("serve", str(ROOT / "examples" / "qube_servo2.toml")).chain()
    (tmp_path / "physics.mjs").write_text(explorer_js(chain))
    (tmp_path / "run.mjs").write_text("import * as m from './physics.mjs';\n"
                                      "console.log(JSON.stringify(m.linear(new Array(2 * m.N).fill(0), m.P)));\n")
    res = json.loads(subprocess.run(["node", str(tmp_path / "run.mjs")], capture_output=True, text=True, check=True,
                                    timeout=60).stdout)
    M0, K0 = (np.array(a, dtype=float) for a in res)
    M, _, K = linear_matrices(chain)
    np.testing.assert_allclose(M0, M, rtol=1e-12, atol=1e-14 * np.abs(M).max())
    np.testing.assert_allclose(K0, K, rtol=1e-12, atol=1e-14 * np.abs(K).max())
    assert K0[0].tolist() == [0.0, 0.0] and K0[:, 0].tolist() == [0.0, 0.0] and K0[1, 1] > 0
