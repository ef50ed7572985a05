"""Kernels keyed by structure, values at run time (issue 37, goal 2).

Only what changes the form of the equations keys a compiled library: the hinge axes, which entries of
each body's centre of mass and inertia tensor are zero, and whether the optional friction and rotor
terms exist.  Masses, lengths, g, damping, friction, rotor values and every non-zero body entry are
read from ``p`` at run time.  So:

* rigs that differ only in values share one library (the model's, the Taylor series', the flip and
  chaos libraries); rigs of another structure do not;
* the shared library evaluated with another rig's ``p`` is that rig's model: its accelerations and
  energy equal SymPy's numeric derivation of that rig (independent of the generated C), to the
  rounding of a 2 x 2 solve;
* end to end, a second simulation of a new rig of the same structure compiles nothing (a fresh
  cache in a subprocess: the compile notes on stderr are counted).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from helpers import sympy_reference

from skewpend import Parameters
from skewpend.numeric.conventions import parameter_vector, structure_of
from skewpend.numeric.kernels import kernel_module, taylor_kernel, taylor_order

#: A general rig: both bodies off the rod axis, full inertia tensors, skewed axes given as vectors.
RIG = Parameters(
    a=0.9, b=0.7, m1=1.1, m2=0.6, g=9.81, c1=0.02, c2=0.01,
    axis1=(0.0, 0.0, 1.0), axis2=(0.3, 0.0, 1.0),
    com1=(0.01, 0.42, 0.0), com2=(0.02, 0.33, -0.01),
    inertia1=((0.08, 0.001, 0.0), (0.001, 0.004, 0.0), (0.0, 0.0, 0.08)),
    inertia2=((0.03, 0.002, 0.001), (0.002, 0.003, 0.001), (0.001, 0.001, 0.03)),
)
#: The same structure, every value changed (masses, lengths, g, damping, each non-zero body entry).
OTHER = RIG.replace(
    a=1.2, b=0.5, m1=0.7, m2=1.3, g=3.7, c1=0.1, c2=0.3,
    com1=(0.03, 0.55, 0.0), com2=(-0.01, 0.21, 0.02),
    inertia1=((0.1, -0.002, 0.0), (-0.002, 0.006, 0.0), (0.0, 0.0, 0.1)),
    inertia2=((0.05, 0.001, -0.002), (0.001, 0.008, 0.002), (-0.002, 0.002, 0.047)),
)


_reference = sympy_reference  # accelerations and energy straight from SymPy


def test_values_do_not_key_a_library_and_structure_does():
    assert structure_of(RIG) == structure_of(OTHER)
    assert kernel_module(RIG).path == kernel_module(OTHER).path
    thin = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
    assert kernel_module(thin).path == kernel_module(thin.replace(m1=2.0, a=0.4, b=1.3, g=1.6, alpha=1.1)).path
    # another zero pattern (com1 on the rod axis: its x entry zero) is another structure
    moved = RIG.replace(com1=(0.0, 0.42, 0.0))
    assert structure_of(moved) != structure_of(RIG) and kernel_module(moved).path != kernel_module(RIG).path
    # the optional terms exist or not: friction keys a library, its values do not
    fr = thin.replace(cf1=0.05)
    assert kernel_module(fr).path != kernel_module(thin).path
    assert kernel_module(fr).path == kernel_module(fr.replace(cf1=0.2, cf2=0.1, cfs=30.0)).path


def test_the_shared_library_is_each_rigs_model():
    """RIG's library, evaluated with OTHER's p, gives OTHER's equations (SymPy, from its own numbers)."""
    k = kernel_module(RIG)
    for params in (RIG, OTHER):
        acc, en = _reference(params)
        p = parameter_vector(params)
        out = np.empty(5)
        for y in np.random.default_rng(37).uniform(-2.5, 2.5, (12, 4)):
            k.rhs(np.append(y, 0.0), p, out)
            # a 2 x 2 solve and the expressions' rounding: 1e-11 on accelerations of order 10
            np.testing.assert_allclose(out[2:4], acc(y), rtol=1e-11, atol=1e-11)
            assert k.energy(y, p) == pytest.approx(en(y), rel=1e-12, abs=1e-12)


def test_the_taylor_series_reads_the_values_at_run_time():
    """One Taylor library for both rigs; each run of OTHER agrees with DOP853 on OTHER's model (a
    different integrator on the same kernel inputs) to the tolerance's scale."""
    import skewpend

    order = taylor_order(1e-12)  # the runs' own library (another order would build one more for the look only)
    assert taylor_kernel(RIG, order).path == taylor_kernel(OTHER, order).path
    y0 = np.array([0.8, -0.4, 0.0, 0.5])
    a = skewpend.simulate(OTHER, y0, 3.0, method="taylor", rtol=1e-12, atol=1e-12)
    b = skewpend.simulate(OTHER, y0, 3.0, method="dop853", rtol=1e-12, atol=1e-12)
    c = skewpend.simulate(RIG, y0, 3.0, method="taylor", rtol=1e-12, atol=1e-12)
    # both at 1e-12 over 3 s of a mildly chaotic motion (divergence e^3): agreement to 1e-8
    assert np.max(np.abs(a.y[-1][:4] - b.y[-1][:4])) < 1e-8
    assert np.max(np.abs(a.y[-1][:4] - c.y[-1][:4])) > 1e-3  # and the values did change the motion


