"""``skewpend orbit`` on a chain of links (issue 51): its help and messages name the options a chain takes
(--q0 --dq0, --mode 1 to n), and a chain's nonlinear normal mode at an energy is found (it was refused as
"the double pendulum's"): the orbit closes after its period when simulated, at the energy asked, near the
linear mode's frequency at a low energy."""

from __future__ import annotations

import math

import numpy as np

import skewpend
from helpers import run_cli
from skewpend.symbolic.chain import Chain

#: A skewed chain of two (a chain, not the double pendulum's Parameters: the chain's code path; two links keep
#: the continuation to a few seconds)
CHAIN = Chain.from_lists(2, length=[0.5, 0.4], mass=[1.0, 0.8], axis=[(0, 0, 1), (0.5, 0, 1)])


def test_a_chains_nonlinear_normal_mode_at_an_energy_closes_after_its_period():
    from skewpend.analysis.orbits import ORBIT_TOL, periodic_orbit

    energy = 0.005
    orbit = periodic_orbit(CHAIN, mode=2, energy=energy)
    assert orbit.ok, orbit.message
    y0 = np.asarray(orbit.state, float)
    tr = skewpend.simulate(CHAIN, y0, orbit.period, rtol=1e-12, atol=1e-12)
    # closes to the shooting's accuracy: the flow's tolerance (1e-12) over a few hundred steps, well below 1e-7
    assert np.max(np.abs(tr.final_state - y0)) < 1e-7 * max(1.0, np.max(np.abs(y0)))
    assert abs(tr.energy[0] - energy) <= 1e-9 * energy
    # at 0.005 J (amplitudes of a few degrees; the shift grows as the energy) the frequency is the linear mode's to well within a percent
    w = 2 * math.pi / orbit.period
    w_linear = skewpend.normal_modes(CHAIN).frequencies[1]
    assert abs(w / w_linear - 1) < 5e-3, (w, w_linear)
    assert ORBIT_TOL <= 1e-10


def test_orbit_on_a_chain_names_the_chains_options():
    ran = run_cli(["orbit", "--links", "3"])
    assert ran.code == 2 and "--q0 --dq0 and --period" in ran.err and "--phi0" not in ran.err, ran.report()
    ran = run_cli(["orbit", "--links", "3", "--mode", "1", "--energy", "0.05", "--q0", "0.1,0.1,0.1"])
    assert ran.code == 2 and "a guess (--q0 --dq0, --period, --rotation) goes without it" in ran.err, ran.report()
    ran = run_cli(["orbit", "--links", "3", "--mode", "4", "--energy", "0.05"])
    assert ran.code == 2 and "from 1 to 3" in ran.err and "double pendulum" not in ran.err, ran.report()
    ran = run_cli(["orbit", "--mode", "1"])  # the double pendulum's messages name its own options
    assert ran.code == 2 and "--energy" in ran.err, ran.report()
    ran = run_cli(["orbit"])
    assert ran.code == 2 and "--phi0 --psi0 --dphi0 --dpsi0 and --period" in ran.err, ran.report()


def test_orbit_help_says_what_a_chain_takes():
    ran = run_cli(["orbit", "--help"])
    text = " ".join(ran.out.split())
    assert "a chain's 1 to n" in text and "a chain's --q0 --dq0" in text and "one a link" in text, text
    assert "is the double pendulum's" not in text and "double pendulum only" not in text
