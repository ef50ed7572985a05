"""simulate(method="taylor"): the Taylor series integrator generated from the derivation (issue 28).

Tolerances follow from the method: with Jorba-Zou's order and step rule the local error per step is
about tol (relative to max(1, |y|)) and every step is accepted, so over a few hundred steps of
non-chaotic motion the global error stays within a few hundred tol; against another integrator run
at 1e-13 the difference is bounded by the sum of both errors.
"""

import ctypes
import math

import numpy as np
import pytest

from skewpend import Parameters, simulate
from skewpend.errors import ParameterError

P = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
Y0 = (0.7, -0.4, 0.3, -0.2)  # a regular (non-chaotic) swing: errors are not amplified by 1e4 per 5 s


def test_agrees_with_dop853_and_with_scipy_on_the_generated_python_rhs():
    scipy = pytest.importorskip("scipy.integrate")
    from skewpend.numeric.codegen import generate, parameter_vector

    tr = simulate(P, Y0, 2.0, method="taylor", rtol=1e-12, atol=1e-12)
    assert tr.ok and tr.stats["rejected"] == 0 and tr.stats["order"] == 15
    ref = simulate(P, Y0, 2.0, method="dop853", rtol=1e-13, atol=1e-13)
    assert np.max(np.abs(tr.y[-1] - ref.y[-1])) < 1e-10
    ns: dict = {}
    exec(generate(P, "python"), ns)
    sol = scipy.solve_ivp(ns["rhs"], (0.0, 2.0), Y0, method="DOP853", rtol=1e-13, atol=1e-13,
                          args=(parameter_vector(P).tolist(),))
    assert np.max(np.abs(tr.y[-1] - sol.y[:, -1])) < 1e-10


def test_error_falls_with_the_tolerance_and_energy_is_conserved():
    ref = simulate(P, Y0, 5.0, method="dop853", rtol=1e-14, atol=1e-14).y[-1]
    errors = []
    for tol in (1e-6, 1e-9, 1e-12):  # orders 11, 15, 15 (a library each: few orders keep the tests quick)
        tr = simulate(P, Y0, 5.0, method="taylor", rtol=tol, atol=tol)
        err = float(np.max(np.abs(tr.y[-1] - ref)))
        errors.append(err)
        assert err < 300 * tol, (tol, err)
        assert tr.energy_drift < 300 * tol, (tol, tr.energy_drift)  # undamped: E - W = E - 0 conserved
        assert np.all(tr.work == 0.0)  # W is not integrated without damping or torques
    # roughly proportional: each 1000-fold tighter tolerance gains at least a factor 30 (until 1e-13)
    for loose, tight in zip(errors, errors[1:]):
        assert tight < loose / 30 or tight < 1e-12, errors


def test_mirror_start_gives_the_mirrored_trajectory():
    a = simulate(P, Y0, 3.0, method="taylor", rtol=1e-9, atol=1e-9)
    b = simulate(P, tuple(-v for v in Y0), 3.0, method="taylor", rtol=1e-9, atol=1e-9)
    assert a.t.shape == b.t.shape and np.array_equal(a.t, b.t)  # the same steps
    np.testing.assert_allclose(b.y, -a.y, rtol=0, atol=1e-13)


def test_damped_driven_model_energy_account_and_friction():
    Pd = P.replace(c1=0.05, c2=0.02, tau1=0.1, tau2=-0.05)
    tr = simulate(Pd, Y0, 5.0, method="taylor", rtol=1e-12, atol=1e-12)
    assert tr.ok and tr.energy_drift < 1e-10
    assert tr.work[-1] != 0.0  # the damping and the torques did work, and E - W was conserved
    ref = simulate(Pd, Y0, 5.0, method="dop853", rtol=1e-13, atol=1e-13)
    assert np.max(np.abs(tr.y[-1] - ref.y[-1])) < 1e-9
    assert abs(tr.work[-1] - ref.work[-1]) < 1e-9
    # Coulomb friction: -cf atan(cfs q'), whose recurrence is generated too
    Pf = P.replace(cf1=0.02, cf2=0.01, cfs=20.0)
    tr = simulate(Pf, Y0, 2.0, method="taylor", rtol=1e-12, atol=1e-12)
    ref = simulate(Pf, Y0, 2.0, method="dop853", rtol=1e-13, atol=1e-13)
    assert tr.ok and np.max(np.abs(tr.y[-1] - ref.y[-1])) < 1e-9
    assert tr.energy_drift < 1e-10