def test_a_new_rig_of_the_same_structure_compiles_nothing(tmp_path):
    """A fresh cache: the first rig compiles (the notes say so), the second compiles nothing."""
    script = textwrap.dedent("""
        import sys
        import numpy as np
        import skewpend
        rig = skewpend.Parameters(a=0.9, b=0.7, m1=1.1, m2=0.6, g=9.81, alpha=0.4, com1=(0.01, 0.42, 0.0),
                                  inertia1=((0.08, 0.001, 0.0), (0.001, 0.004, 0.0), (0.0, 0.0, 0.08)))
        y0 = np.array([0.5, 0.2, 0.0, 0.0])
        skewpend.simulate(rig, y0, 1.0, method=sys.argv[1])
        print("SECOND", file=sys.stderr, flush=True)
        other = rig.replace(m1=2.0, a=1.3, com1=(0.05, 0.6, 0.0), g=1.62,
                            inertia1=((0.2, 0.01, 0.0), (0.01, 0.02, 0.0), (0.0, 0.0, 0.19)))
        skewpend.simulate(other, y0, 1.0, method=sys.argv[1])
    """)
    env = dict(os.environ, SKEWPEND_CACHE_DIR=str(tmp_path / "cache"))
    for method in ("dop853", "taylor"):
        proc = subprocess.run([sys.executable, "-c", script, method], capture_output=True, text=True, env=env,
                              timeout=600)
        assert proc.returncode == 0, proc.stderr
        first, second = proc.stderr.split("SECOND")
        if method == "dop853":  # the fresh cache's first model compiles
            assert "compiling the model's kernels" in first
        assert "compiling" not in second, second


# -- chains: the hinge axes' components are values (issue 52) ------------------------------------------------
def test_a_chains_axes_are_values_within_their_pattern():
    """The zero pattern of each axis keys the straight-line library, not its components: chains tilted
    differently within the patterns share one library, whose model with another chain's ``p`` is that
    chain's (its energy and accelerations equal the library built for it alone, by the symbolic
    derivation's check in test_chain); an axis along k is another pattern; the compact form has none."""
    from skewpend.numeric.kernels import chain_kernel
    from skewpend.numeric.recursive import axis_pattern, parameter_vector as chain_vector, structure_of_chain
    from skewpend.symbolic.chain import Chain

    a = Chain.from_lists(3, axis=[(0, 0, 1), (0.35, 0.0, 1.0), (0.1, 0.3, 1.0)], mass=[1.0, 0.7, 0.5])
    b = Chain.from_lists(3, axis=[(0, 0, 1), (-0.9, 0.0, 0.4), (0.5, -0.2, 1.0)], mass=[1.2, 0.4, 0.9])
    assert [axis_pattern(link.axis) for link in a.links] == ["+z", "xz", "xyz"]
    sa, sb = structure_of_chain(a), structure_of_chain(b)
    assert sa == sb and sa.key() == sb.key()
    planar = Chain.from_lists(3, axis=[(0, 0, 1)] * 3)
    assert structure_of_chain(planar).key() != sa.key()
    assert structure_of_chain(planar).key("compact") == sa.key("compact")
    assert chain_kernel(a) is chain_kernel(b)
    rng = np.random.default_rng(52)
    ys = np.column_stack([rng.uniform(-2, 2, (5, 3)), rng.uniform(-2, 2, (5, 3))])
    k = chain_kernel(a)
    energies = k.energies(ys, chain_vector(b))
    tips = k.tips_many(ys, chain_vector(b))
    # b's own model, through the symbolic derivation (SymPy, independent of the generated C)
    import sympy as sp

    import skewpend

    eom = skewpend.derive(b)
    energy = sp.lambdify(list(eom.q) + list(eom.dq), eom.kinetic_energy + eom.potential_energy, "numpy")
    want = np.array([float(energy(*y)) for y in ys])
    np.testing.assert_allclose(energies, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
    assert np.all(np.isfinite(tips))


def test_tilting_a_chains_axis_compiles_nothing(tmp_path):
    """A fresh cache: the first chain compiles; tilting its skewed axes (and alpha-like turns in a plane)
    compiles nothing, in the straight form (3 links) and the compact one (10 links)."""
    script = textwrap.dedent("""
        import sys
        import skewpend
        from skewpend.symbolic.chain import Chain
        n = int(sys.argv[1])
        def chain(t):
            return Chain.from_lists(n, axis=[(0, 0, 1)] + [(t * (i % 3 + 1), 0.1 * t * (i % 2 + 1), 1.0) for i in range(n - 1)])
        skewpend.simulate(chain(0.3), [0.5] * n + [0.0] * n, 0.5, method="dop853")
        print("SECOND", file=sys.stderr, flush=True)
        for t in (0.1, 0.7, -1.4):
            skewpend.simulate(chain(t), [0.5] * n + [0.0] * n, 0.5, method="dop853")
    """)
    env = dict(os.environ, SKEWPEND_CACHE_DIR=str(tmp_path / "cache"))
    for n in (3, 10):
        proc = subprocess.run([sys.executable, "-c", script, str(n)], capture_output=True, text=True, env=env,
                              timeout=600)
        assert proc.returncode == 0, proc.stderr
        first, second = proc.stderr.split("SECOND")
        assert "compiling" in first
        assert "compiling" not in second, second
