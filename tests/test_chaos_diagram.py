"""The chaos diagram over (alpha, energy): a tiny diagram against physics and against the
single-trajectory Lyapunov exponent, bitwise independence of workers, stores and clusters,
resuming a store, bad input.

Parameters: thin rods, ``a = b = 1 m``, ``m1 = m2 = 1 kg`` (alpha is the diagram's axis).  The
planar double pendulum (alpha = 0) is regular at 3 J above the minimum and mostly chaotic at 20 J.
"""

from __future__ import annotations

import json
import logging
import math

import numpy as np
import pytest
import sympy as sp

from skewpend import SYMBOLS, ParameterError, Parameters, derive
from skewpend.analysis.chaos import ChaosDiagram, chaos_diagram, default_threshold, open_chaos_diagram
from skewpend.analysis.lyapunov import lyapunov
from skewpend.analysis.poincare import EnergySurface, energy_minimum, section_seeds
from skewpend.numeric.kernels import kernel_module, parameter_vector

P = Parameters(a=1.0, b=1.0, m1=1.0, m2=1.0, g=9.81, alpha=0.6)
T_END = 60.0
KW = dict(alpha=[0.0, 0.6], energy=[3.0, 20.0], samples=4, t_end=T_END)


@pytest.fixture(scope="module")
def ref() -> ChaosDiagram:
    return chaos_diagram(P, workers=1, **KW)


def same(a: ChaosDiagram, b: ChaosDiagram) -> bool:
    return a.exponent.tobytes() == b.exponent.tobytes() and a.threshold == b.threshold


# -- 1. a tiny diagram ----------------------------------------------------------------------------------------------
def test_tiny_diagram_shape_and_physics(ref):
    d = ref
    assert d.exponent.shape == (2, 2, 4) and d.fraction.shape == d.mean_exponent.shape == (2, 2)
    assert np.array_equal(d.alpha, [0.0, 0.6]) and np.array_equal(d.energy, [3.0, 20.0])
    assert np.all(d.valid == 4) and np.all(np.isfinite(d.exponent))
    assert d.stats["trajectories"] == 16 and d.stats["failed"] == 0 and d.stats["unreachable"] == 0
    assert np.all((d.fraction >= 0) & (d.fraction <= 1))
    # the fraction is the share of samples above the threshold, by definition
    assert np.array_equal(d.fraction, (d.exponent > d.threshold).mean(axis=2))
    # threshold: max(0.1 omega_low, 4 ln(t_end)/t_end), omega_low the lower small-oscillation
    # frequency at alpha = 0 -- here from the linear equations of derive(), not the generated Jacobian
    lin = derive(P.replace(alpha=0.0)).linearize()
    w2 = np.linalg.eigvals(np.linalg.solve(np.array(lin.M, dtype=float), np.array(lin.K, dtype=float)))
    omega_low = math.sqrt(float(np.min(w2.real)))
    expected = max(0.1 * omega_low, 4.0 * math.log(T_END) / T_END)
    assert d.threshold == pytest.approx(expected, rel=1e-9) and default_threshold(P, T_END) == d.threshold
    # planar pendulum: at 3 J every sampled motion is regular -- finite-time exponents of order
    # ln(T)/T (<= 2 ln(T)/T, see test_lyapunov.py) -- and at 20 J most are chaotic (~1 1/s)
    assert d.fraction[0, 0] == 0.0 and np.all(d.exponent[0, 0] <= 2 * math.log(T_END) / T_END)
    assert d.fraction[0, 1] > 0.5 and np.max(d.exponent[0, 1]) > 0.5
    assert len(d.table().splitlines()) == 3
    ds = d.to_xarray()
    assert ds["exponent"].dims == ("alpha", "energy", "sample") and np.array_equal(ds["exponent"].values, d.exponent)
    assert json.loads(ds.attrs["settings"])["samples"] == 4


