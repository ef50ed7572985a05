"""Nonlinear normal modes of a chain of links (issue 38): the chain of two's families against the double
pendulum's, a skewed triple pendulum's three families checked against simulate (orbits close, energy kept,
the monodromy matrix of an unstable orbit against differences of the flow), the flip energy against its
closed form, the file round trip and the command line."""

from __future__ import annotations

import numpy as np
import pytest

import skewpend
from skewpend.analysis.orbits import flip_energy
from skewpend.errors import ParameterError
from skewpend.symbolic.chain import Chain


def _triple() -> Chain:
    return Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)])


@pytest.fixture(scope="module")
def mode3():
    return skewpend.nnm(_triple(), 3, resolution=30)


def test_the_chain_of_twos_nonlinear_normal_modes_are_the_double_pendulums(recursive_forms):
    """Both families of the skewed double pendulum from its symbolic kernel and from the chain of two's
    recursive one: the same orbits (energies, frequencies to 1e-8), the same stability and events, and the same
    flip energy (the minimum of V on the square's sides; the chain's search over the faces of its cube)."""
    params = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.3, g=9.81)
    chain = Chain.from_parameters(params)
    assert flip_energy(chain) == pytest.approx(flip_energy(params), rel=1e-9)
    for mode in (1, 2):
        a = skewpend.nnm(params, mode, energy_max=1.5, resolution=5)
        b = skewpend.nnm(chain, mode, energy_max=1.5, resolution=5)
        assert a.ok and b.ok and len(a) == len(b)
        np.testing.assert_allclose(b.energies, a.energies, rtol=1e-8)
        np.testing.assert_allclose(b.frequencies, a.frequencies, rtol=1e-8)
        np.testing.assert_array_equal(b.stable, a.stable)
        assert [e.kind for e in b.events] == [e.kind for e in a.events]


def test_a_triple_pendulums_flip_energy_is_its_light_rods():
    """The skewed triple's lowest way over the top: the third rod turned up with the others hanging, V = m3 g l3
    (a uniform rod's centre of mass rises by its length) -- the chain's search over the faces finds exactly it."""
    assert flip_energy(_triple()) == pytest.approx(0.5 * 9.81 * 0.3, rel=1e-9)


def test_a_triple_pendulums_third_family_against_simulate(mode3):
    """The third family of the skewed triple: from its linear mode's frequency (normal_modes) at low energy
    (the relative difference at the first orbit's amplitude, ~1e-4 of the energy, below 1e-4), every orbit
    closing after its period under ``simulate`` (DOP853 at 1e-12, another driver than the shooting's) to 1e-7,
    its energy kept; it loses stability at a branch point, where the largest multiplier's modulus crosses 1
    between a stable orbit and an unstable one; the unstable orbit's monodromy matrix equals central
    differences of ``simulate``'s flow along its unstable direction (1e-5)."""
    chain = _triple()
    fam = mode3
    assert fam.ok and fam.states.shape[1] == 6 and fam.multipliers.shape[1] == 6
    w_lin = skewpend.normal_modes(chain).frequencies[2]
    assert fam.linear_frequency == pytest.approx(w_lin, rel=1e-12)
    assert abs(fam.frequencies[0] - w_lin) / w_lin < 1e-4
    for k in (0, len(fam) // 2, len(fam) - 1):
        tr = skewpend.simulate(chain, fam.states[k], float(fam.periods[k]), dt_out=float(fam.periods[k]) / 50,
                               rtol=1e-12, atol=1e-12)
        assert np.abs(tr.y[-1] - fam.states[k]).max() < 1e-7
        assert np.ptp(tr.energy) < 1e-9 * max(1.0, np.abs(tr.energy).max())
    kinds = [e.kind for e in fam.events]
    assert kinds == ["branch point"], fam.events
    ev = fam.events[0]
    assert fam.stable[ev.index] and not fam.stable[ev.index + 1]
    assert fam.energies[ev.index] <= ev.energy <= fam.energies[ev.index + 1]
    k = len(fam) - 1
    mu, V = np.linalg.eig(fam.monodromies[k])
    j = int(np.argmax(np.abs(mu)))
    assert abs(mu[j]) > 2 and abs(mu[j].imag) < 1e-9
    v = np.real(V[:, j]) / np.linalg.norm(np.real(V[:, j]))
    h = 1e-6
    ends = [skewpend.simulate(chain, fam.states[k] + s * h * v, float(fam.periods[k]), rtol=1e-13, atol=1e-13).y[-1]
            for s in (1, -1)]
    np.testing.assert_allclose((ends[0] - ends[1]) / (2 * h), mu[j].real * v, rtol=0, atol=1e-5 * abs(mu[j]))


def test_a_chains_family_reads_back(mode3, tmp_path):
    back = skewpend.open_result(mode3.to_netcdf(tmp_path / "nnm.nc"))
    assert back.params == mode3.params and back.events == mode3.events
    np.testing.assert_array_equal(back.energies, mode3.energies)
    np.testing.assert_array_equal(back.stable, mode3.stable)
    assert "max |mu|" in back.table() and "nan" not in back.table()


def test_chain_families_refuse_in_one_line():
    with pytest.raises(ParameterError, match=r"mode must be .*1 to 3|mode must be a whole number from 1 to 3"):
        skewpend.nnm(_triple(), 4)
    with pytest.raises(ParameterError, match="a nonlinear normal mode"):
        skewpend.nnm(_triple().replace_link(2, damping=0.1), 1)


def test_the_cli_continues_a_chains_families(tmp_path):
    from helpers import run_cli

    config = tmp_path / "triple.toml"
    config.write_text('[chain]\ng = 9.81\n[[links]]\nlength = 0.5\nmass = 1.0\n[[links]]\nlength = 0.4\nmass = 0.8\n'
                      'axis = [0.5, 0, 1]\n[[links]]\nlength = 0.3\nmass = 0.5\naxis = [1, 0, 0]\n')
    ran = run_cli(["nnm", "--config", config, "--mode", "3", "--resolution", "12", "--out", tmp_path / "m3.nc"])
    assert ran.code == 0, ran.report()
    assert "mode 3: linear frequency 10.416" in ran.out and "branch point at E = " in ran.out
    assert skewpend.open_result(tmp_path / "m3.nc").mode == 3
    ran = run_cli(["nnm", "--config", config, "--mode", "4"])
    assert ran.code == 2 and "mode" in ran.err and len(ran.err.strip().splitlines()) == 1, ran.report()
