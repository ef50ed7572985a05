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