def test_dense_output_agrees_with_the_steps():
    steps = simulate(P, Y0, 2.0, method="taylor", rtol=1e-12, atol=1e-12)
    grid = simulate(P, Y0, 2.0, method="taylor", rtol=1e-12, atol=1e-12, dt_out=0.01)
    assert len(grid.t) == 201 and grid.t[-1] == 2.0
    assert np.array_equal(grid.y[-1], steps.y[-1])  # the same steps: the end state is bit for bit the same
    assert np.array_equal(grid.y[0], steps.y[0])
    # between the steps: the polynomial agrees with a tight DOP853 dense output on the same grid
    ref = simulate(P, Y0, 2.0, method="dop853", rtol=1e-13, atol=1e-13, dt_out=0.01)
    assert np.max(np.abs(grid.y - ref.y)) < 1e-9


def test_results_do_not_depend_on_the_chunking():
    from skewpend.numeric.kernels import TaylorState, parameter_vector, taylor_kernel, taylor_rule

    order, step_l = taylor_rule(1e-9)
    kernel = taylor_kernel(P, order)
    p = parameter_vector(P)

    def run(budget, cap):
        s = TaylorState.at(0.0, list(Y0) + [0.0])
        rows = np.empty((cap, 6))
        out, m, k = [], ctypes.c_int64(0), ctypes.c_int64(0)
        while True:
            rc = kernel.lib.sp_taylor(ctypes.addressof(s), p.ctypes.data, 1.0, 1e-9, 1e-9, step_l, 10**6, budget, 0.05, 21,
                                      ctypes.byref(k), rows.ctypes.data, cap, ctypes.byref(m))
            out.append(rows[: m.value].copy())
            if rc >= 0:
                return rc, np.concatenate(out)

    rc1, a = run(10**6, 1000)
    rc2, b = run(1, 2)
    assert rc1 == rc2 == 0 and a.shape == (21, 6) and np.array_equal(a, b)


def test_refusals():
    with pytest.raises(ParameterError, match="dt is the step of rk4 and gauss; taylor"):
        simulate(P, Y0, 1.0, method="taylor", rtol=1e-9, dt=1e-3)
    with pytest.raises(ParameterError, match="rtol is a tolerance of dop853 and taylor"):
        simulate(P, Y0, 1.0, method="rk4", rtol=1e-6)
    from skewpend.numeric.control import Controller

    with pytest.raises(ParameterError, match="taylor"):
        simulate(P, Y0, 1.0, method="taylor", controller=Controller.function(lambda t, y: (0.0, 0.0)))
    tr = simulate(P, Y0, 10.0, method="taylor", rtol=1e-9, atol=1e-9, max_steps=5)  # stopped at the cap
    assert not tr.ok and tr.stats["steps"] <= 5 and math.isfinite(tr.y[-1, 0])


def _columns(tr):
    return [tr.t, tr.y, tr.energy, tr.work, np.array([tr.energy_drift, tr.stats["steps"], int(tr.status)])]


def _same_bits(a, b):
    return all(x.shape == y.shape and x.tobytes() == y.tobytes() for x, y in zip(_columns(a), _columns(b)))