def test_samples_are_single_trajectory_exponents_on_the_energy_surface(ref):
    """Each sample is the largest exponent (lyapunov, n_exponents=1, the diagram's tolerance 1e-8)
    of a start on the section phi = 0 (phi' > 0) at E_min + E: the same algorithm, so equal to
    rounding; the start is checked to lie on that energy surface with the symbolic energy."""
    params = P.replace(alpha=0.6)
    kernel, p = kernel_module(params, chaos=True), parameter_vector(params)
    e_min, _ = energy_minimum(kernel, p)
    eom = derive(params)
    q = [SYMBOLS[n] for n in ("phi", "psi", "dphi", "dpsi")]
    energy = sp.lambdify(q, eom.kinetic_energy + eom.potential_energy, "math")
    for j, de in enumerate(ref.energy):
        surface = EnergySurface(kernel, p, e_min + de, 0, 0.0, e_min)
        starts = surface.states(*section_seeds(surface, 4).T, +1)
        for s in (0, 3):
            y0 = starts[s]
            assert y0[0] == 0.0 and y0[2] > 0
            assert energy(*y0) == pytest.approx(e_min + de, rel=1e-12)
            one = lyapunov(params, y0, t_end=T_END, n_exponents=1, rtol=1e-8, atol=1e-8)
            assert ref.exponent[1, j, s] == pytest.approx(one.exponents[0], rel=1e-12)


# -- 3. workers -----------------------------------------------------------------------------------------------------
def test_workers_do_not_change_the_result(ref):
    calls = []
    d = chaos_diagram(P, workers=2, progress=lambda done, total: calls.append((done, total)), **KW)
    assert same(d, ref) and d.stats["workers"] == 2
    assert calls[0] == (0, 2) and calls[-1] == (2, 2)


# -- 2. store and resume --------------------------------------------------------------------------------------------
def test_store_open_and_resume(ref, tmp_path):
    pytest.importorskip("zarr")
    path = tmp_path / "diagram.zarr"
    d = chaos_diagram(P, store=path, **KW)
    assert same(d, ref) and d.stats["store"] == str(path) and d.stats["rows_computed"] == 2
    back = open_chaos_diagram(path)
    assert same(back, ref) and np.array_equal(back.alpha, ref.alpha) and np.array_equal(back.energy, ref.energy)
    assert back.settings == ref.settings and np.array_equal(back.fraction, ref.fraction)
    # an existing store is never overwritten
    with pytest.raises(ParameterError, match="exists; resume it"):
        chaos_diagram(P, store=path, **KW)
    # resuming with other settings is refused, naming what differs
    with pytest.raises(ParameterError, match="other settings: .*t_end 50.0 \\(store: 60.0\\)"):
        chaos_diagram(P, store=path, resume=True, **{**KW, "t_end": 50.0})
    with pytest.raises(ParameterError, match="other settings: .*samples 5 \\(store: 4\\)"):
        chaos_diagram(P, store=path, resume=True, **{**KW, "samples": 5})
    # resuming a complete store computes nothing
    again = chaos_diagram(P, store=path, resume=True, **KW)
    assert same(again, ref) and again.stats["rows_resumed"] == 2 and again.stats["rows_computed"] == 0
    # a row whose done flag is cleared (and its data spoilt) is computed again, bitwise as before
    import zarr

    group = zarr.open_group(str(path), mode="r+")
    group["done"][1] = False
    group["exponent"][1] = -1.0
    fixed = chaos_diagram(P, store=path, resume=True, **KW)
    assert same(fixed, ref) and fixed.stats["rows_resumed"] == 1 and fixed.stats["rows_computed"] == 1
    assert same(open_chaos_diagram(path), ref)


def test_an_interrupted_store_is_incomplete_and_resumes_bitwise(ref, tmp_path):
    pytest.importorskip("zarr")
    path = tmp_path / "diagram.zarr"

    def interrupt(done, total):  # Ctrl-C once the first row is stored
        if done == 1:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        chaos_diagram(P, store=path, workers=1, progress=interrupt, **KW)
    with pytest.raises(ParameterError, match="is not complete"):
        open_chaos_diagram(path)
    d = chaos_diagram(P, store=path, resume=True, **KW)
    assert same(d, ref) and d.stats["rows_resumed"] == 1 and d.stats["rows_computed"] == 1
    assert same(open_chaos_diagram(path), ref)


def test_refusal_names_only_what_differs(ref, tmp_path):
    pytest.importorskip("zarr")
    path = tmp_path / "diagram.zarr"
    chaos_diagram(P, store=path, **KW)
    with pytest.raises(ParameterError) as exc:
        chaos_diagram(P, store=path, resume=True, **{**KW, "samples": 5})
    assert "alpha" not in str(exc.value)


