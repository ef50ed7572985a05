"""Coulomb friction in the linear analyses (issue 36, item 6): non-smooth at rest, so the modes, the
equilibria and derive --linear leave it out by default and say so; ``coulomb="smoothed"`` linearises
its smoothed form ``cf atan(cfs q')``, whose slope at rest is a viscous damping ``cfs cf``.

The references are independent constructions: the same model without friction (what "excluded"
must equal, matrix for matrix), and the same model with the slope written as viscous damping
``c + cfs cf`` and no friction (what "smoothed" must equal)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import skewpend
from skewpend import ParameterError, Parameters

from helpers import run_cli

BASE = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
CF = dict(cf1=0.05, cf2=0.03, cfs=100.0)
FRICTION = BASE.replace(**CF)
VISCOUS = BASE.replace(c1=CF["cfs"] * CF["cf1"], c2=CF["cfs"] * CF["cf2"])  # the smoothed slope as viscous damping


def test_coulomb_friction_alone_leaves_the_modes_undamped_by_default():
    m, plain = skewpend.normal_modes(FRICTION), skewpend.normal_modes(BASE)
    assert m.coulomb == "exclude" and not m.damped
    np.testing.assert_array_equal(m.damping_ratios, [0.0, 0.0])
    # cf enters neither M0 nor K0: the same matrices, so the same frequencies and shapes to rounding
    np.testing.assert_allclose(m.frequencies, plain.frequencies, rtol=1e-14)
    np.testing.assert_allclose(m.shapes, plain.shapes, rtol=1e-13, atol=1e-15)
    np.testing.assert_array_equal(m.C, np.zeros((2, 2)))


def test_smoothed_is_the_slope_as_viscous_damping():
    """The option reproduces the old linearisation: C0 = diag(c + cfs cf) (here overdamped mode 2)."""
    s, v = skewpend.normal_modes(FRICTION, coulomb="smoothed"), skewpend.normal_modes(VISCOUS)
    np.testing.assert_allclose(s.C, np.diag([5.0, 3.0]), rtol=1e-15)
    np.testing.assert_allclose(s.damping_ratios, v.damping_ratios, rtol=1e-12)
    np.testing.assert_allclose(s.eigenvalue_pairs, v.eigenvalue_pairs, rtol=1e-12)
    assert s.overdamped.tolist() == v.overdamped.tolist() and s.damping_ratios[1] > 1


def test_the_summary_and_the_result_say_what_was_done():
    m = skewpend.normal_modes(FRICTION)
    line = m.summary().splitlines()[0]
    assert "Coulomb friction cf1, cf2 excluded from the linearisation" in line
    assert "cfs*cf = 5, 3 N m s" in line and "coulomb='smoothed'" in line
    assert m.settings["coulomb"] == "exclude" and m.to_dict()["coulomb_note"] == m.coulomb_note
    s = skewpend.normal_modes(FRICTION, coulomb="smoothed")
    assert "linearised by its smoothed slope" in s.message
    only_one = skewpend.normal_modes(BASE.replace(cf2=0.02))
    assert "Coulomb friction cf2 excluded" in only_one.message and "cfs*cf = 2 N m s" in only_one.message
    plain = skewpend.normal_modes(BASE)
    assert plain.coulomb_note == "" and "Coulomb" not in plain.summary() and "coulomb" not in plain.settings


def test_every_linearisation_agrees():
    """Equilibria (each point's C and growth rates), the modes about another equilibrium and the
    symbolic linearisation treat the friction alike; a controller's linearisation takes the slope by
    default (its region is certified on the smooth model that is simulated)."""
    ex, plain = skewpend.equilibria(FRICTION), skewpend.equilibria(BASE)
    assert "Coulomb friction cf1, cf2 excluded" in ex.message and ex.coulomb == "exclude"
    for e, p in zip(ex, plain):
        assert e.label == p.label
        np.testing.assert_array_equal(e.C, np.zeros((2, 2)))
        np.testing.assert_allclose(e.growth_rates, p.growth_rates, rtol=1e-12)
    sm, visc = skewpend.equilibria(FRICTION, coulomb="smoothed"), skewpend.equilibria(VISCOUS)
    for e, v in zip(sm, visc):
        np.testing.assert_allclose(e.C, v.C, rtol=1e-15)
        np.testing.assert_allclose(e.growth_rates, v.growth_rates, rtol=1e-10)
    up = skewpend.normal_modes(FRICTION, about="up-down")
    np.testing.assert_allclose(up.growth_rates, skewpend.normal_modes(BASE, about="up-down").growth_rates, rtol=1e-12)
    # an Equilibrium made with the other choice is linearised again
    again = skewpend.normal_modes(FRICTION, about=sm.find("up-down"))
    np.testing.assert_array_equal(again.C, np.zeros((2, 2)))
    lin = skewpend.derive(FRICTION).linearize()
    np.testing.assert_array_equal(np.array(lin.C, dtype=float), np.zeros((2, 2)))
    np.testing.assert_allclose(np.array(lin.M, dtype=float), skewpend.normal_modes(FRICTION).M, rtol=1e-14)
    # control: the slope by default, the exclusion on request
    for coulomb, reference in (("smoothed", VISCOUS), ("exclude", BASE)):
        kw = {} if coulomb == "smoothed" else {"coulomb": coulomb}
        L = skewpend.linearization(FRICTION, "up-up", **kw)
        np.testing.assert_allclose(L.A, skewpend.linearization(reference, "up-up").A, rtol=1e-12, atol=1e-12)
        assert L.coulomb == coulomb and "Coulomb friction cf1, cf2" in L.coulomb_note


def test_a_bad_choice_is_one_line():
    for call in (lambda: skewpend.normal_modes(FRICTION, coulomb="linear"),
                 lambda: skewpend.equilibria(FRICTION, coulomb=None),
                 lambda: skewpend.derive(FRICTION).linearize(coulomb="yes"),
                 lambda: skewpend.linearization(FRICTION, coulomb=1)):
        with pytest.raises(ParameterError, match="'exclude' .* or 'smoothed'") as info:
            call()
        assert "\n" not in str(info.value)


def test_nonlinear_check_refuses_coulomb_friction():
    """Undamped modes by default, but the nonlinear motion has the friction: the check refuses it."""
    from skewpend.analysis.modes import check_nonlinear

    with pytest.raises(ParameterError, match="without losses .* but cf1 = 0.05, cf2 = 0.03; set cf1, cf2 to 0"):
        check_nonlinear(FRICTION, 0.1)


# -- the command line -------------------------------------------------------------------------------
RUN = "[parameters]\na = 1.0\nb = 0.8\nm1 = 1.0\nm2 = 0.7\nalpha = 0.6\ng = 9.81\ncf1 = 0.05\ncf2 = 0.03\n"


def test_modes_cli_states_the_exclusion_and_takes_the_smoothed_slope(tmp_path):
    (tmp_path / "f.toml").write_text(RUN)
    ran = run_cli(["modes", "--config", "f.toml"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    assert "Coulomb friction cf1, cf2 excluded from the linearisation" in ran.out
    assert "--coulomb smoothed includes it" in ran.out and "with damping" not in ran.out
    ran = run_cli(["modes", "--config", "f.toml", "--coulomb", "smoothed", "--format", "json"], cwd=tmp_path)
    data = json.loads(ran.out)
    np.testing.assert_allclose(data["damping_ratios"], skewpend.normal_modes(VISCOUS).damping_ratios, rtol=1e-12)
    assert data["coulomb"] == "smoothed" and "smoothed slope" in data["coulomb_note"]
    ran = run_cli(["modes", "--config", "f.toml", "--coulomb", "smoothed", "--sweep", "alpha=0:1:3"], cwd=tmp_path)
    assert ran.code == 2 and "--coulomb" in ran.err and "no effect" in ran.err, ran.report()


def test_plain_modes_of_a_model_off_its_axis_is_about_its_hanging_rest(tmp_path):
    """A fitted model's centres of mass sit a little off the rods' lines: phi = psi = 0 is no
    equilibrium, and plain `modes` takes the modes about its rest, as --about down-down does."""
    params = BASE.replace(alpha=0.0, com1=(0.002, 0.5, 0.0), com2=(-0.001, 0.4, 0.0))
    (tmp_path / "fit.toml").write_text(
        "[parameters]\na = 1.0\nb = 0.8\nm1 = 1.0\nm2 = 0.7\nalpha = 0.0\ng = 9.81\n"
        "com1 = [0.002, 0.5, 0.0]\ncom2 = [-0.001, 0.4, 0.0]\n")
    ran = run_cli(["modes", "--config", "fit.toml"], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    assert ran.out.startswith("Normal modes about the hanging rest (down-down) at phi = ")
    assert "phi = psi = 0 is no equilibrium of this model" in ran.out
    rest = skewpend.normal_modes(params, about="down-down")
    assert f"{rest.frequencies[0]:14.8g}" in ran.out and f"{rest.frequencies[1]:14.8g}" in ran.out
    data = json.loads(run_cli(["modes", "--config", "fit.toml", "-f", "json"], cwd=tmp_path).out)
    assert data["about"] == "down-down" and np.allclose(data["equilibrium"], rest.equilibrium, rtol=0, atol=1e-15)
    with pytest.raises(skewpend.EquilibriumError, match="about='down-down'"):  # the library keeps q = 0 exact
        skewpend.normal_modes(params)


def test_derive_reads_its_run_file(tmp_path):
    (tmp_path / "f.toml").write_text(RUN)
    text = run_cli(["derive", "--config", "f.toml", "--linear"], cwd=tmp_path)
    assert text.code == 0, text.report()
    assert "Coulomb friction cf1, cf2 excluded from the linearisation" in text.out
    data = json.loads(run_cli(["derive", "--config", "f.toml", "--linear", "--coulomb", "smoothed", "-f", "json"],
                              cwd=tmp_path).out)
    assert data["values"]["cf1"] == 0.05 and data["values"]["a"] == 1.0
    assert data["linearized"]["C"] == [["5", "0"], ["0", "3"]] and data["linearized"]["coulomb"] == "smoothed"
    # options override the run file, as everywhere
    data = json.loads(run_cli(["derive", "--config", "f.toml", "--a", "2", "-f", "json"], cwd=tmp_path).out)
    assert data["values"]["a"] == 2.0


def test_serve_takes_the_run_files_model_and_start(tmp_path, monkeypatch):
    pytest.importorskip("fastapi")
    from skewpend.views import explorer

    started = []
    monkeypatch.setattr(explorer, "serve", lambda *a, **kw: started.append(kw))
    (tmp_path / "s.toml").write_text('[parameters]\na = 1.2\nalpha = "40deg"\ncom2 = [0.0, 0.3, 0.0]\n'
                                     '[initial]\nphi0 = "30deg"\n')
    import socket

    with socket.socket() as free:
        free.bind(("127.0.0.1", 0))
        port = free.getsockname()[1]
    ran = run_cli(["serve", "--config", "s.toml", "--port", str(port)], cwd=tmp_path)
    assert ran.code == 0, ran.report()
    assert "?alpha=40.0&a=1.2&phi0=30.0 (Ctrl-C to stop)" in ran.err
    assert started and started[0]["physics_params"].com2 == (0.0, 0.3, 0.0)
    site = run_cli(["serve", "--config", "s.toml", "--export", "site"], cwd=tmp_path)
    assert site.code == 0 and "index.html?alpha=40.0&a=1.2&phi0=30.0" in site.err, site.report()
