"""The rotary (Furuta) pendulum in the browser views (issue 54, item 4), in Debian's Chromium (Playwright, WebGL by
SwiftShader): ``examples/qube_servo2.toml``'s arm turns about the vertical and runs along its body's ``i``.

* The explorer (``skewpend serve --config examples/qube_servo2.toml --export``; the motor at 0 V, its back-EMF in
  joint 1's damping): the drawn arm runs from hinge 1 to the pendulum's hinge, horizontal and ``Lr`` from the
  vertical axis, the pendulum from there to its rod's end -- the library's kinematics at the page's state
  (1e-9 m; the rig, 0.214 m, drawn magnified: the scene's scale undone) --, the arm's and the pendulum's colours
  on screen where the page says they are; the equations' K0 typeset (the arm's row and column zero).
* The report's live view (``web/replay.js``, its data from :func:`skewpend.views.frontend.replay_data`): each
  frame's drawn links are the library's hinges and tip.
No console error, no request leaving the page."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest

import skewpend
from helpers import chromium, missing_browser, needs, run_cli

pytestmark = needs(missing_browser())

ROOT = Path(__file__).resolve().parents[1]
RUN_FILE = ROOT / "examples" / "qube_servo2.toml"
Lr, Lp = 0.085, 0.129
ARM_RGB, PENDULUM_RGB = (0x4F, 0x8F, 0xE8), (0xE8, 0x86, 0x4F)  # scene.js's rods: the first blue, the last orange


def _chain():
    from skewpend.config import Run

    return Run("serve", str(RUN_FILE)).chain()


@pytest.fixture(scope="module")
def browser():
    with chromium() as b:
        yield b


def _page(browser, url: str):
    page = browser.new_page(viewport={"width": 1400, "height": 950})
    problems, blocked = [], []
    page.on("console", lambda m: problems.append(m.text) if m.type in ("error", "warning") else None)
    page.on("pageerror", lambda e: problems.append(str(e)))
    page.route("**/*", lambda r: r.continue_() if r.request.url.startswith(("file:", "data:", "blob:"))
               else (blocked.append(r.request.url), r.abort()))
    page.goto(url)
    return page, problems, blocked


def _hue_near(image: np.ndarray, x: float, y: float, rgb, reach: int = 3) -> float:
    """The best match (cosine of the colours as unit vectors: shading scales a colour) near page pixel (x, y)."""
    patch = image[int(round(y)) - reach:int(round(y)) + reach + 1, int(round(x)) - reach:int(round(x)) + reach + 1]
    patch = patch.reshape(-1, 3).astype(float)
    base = np.asarray(rgb, dtype=float) / np.linalg.norm(rgb)
    return float(np.max(patch @ base / np.maximum(np.linalg.norm(patch, axis=1), 1e-9)))


@pytest.mark.slow
def test_the_explorer_draws_the_arm_horizontal_and_the_pendulum_from_its_end(browser, tmp_path):
    from PIL import Image

    from skewpend.numeric.recursive import hinge_positions

    folder = tmp_path / "site"
    ran = run_cli(["serve", "--config", RUN_FILE, "--export", folder])
    assert ran.code == 0, ran.report()
    assert sum("skewpend serve applies 0 V" in line for line in ran.err.splitlines()) == 1, ran.report()
    page, problems, blocked = _page(browser, (folder / "index.html").resolve().as_uri() + "?phi0=20&psi0=30")
    try:
        page.wait_for_function("() => window.explorer && window.explorer.state().t > 0.3", timeout=60000)
        page.click("#play")  # pause
        page.wait_for_function("() => !window.explorer.state().running")
        state = page.evaluate("() => window.explorer.state()")
        G = page.evaluate("() => window.explorer.geometry()")
        chain = _chain()
        assert G["scale"] == pytest.approx(0.9 / (Lr + Lp), rel=1e-12)  # scene.js's MIN_REACH over the rig's reach
        back = lambda v: np.array([v[0], -v[1], v[2]]) / G["scale"]  # noqa: E731  three.js -> the model's frame [m]
        y = np.array(state["y"])
        hinges = hinge_positions(chain, y[:2])
        tip = skewpend.simulate(chain, y, 1e-3, dt_out=1e-3).tips()[0, 3:6]
        np.testing.assert_allclose([back(v) for v in G["pivots"]], hinges, rtol=0, atol=1e-9)
        np.testing.assert_allclose(back(G["tips"][0]), hinges[1], rtol=0, atol=1e-9)
        np.testing.assert_allclose(back(G["tips"][1]), tip, rtol=0, atol=1e-9)
        arm = back(G["tips"][0])
        assert abs(arm[1]) < 1e-12 and np.hypot(arm[0], arm[2]) == pytest.approx(Lr, rel=1e-9)  # horizontal, Lr out
        assert np.linalg.norm(back(G["tips"][1]) - arm) == pytest.approx(Lp, rel=1e-9)
        # the pixels: each rod's colour where the page says it is drawn, the pendulum's tip below the arm
        shot = np.asarray(Image.open(io.BytesIO(page.screenshot())).convert("RGB"))
        at = {name: page.evaluate(f"() => window.explorer.screenOf('{name}')") for name in ("rod1", "rod2", "joint", "tip")}
        assert _hue_near(shot, at["rod1"]["x"], at["rod1"]["y"], ARM_RGB) > 0.99
        assert _hue_near(shot, at["rod2"]["x"], at["rod2"]["y"], PENDULUM_RGB) > 0.99
        assert at["tip"]["y"] > at["joint"]["y"] + 100  # [px]: magnified, the 12.9 cm pendulum is long on screen
        equations = page.evaluate("() => window.explorer.equations().latex")
        assert "K_0 = \\begin{pmatrix}0 & 0 \\\\ 0 & " in equations
        assert page.evaluate("document.querySelectorAll('.katex-error').length") == 0
        modes = page.evaluate("() => document.getElementById('modes').textContent")
        assert "φ moves no weight (K0's row and column of it are zero)" in modes, modes
        assert problems == [] and blocked == []
    finally:
        page.close()


@pytest.mark.slow
def test_the_reports_live_view_replays_the_rig_as_the_library_draws_it(browser, tmp_path):
    """The report's live view on its own page (the report's own HTML of it and its scripts)."""
    from skewpend.views.drawing import link_points
    from skewpend.views.frontend import inline_page_scripts, replay_data
    from skewpend.views.report.common import live_view_html

    chain = _chain()
    tr = skewpend.simulate(chain, [0.3, 0.9, 4.0, 0.0], 1.0, dt_out=1 / 15, method="dop853")
    data = replay_data(tr)
    page_file = tmp_path / "live.html"
    page_file.write_text("<!doctype html><html><head><meta charset='utf-8'></head><body>"
                         + live_view_html(data, "the rotary pendulum", None, (480, 360)) + inline_page_scripts()
                         + "</body></html>", encoding="utf-8")
    page, problems, blocked = _page(browser, page_file.resolve().as_uri())
    try:
        page.wait_for_function("window.skewpendReplay && window.skewpendReplay.views.length === 1 && "
                               "window.skewpendReplay.views[0].state().renders > 2", timeout=30000)
        points = link_points(chain, tr.y, tr.tips())
        for k in range(0, tr.t.size, 5):
            drawn = page.evaluate(f"window.skewpendReplay.views[0].show({k})")
            np.testing.assert_allclose(np.reshape(drawn["pivots"], (2, 3)), points[k, :2], rtol=0, atol=1e-12)
            np.testing.assert_allclose(np.reshape(drawn["tips"], (2, 3)), points[k, 1:], rtol=0, atol=1e-12)
            assert abs(drawn["tips"][1]) < 1e-12  # the arm's end at hinge 1's height
        png = page.locator("figure.live-view canvas").screenshot()
        from PIL import Image

        pixels = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)
        hue = pixels.reshape(-1, 3) / np.maximum(np.linalg.norm(pixels.reshape(-1, 3), axis=1), 1e-9)[:, None]
        for rgb in (ARM_RGB, PENDULUM_RGB):  # both rods on screen, a few hundred pixels each at least
            assert np.count_nonzero(hue @ (np.asarray(rgb) / np.linalg.norm(rgb)) > 0.995) > 200
        assert problems == [] and blocked == []
    finally:
        page.close()