def test_netcdf_reads_back(ref, tmp_path):
    xr = pytest.importorskip("xarray")
    pytest.importorskip("netCDF4")
    path = tmp_path / "diagram.nc"
    ref.to_netcdf(path)
    with xr.open_dataset(path) as ds:
        assert np.array_equal(ds["exponent"].values, ref.exponent)
        assert np.array_equal(ds["fraction"].values, ref.fraction)
        assert np.array_equal(ds["alpha"].values, ref.alpha) and ds.attrs["threshold"] == ref.threshold
    assert [p.name for p in tmp_path.iterdir()] == ["diagram.nc"]


# -- 4. on a Dask cluster -------------------------------------------------------------------------------------------
@pytest.fixture
def time_limit():
    """No pytest-timeout in the test extra: SIGALRM stops a cluster test that hangs (60 s)."""
    import signal

    if not hasattr(signal, "SIGALRM"):  # pragma: no cover - not POSIX
        yield
        return

    def expired(signum, frame):
        raise TimeoutError("test took longer than 60 s")

    old = signal.signal(signal.SIGALRM, expired)
    signal.alarm(60)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.fixture(scope="module")
def cluster():
    distributed = pytest.importorskip("distributed")
    # threads in this process (processes=False) over TCP on 127.0.0.1; ":0": no fixed port for the
    # scheduler's HTTP server (see test_flipmap_cluster.py)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, host="127.0.0.1",
                                  protocol="tcp://", dashboard_address=":0", silence_logs=logging.ERROR) as lc:
        yield lc


def test_cluster_result_is_bitwise_the_local_one(time_limit, cluster, ref):
    import distributed

    d = chaos_diagram(P, scheduler=cluster.scheduler_address, **KW)
    assert same(d, ref) and d.stats["scheduler"] == cluster.scheduler_address
    with distributed.Client(cluster.scheduler_address, set_as_default=False) as client:
        d = chaos_diagram(P, scheduler=client, **KW)
        assert same(d, ref)
        assert client.status == "running"  # a client passed in is left open


# -- 5. bad input ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("params, kwargs, match", [
    (Parameters(a=1, b=1, m1=1, m2=1, g=9.81, axis2=(0.0, 0.5, 1.0)), {}, "axis2"),
    (P.replace(c1=0.1), {}, "conservative.*c1 = 0.1"),
    (P.replace(c2=0.1), {}, "conservative.*c2 = 0.1"),
    (P.replace(tau1=0.2), {}, "conservative.*tau1 = 0.2"),
    (P, dict(energy=[0.0, 3.0]), "energy values must be positive"),
    (P, dict(energy=[-1.0]), "energy values must be positive"),
    (P, dict(energy=[3.0, 3.0]), "energy values must be increasing"),
    (P, dict(samples=0), "samples"),
    (P, dict(samples=2.5), "samples"),
    (P, dict(alpha=[0.6, 0.0]), "alpha values must be increasing"),
    (P, dict(alpha=[]), "alpha"),
    (P, dict(alpha=[0.0, math.nan]), "alpha"),
    (P, dict(t_end=0.0), "t_end"),
    (P, dict(t_end=10.0, renorm_every=20.0), "renorm_every"),
    (P, dict(threshold=-1.0), "threshold"),
    (P, dict(resume=True), "resume needs a store"),
    (P, dict(workers=2, scheduler="tcp://127.0.0.1:8786"), "workers or scheduler, not both"),
    (Parameters(), {}, "numeric values"),
    ("P", {}, "params must be a skewpend.Parameters"),
])
def test_bad_input_is_refused(params, kwargs, match):
    with pytest.raises(ParameterError, match=match):
        chaos_diagram(params, **{**KW, **kwargs})


def test_alpha_left_symbolic_is_the_diagrams_own_axis(ref):
    """params without alpha (every other parameter numeric) is accepted: alpha is the axis."""
    d = chaos_diagram(Parameters(a=1, b=1, m1=1, m2=1, g=9.81), workers=1, **KW)
    assert same(d, ref)