def test_prepared_parameters_are_per_object_and_results_equal_a_fresh_process():
    """simulate keeps what it prepared for a Parameters object (kernel, parameter array, Taylor
    kernels); another object -- other parameters, or equal ones -- gets its own, and every result
    is the same bits as in a fresh process."""
    import json
    import subprocess
    import sys

    from skewpend.numeric import simulation

    Pd = P.replace(c1=0.05, c2=0.02, tau1=0.1, tau2=-0.05)
    runs = [(P, 1e-9, None), (Pd, 1e-9, None), (P.replace(g=3.7), 1e-9, 0.05), (P, 1e-6, None), (Pd, 1e-9, None)]
    here = [simulate(Q, Y0, 3.0, method="taylor", rtol=tol, atol=tol, dt_out=d) for Q, tol, d in runs]
    assert simulation._PREPARED[id(P)].params is P and simulation._PREPARED[id(Pd)].params is Pd
    again = simulate(Parameters(**P.to_dict()), Y0, 3.0, method="taylor", rtol=1e-9, atol=1e-9)  # equal, not the same
    assert _same_bits(again, here[0])
    code = (
        "import json, sys, numpy as np\n"
        "from skewpend import Parameters, simulate\n"
        "out = []\n"
        "for d, g, tol, dt_out in json.loads(sys.argv[1]):\n"
        "    tr = simulate(Parameters(**d).replace(g=g), %r, 3.0, method='taylor', rtol=tol, atol=tol, dt_out=dt_out)\n"
        "    out.append([a.tobytes().hex() for a in (tr.t, tr.y, tr.energy, tr.work,"
        " np.array([tr.energy_drift, tr.stats['steps'], int(tr.status)]))])\n"
        "print(json.dumps(out))\n" % (Y0,)
    )
    spec = [(Q.to_dict(), Q.g, tol, d) for Q, tol, d in runs]
    fresh = json.loads(subprocess.run([sys.executable, "-c", code, json.dumps(spec)], capture_output=True, text=True,
                                      check=True).stdout)
    for tr, hexes in zip(here, fresh):
        assert [a.tobytes().hex() for a in _columns(tr)] == hexes


def test_quick_argument_paths_give_the_same_run():
    """Floats in a tuple take simulate's quick checks; arrays, ints and lists the library's checks:
    the same run either way, and the same refusals."""
    a = simulate(P, (1.0, -0.5, 0.0, 0.0), 2.0, method="taylor", rtol=1e-8, atol=1e-8)
    b = simulate(P, np.array([1, -0.5, 0, 0]), 2, method="taylor", rtol=np.float64(1e-8), atol=1e-8, max_steps=10**6)
    c = simulate(P, [1.0, -0.5, 0, 0.0], 2.0, method="taylor", rtol=1e-8, atol=1e-8)
    assert _same_bits(a, b) and _same_bits(a, c)
    for y0 in ((1.0, float("nan"), 0.0, 0.0), (2e6, 0.0, 0.0, 0.0), (0.0, 0.0, float("inf"), 0.0), (1.0, 2.0, 3.0)):
        with pytest.raises(ParameterError, match="y0|initial angles"):
            simulate(P, y0, 1.0, method="taylor")
    for t_end in (float("nan"), -1.0, 0.0, float("inf"), 1e-320):
        with pytest.raises(ParameterError, match="t_end"):
            simulate(P, Y0, t_end, method="taylor")
    with pytest.raises(ParameterError, match="rtol"):
        simulate(P, Y0, 1.0, method="taylor", rtol=1e-16, atol=1e-9)
    with pytest.raises(ParameterError, match="max_steps"):
        simulate(P, Y0, 1.0, method="taylor", max_steps=0)


def test_long_run_goes_on_in_chunks_with_progress_and_keep_false():
    """More than the first call's 2000 steps: the run continues in drive() (Interrupts, progress);
    keep=False keeps the first and last rows of the same run, and the same energy drift."""
    seen = []
    full = simulate(P, Y0, 200.0, method="taylor", rtol=1e-6, atol=1e-6, progress=lambda t, t_end: seen.append(t))
    assert full.ok and full.stats["steps"] > 3000 and len(seen) >= 2 and seen[-1] == 200.0
    assert all(x <= y for x, y in zip(seen, seen[1:]))
    ends = simulate(P, Y0, 200.0, method="taylor", rtol=1e-6, atol=1e-6, keep=False)
    assert not ends.kept and len(ends.t) == 2 and ends.energy_drift == full.energy_drift
    for name in ("t", "y", "energy", "work"):
        assert np.array_equal(getattr(ends, name), getattr(full, name)[[0, -1]])
    short = simulate(P, Y0, 0.5, method="taylor", rtol=1e-6, atol=1e-6, progress=lambda t, t_end: seen.append(-t))
    assert short.ok and seen[-1] == -0.5  # one call: progress once, at the end
    for name in ("t", "y", "energy", "work"):  # arrays of their own, contiguous
        arr = getattr(full, name)
        assert arr.flags.c_contiguous and arr.flags.owndata


