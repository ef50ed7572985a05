"""A chain's standalone code (issue 38: "the generated code, Python, C, JavaScript, for any N"): the Python and
JavaScript modules printed from the recursive algorithms' CasADi graphs give the compiled kernels' right-hand
side, energy, rod ends and hinge axes, and the Python module's motion under SciPy conserves the energy."""

from __future__ import annotations

import json
import shutil
import subprocess

import numpy as np
import pytest

from skewpend.numeric import recursive
from skewpend.numeric.kernels import chain_kernel
from skewpend.symbolic.chain import Chain

CHAINS = {
    "skewed triple, damped": Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], damping=[0.1, 0.0, 0.05],
                                             axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)], torque=[0.0, 0.2, 0.0]),
    "five general bodies": Chain.from_lists(5, length=0.3, mass=[1.0, 0.9, 0.7, 0.5, 0.4],
                                           axis=[(np.sin(0.3 * k), 0.1 * k, np.cos(0.3 * k)) for k in range(5)],
                                           com=[(0.01 * k, 0.12, -0.01) for k in range(5)]),
}


def _kernel_values(chain, ys):
    """The compiled kernel's (q', q''), energy, rod ends and axes at the states ``ys``."""
    n = chain.n
    K, p = chain_kernel(chain), recursive.parameter_vector(chain)
    rows = []
    for y in ys:
        out, tips = np.empty(2 * n + 1), np.empty(3 * n)
        yy = np.r_[y, 0.0]
        K.rhs(yy, p, out)
        K.tips(yy, p, tips)
        rows.append((out[:2 * n], K.energy(yy, p), tips, np.asarray(K.axes_many(yy[None, :], p))[0]))
    return rows


def _states(n, seed):
    rng = np.random.default_rng(seed)
    return [np.r_[rng.uniform(-3, 3, n), rng.normal(size=n)] for _ in range(12)]


@pytest.mark.parametrize("name", list(CHAINS))
def test_the_python_module_is_the_kernel(name):
    """The same operations in the same order as the kernel's C: equal to rounding (1e-13 of the largest value)."""
    chain = CHAINS[name]
    ns: dict = {}
    exec(recursive.chain_code(chain, "python"), ns)
    assert list(ns["P"]) == recursive.parameter_vector(chain).tolist() and ns["N"] == chain.n
    ys = _states(chain.n, 3)
    for y, (dy, E, tips, axes) in zip(ys, _kernel_values(chain, ys)):
        np.testing.assert_allclose(ns["rhs"](0.0, list(y)), dy, rtol=0, atol=1e-13 * np.abs(dy).max())
        assert ns["energy"](list(y)) == pytest.approx(E, rel=1e-13, abs=1e-13)
        np.testing.assert_allclose(ns["ends"](list(y[:chain.n])), tips, rtol=0, atol=1e-14)
        np.testing.assert_allclose(ns["axes"](list(y[:chain.n])), axes, rtol=0, atol=1e-14)


def test_the_python_module_conserves_energy_under_scipy():
    """The undamped triple by SciPy's DOP853 on the module's ``rhs``: the energy kept to the integrator's
    tolerance over 5 s of chaotic motion (1e-8 of the energy scale at rtol = atol = 1e-11)."""
    from scipy.integrate import solve_ivp

    chain = Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)])
    ns: dict = {}
    exec(recursive.chain_code(chain, "python"), ns)
    y0 = [2.0, -1.0, 0.5, 0.0, 0.0, 0.0]
    sol = solve_ivp(ns["rhs"], (0.0, 5.0), y0, method="DOP853", rtol=1e-11, atol=1e-11, dense_output=False)
    E = np.array([ns["energy"](list(y)) for y in sol.y.T])
    assert sol.success and np.ptp(E) < 1e-8 * max(1.0, np.abs(E).max())


@pytest.mark.skipif(shutil.which("node") is None, reason="no Node.js")
@pytest.mark.parametrize("name", list(CHAINS))
def test_the_javascript_module_is_the_kernel(tmp_path, name):
    chain = CHAINS[name]
    (tmp_path / "chain.mjs").write_text(recursive.chain_code(chain, "javascript"))
    ys = _states(chain.n, 4)
    (tmp_path / "run.mjs").write_text(
        "import { rhs, energy, ends, axes, P, N, PARAMETER_ORDER } from './chain.mjs';\n"
        f"const ys = {json.dumps([y.tolist() for y in ys])};\n"
        "console.log(JSON.stringify({P, N, order: PARAMETER_ORDER, rows: ys.map(y => [rhs(y), energy(y), "
        "ends(y.slice(0, N)), axes(y.slice(0, N))])}));\n")
    res = json.loads(subprocess.run(["node", str(tmp_path / "run.mjs")], capture_output=True, text=True,
                                    check=True).stdout)
    assert res["P"] == recursive.parameter_vector(chain).tolist() and res["N"] == chain.n
    assert tuple(res["order"]) == recursive.parameter_names(chain.n)
    for (dy_js, E_js, tips_js, axes_js), (dy, E, tips, axes) in zip(res["rows"], _kernel_values(chain, ys)):
        np.testing.assert_allclose(dy_js, dy, rtol=0, atol=1e-13 * np.abs(dy).max())
        assert E_js == pytest.approx(E, rel=1e-13, abs=1e-13)
        np.testing.assert_allclose(tips_js, tips, rtol=0, atol=1e-14)
        np.testing.assert_allclose(axes_js, axes, rtol=0, atol=1e-14)
