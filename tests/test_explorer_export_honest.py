"""The exported explorer of a run file (``skewpend serve --config run.toml --export DIR``, issue 51): the page
opens at the run's start angles and values from ``index.html`` alone (no printed query needed), an address
query still goes over them, and a damping between the slider's steps (0.005 on a 0.01 grid) is shown as the
value the physics runs (the parameter vector ``p`` the page integrates with), in Chromium from file://."""

from __future__ import annotations

import math

import pytest

from helpers import chromium, missing_browser, needs, run_cli

pytestmark = needs(missing_browser())

RUN = """
[parameters]
alpha = "35deg"
c1 = 0.005

[initial]
phi0 = "50deg"
psi0 = "-20deg"
"""


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    d = tmp_path_factory.mktemp("run-export")
    (d / "run.toml").write_text(RUN)
    ran = run_cli(["serve", "--config", str(d / "run.toml"), "--export", str(d / "site")])
    assert ran.code == 0, ran.report()
    return (d / "site" / "index.html").resolve().as_uri()


@pytest.fixture(scope="module")
def browser():
    with chromium() as b:
        yield b


def _open(browser, url):
    page = browser.new_page(viewport={"width": 1400, "height": 950})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(url)
    page.wait_for_function("() => window.explorer && window.explorer.state().frames >= 1", timeout=30000)
    return page, errors


def test_the_export_opens_at_the_run_files_start_and_shows_the_damping_it_runs(browser, site, tmp_path):
    page, errors = _open(browser, site)  # no query in the address
    state = page.evaluate("() => window.explorer.state()")
    assert state["values"]["phi0"] == pytest.approx(50.0) and state["values"]["psi0"] == pytest.approx(-20.0)
    assert state["values"]["alpha"] == pytest.approx(35.0)
    assert state["values"]["c1"] == pytest.approx(0.005)
    shown = page.locator("#s-c1-out").inner_text()
    assert shown.split()[0] == "0.005", shown  # was "0.01": the slider's step, not the value
    assert 0.005 in [round(v, 12) for v in state["p"]], state["p"]  # the physics runs 0.005
    page.locator("#sliders").screenshot(path=str(tmp_path / "sliders.png"))
    assert errors == []
    page.close()
    page, errors = _open(browser, site + "?phi0=10")  # the address's own query goes over the run's start
    values = page.evaluate("() => window.explorer.state().values")
    assert values["phi0"] == pytest.approx(10.0) and values["psi0"] == pytest.approx(-20.0)
    assert errors == []
    page.close()
    assert math.isfinite(values["c1"])


#: A double pendulum with what the page's sliders do not set, as a run file gives it (every body value given: the
#: library's model below is the same): damping, Coulomb friction and rotors (the recursive form's physics, a
#: chain's page), or a constant torque (the derivation's, the torque in its parameter vector).
BODIES = 'a = 0.5\nb = 0.4\nm1 = 1.0\nm2 = 0.7\nalpha = "20deg"\ng = 9.81\n'
LOSSES = {"friction and rotors": "c1 = 0.01\ncf1 = 0.05\ncf2 = 0.02\nIr = 0.001\ngr = 2.0\n",
          "a constant torque": "c2 = 0.02\ntau1 = 0.2\n"}


@pytest.mark.slow  # 8-14 s each: the export (the recursive form's code printed) and a page in software WebGL
@pytest.mark.parametrize("case", list(LOSSES), ids=["friction-rotors", "torque"])
def test_a_double_pendulum_with_friction_rotors_or_torques_runs_them(browser, tmp_path, case):
    """``serve --config --export`` of the double pendulum with Coulomb friction and rotors, or with a constant
    torque: the page opens, draws and moves, its motion is the library's (DOP853's, to the page's RK4 error), and
    its generated physics stepped by RK4 at 1 ms is the compiled RK4's (to rounding); with friction and rotors its modes are
    ``normal_modes``' (the rotors' inertia in M0), with a torque the page says why there are none."""
    import numpy as np

    import skewpend

    (tmp_path / "run.toml").write_text(f"[parameters]\n{BODIES}{LOSSES[case]}\n[initial]\nphi0 = \"60deg\"\npsi0 = 0\n")
    ran = run_cli(["serve", "--config", str(tmp_path / "run.toml"), "--export", str(tmp_path / "site")])
    assert ran.code == 0, ran.report()
    values = dict(line.split(" = ") for line in (BODIES + LOSSES[case]).splitlines())
    model = skewpend.Parameters(**{k: math.radians(20) if k == "alpha" else float(v) for k, v in values.items()})
    page, errors = _open(browser, (tmp_path / "site" / "index.html").resolve().as_uri())
    page.wait_for_function("() => window.explorer.state().frames >= 3", timeout=30000)
    sliders = sorted(k for k in page.evaluate("() => window.explorer.state().values"))
    recursive = case == "friction and rotors"
    assert sliders == (["c1", "c2", "g", "phi0", "psi0"] if recursive else ["a", "alpha", "b", "c1", "c2", "g", "m1", "m2",
                                                                            "phi0", "psi0"]), sliders
    png = page.locator("#scene").screenshot()
    page.click("#reset")  # from the start, now
    page.wait_for_function("() => window.explorer.state().t > 0.5", timeout=60000)
    page.click("#play")
    page.wait_for_function("() => !window.explorer.state().running")
    s = page.evaluate("() => window.explorer.state()")
    assert png != page.locator("#scene").screenshot()  # it moved
    y0 = [math.radians(60.0), 0.0, 0.0, 0.0]
    # the live motion (RK4, steps of at most 1 ms, a frame's last one shorter) is the library's to RK4's error
    exact = skewpend.simulate(model, y0, s["t"], rtol=1e-12, atol=1e-12)
    assert np.abs(np.array(s["y"]) - exact.y[-1]).max() < 1e-4
    assert abs(np.array(s["y"]) - y0).max() > 0.3  # a swing, not a rest
    # the page's physics (its generated rhs at the page's p) stepped 600 times by 1 ms is the compiled RK4's
    stepped = page.evaluate("""(y) => { const ph = window.explorer.physics, p = window.explorer.state().p, h = 1e-3;
        const at = (a, k, c) => a.map((v, i) => v + c * k[i]);
        for (let i = 0; i < 600; i++) {
          const k1 = ph.rhs(y, p), k2 = ph.rhs(at(y, k1, h / 2), p), k3 = ph.rhs(at(y, k2, h / 2), p), k4 = ph.rhs(at(y, k3, h), p);
          y = y.map((v, j) => v + h / 6 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]));
        }
        return y; }""", y0)
    rk4 = skewpend.simulate(model, y0, 0.6, method="rk4", dt=1e-3)
    assert np.abs(np.array(stepped) - rk4.y[-1]).max() < 1e-9
    modes = page.locator("#modes").inner_text()
    if recursive:
        js, lib = page.evaluate("() => window.explorer.modes()"), skewpend.normal_modes(model)
        np.testing.assert_allclose(js["frequencies"], lib.frequencies, rtol=1e-9)
        rotorless = skewpend.normal_modes(model.replace(Ir=0.0)).frequencies
        assert np.abs(lib.frequencies - rotorless).max() > 1e-3 * lib.frequencies.max()  # the rotors are in it
    else:
        assert "the hanging position is not an equilibrium" in modes, modes
    assert errors == []
    page.close()