def test_step_rows_carry_the_model_energy_and_do_not_depend_on_the_chunking():
    """At the integrator's own steps (sp_taylor_rows) each row's energy comes from the series' order 0
    (generated from T + Pi of the derivation): it equals the model kernel's energy to rounding, and
    the rows, energies and account are the same bits however the run is split into calls."""
    from skewpend.numeric import simulation
    from skewpend.numeric.kernels import TaylorState, kernel_module, parameter_vector, taylor_kernel, taylor_rule

    Pd = P.replace(c1=0.05, tau2=-0.05)
    p = parameter_vector(Pd)
    tr = simulate(Pd, Y0, 3.0, method="taylor", rtol=1e-10, atol=1e-10)
    rows = np.column_stack([tr.t, tr.y, tr.work])
    energy, acc = np.empty(len(rows)), np.zeros(4)
    kernel_module(Pd).lib.sp_energy_account(rows.ctypes.data, len(rows), 6, p.ctypes.data, energy.ctypes.data,
                                            acc.ctypes.data)
    np.testing.assert_allclose(tr.energy, energy, rtol=0, atol=1e-13 * np.max(np.abs(energy)))
    assert abs(tr.energy_drift - acc[0] / acc[1]) < 1e-12

    order, step_l = taylor_rule(1e-10)
    fn = simulation._rows_fn(taylor_kernel(Pd, order))
    y0 = (ctypes.c_double * 4)(*Y0)

    def run(budget, cap):
        s, m = TaylorState(), ctypes.c_int64(0)
        cols, e, acc = np.empty(6 * cap), np.empty(cap), np.zeros(4)  # t, y (cap x 4), W as columns
        out, first = [], True
        while True:
            rc = fn(ctypes.addressof(s), ctypes.addressof(y0) if first else None, p.ctypes.data, 3.0, 1e-10, 1e-10,
                    step_l, 10**6, budget, cols.ctypes.data, cap, e.ctypes.data, acc.ctypes.data, ctypes.byref(m))
            first = False
            k = m.value
            out.append(np.column_stack([cols[:k], cols[cap:5 * cap].reshape(cap, 4)[:k], cols[5 * cap:][:k], e[:k]]))
            if rc >= 0:
                return rc, np.concatenate(out), acc

    rc1, a, acc1 = run(10**6, 1000)
    rc2, b, acc2 = run(1, 2)
    assert rc1 == rc2 == 0 and np.array_equal(a, b) and np.array_equal(acc1, acc2)
    assert np.array_equal(a[:, :6], rows) and np.array_equal(a[:, 6], tr.energy)


def test_an_initial_state_that_overflows_is_refused():
    with pytest.raises(ParameterError, match="not finite"):
        simulate(P, (0.5, 0.5, 1e200, -1e200), 1.0, method="taylor", rtol=1e-8, atol=1e-8)


def test_a_trajectory_made_in_one_call_has_every_field():
    """simulate's quick Taylor result sets the Trajectory's fields at once: all of them, as its
    dataclass would (a field added later must be added there too)."""
    import dataclasses

    from skewpend.numeric.simulation import Trajectory

    tr = simulate(P, Y0, 1.0, method="taylor", rtol=1e-8, atol=1e-8)
    assert set(vars(tr)) == {f.name for f in dataclasses.fields(Trajectory)}
    assert type(tr.status).__name__ == "Status" and tr.ok and tr.controller is None and tr.kept
    same = Trajectory(**vars(tr))
    assert same.status is tr.status and repr(same) == repr(tr)


def test_the_rule_by_tolerance_band_and_the_summary_line():
    """The order and step exponent follow kernels.taylor_rule (L = 1.5 to 1e-9, 1.75 to 1e-11, 2 below:
    heyoka's rule there, so its orders), the run reports them, and the CLI's summary says them."""
    from skewpend.cli.simulate import summary
    from skewpend.numeric.kernels import taylor_rule

    assert [taylor_rule(t) for t in (1e-4, 1e-9, 1e-10, 1e-12, 1e-15)] == [(8, 1.5), (15, 1.5), (15, 1.75), (15, 2.0),
                                                                          (19, 2.0)]
    for tol in (1e-12, 1e-14):  # heyoka.py's ceil(-ln(tol) / 2) + 1
        assert taylor_rule(tol)[0] == math.ceil(-math.log(tol) / 2) + 1
    for tol in (1e-6, 1e-9, 1e-12):  # the bound the series' last terms estimate: e^(-L (p - 1)) <= tol
        p, L = taylor_rule(tol)
        assert math.exp(-L * (p - 1)) <= tol < math.exp(-L * (p - 2))
    tr = simulate(P, Y0, 1.0, method="taylor", rtol=1e-9, atol=1e-9)
    assert (tr.stats["order"], tr.stats["step_exponent"]) == (15, 1.5)
    assert "(order 15, step factor e^-1.5)" in summary(tr, None)
    assert "order" not in summary(simulate(P, Y0, 1.0, method="dop853"), None).split("steps")[1].split("\n")[0]


@pytest.mark.slow
def test_the_looped_jet_computes_the_written_out_jets_series(tmp_path, monkeypatch):
    """One model, two ways of printing its series (numeric.taylor_source): every order written out (the double
    pendulum's, small models) and one loop over the orders (models above LOOP_FROM_OPS operations, a chain of
    three). Printed both ways for a damped skewed double pendulum with Coulomb friction (every kind of series
    operation: sums, products, squares, quotients, sin/cos, atan), the same steps' states agree to rounding:
    the loops add in another order (1e-12 over 2 s of a regular swing; measured ~1e-15)."""
    import ctypes

    from skewpend import Parameters
    from skewpend.numeric import kernels as K, simulation, taylor_source
    from skewpend.numeric.taylor_source import exact_system, taylor_c_source

    P = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81, c1=0.05, cf2=0.03, tau1=0.1)
    order, step_l = K.taylor_rule(1e-10)
    p = K.parameter_vector(P)
    runs = []
    for loop_from in (10**6, 0):
        monkeypatch.setattr(taylor_source, "LOOP_FROM_OPS", loop_from)
        source = taylor_c_source(exact_system(K.geometry_of(P)), order)
        assert ("for (int k = 0; k < SP_TORDER; k++)" in source) == (loop_from == 0)
        path = tmp_path / f"taylor_loop{loop_from}{K.LIB_SUFFIX}"
        K._compile(source, path, K.fused_multiply_add()[1])
        fn = simulation._rows_fn(K.TaylorKernel(path, "compiled", 0.0, order))
        s, m, cap = K.TaylorState(), ctypes.c_int64(0), 4096
        cols, e, acc = np.empty(6 * cap), np.empty(cap), np.zeros(4)
        y0 = (ctypes.c_double * 4)(0.7, -0.4, 0.3, -0.2)
        rc = fn(ctypes.addressof(s), ctypes.addressof(y0), p.ctypes.data, 2.0, 1e-10, 1e-10, step_l, 10**6, 10**6,
                cols.ctypes.data, cap, e.ctypes.data, acc.ctypes.data, ctypes.byref(m))
        k = m.value
        assert rc == 0 and k > 20
        runs.append(np.column_stack([cols[:k], cols[cap:cap + 4 * k].reshape(k, 4), e[:k]]))
    a, b = runs
    assert a.shape == b.shape
    assert np.max(np.abs(a - b)) < 1e-12, np.max(np.abs(a - b))
