"""The explorer of a chain of links as a person uses it, served and static, in Debian's Chromium (Playwright,
WebGL by SwiftShader): a skewed, damped triple pendulum (``skewpend serve --config`` with ``[[links]]``, and
``--export``), every test on both, each claim checked against the library computing on its own:

* the canvas shows a drawing, of three rods: the drawn rod ends and hinge axes are ``simulate``'s at the
  page's state (1e-9), and the page's live motion (the chain's generated JavaScript, RK4) is the compiled
  DOP853 run from the page's start (1e-7);
* the normal modes shown are ``normal_modes(chain)``'s, and after the g slider moves ``normal_modes`` of the
  chain with that g (the page computes them from its generated M0 and K0: the library recomputes them);
* the linearised equations are typeset (KaTeX, no error) with K0 at the slider's g;
* the flip map computed in the page's workers equals ``flip_map(chain)``'s over (q1, q2) (same outcome and
  joint in every cell, flip times within 1e-3 s on 99 % of the cells that flip); a cell's click starts there;
* dragging rod 3 turns joint 3's start alone; the address holds the start and gives it back;
* no console error, no request leaving the site.
"""

from __future__ import annotations

import io
import math
import threading
import time
from pathlib import Path
from urllib.parse import urlparse

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("uvicorn")

import skewpend  # noqa: E402
from helpers import artifacts, chromium, example_model, missing_browser, needs, run_cli  # noqa: E402

pytestmark = needs(missing_browser())

#: The skewed triple of examples/skewed_triple.toml, started at its [initial] q0 (the page starts at rest).
TRIPLE = example_model() + '\n[initial]\nq0 = ["60deg", -0.3, 0.2]\n'
Q0 = (np.radians(60.0), -0.3, 0.2)


def _chain():
    from skewpend.symbolic.chain import Chain

    return Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], axis=[(0, 0, 1), (0.5, 0, 1), (1, 0, 0)],
                            damping=[0.0, 0.0, 0.01])


@pytest.fixture(scope="module")
def run_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("chain-run") / "triple.toml"
    path.write_text(TRIPLE, encoding="utf-8")
    return path


@pytest.fixture(scope="module", params=["served", "static"])
def site(request, run_file, tmp_path_factory):
    """The page's address with the run file's start: the real server's (``explorer.serve`` with the chain's
    physics), or the export the command line writes (``skewpend serve --config ... --export``)."""
    if request.param == "static":
        folder = tmp_path_factory.mktemp("chain-static") / "site"
        ran = run_cli(["serve", "--config", str(run_file), "--export", str(folder)])
        assert ran.code == 0, ran.report()
        query = ran.err.split("(open index.html?", 1)[1].split(" ", 1)[0]
        yield (folder / "index.html").resolve().as_uri(), query
        return
    from urllib.parse import urlencode

    from skewpend.views import explorer

    query = urlencode({f"q{k}_0": repr(float(np.degrees(q))) for k, q in enumerate(Q0, start=1)})
    started, stop = [], threading.Event()
    thread = threading.Thread(target=explorer.serve, args=("127.0.0.1", 0), daemon=True,
                              kwargs={"ready": started.append, "stop": stop, "physics_params": _chain()})
    thread.start()
    deadline = time.time() + 60
    while not started:
        assert time.time() < deadline and thread.is_alive(), "the server did not start"
        time.sleep(0.05)
    yield started[0].url, query
    stop.set()
    thread.join(timeout=10)


@pytest.fixture(scope="module")
def browser():
    with chromium() as b:
        yield b


class Page:
    """The page at ``url?query``, what it logged and what it asked for elsewhere (blocked)."""

    def __init__(self, browser, url: str, query: str):
        self.url = url
        self.page = browser.new_page(viewport={"width": 1400, "height": 950})
        self.console, self.blocked = [], []
        self.page.on("console", lambda m: self.console.append((m.type, m.text)))
        self.page.on("pageerror", lambda e: self.console.append(("pageerror", str(e))))
        self.page.route("**/*", self._route)
        self.page.goto(f"{url}?{query}")
        self.page.wait_for_function("() => window.explorer && window.explorer.state().frames >= 4", timeout=60000)

    def _route(self, r):
        u = r.request.url
        if u.startswith(("data:", "blob:")) or (u.startswith(self.url.rsplit("/", 1)[0] + "/") if self.url.startswith("file:")
                                                 else urlparse(u).netloc == urlparse(self.url).netloc):
            r.continue_()
        else:
            self.blocked.append(u)
            r.abort()

    def state(self):
        return self.page.evaluate("() => window.explorer.state()")

    def pause(self):
        if self.state()["running"]:
            self.page.click("#play")
        self.page.wait_for_function("() => !window.explorer.state().running")

    def slider(self, key: str, value: float):
        self.page.locator(f"#s-{key}").fill(str(value))

    def errors(self):
        return [m for m in self.console if m[0] in ("error", "warning", "pageerror")]


@pytest.fixture(scope="module")
def opened(browser, site):
    p = Page(browser, *site)
    yield p
    p.page.close()


def _canvas_std(p: Page) -> float:
    from PIL import Image

    png = p.page.locator("#scene").screenshot()
    return float(np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float).std())


def _back(v):  # three.js (y up) -> the model's frame (j down)
    return [v[0], -v[1], v[2]]


def test_three_rods_drawn_where_the_library_puts_them_moving_as_it_computes(opened):
    chain = _chain()
    assert opened.page.evaluate("() => window.explorer.n") == 3
    assert [opened.page.locator(f"#s-{k}").count() for k in ("q1_0", "q2_0", "q3_0", "g", "c1", "c2", "c3")] == [1] * 7
    assert opened.page.locator("#s-alpha").count() == 0 and opened.page.locator("#s-phi0").count() == 0
    assert _canvas_std(opened) > 8.0
    opened.page.click("#reset")  # from the start, now
    opened.page.wait_for_function("() => window.explorer.state().t > 0.6", timeout=60000)
    opened.pause()
    s = opened.state()
    assert len(s["y"]) == 6 and s["values"]["q1_0"] == pytest.approx(60.0)
    y0 = np.radians([s["values"][f"q{k}_0"] for k in (1, 2, 3)]).tolist() + [0.0] * 3
    np.testing.assert_allclose(y0[:3], Q0, atol=1e-12)  # the run file's start, through the address
    tr = skewpend.simulate(chain, y0, s["t"], rtol=1e-12, atol=1e-12)
    assert np.max(np.abs(np.array(s["y"]) - tr.y[-1])) < 1e-7  # RK4 at <= 1 ms against DOP853 at 1e-12
    G = opened.page.evaluate("() => window.explorer.geometry()")
    at = skewpend.simulate(chain, s["y"], 1e-3, dt_out=1e-3)
    assert len(G["tips"]) == 3
    np.testing.assert_allclose(sum((_back(v) for v in G["tips"]), []), at.tips()[0], atol=1e-9)
    np.testing.assert_allclose(sum((_back(v) for v in G["axes"]), []), at.axes()[0], atol=1e-9)
    assert opened.errors() == [] and opened.blocked == []


def test_the_modes_are_the_library_s_at_the_slider_s_g(opened):
    from dataclasses import replace

    chain = _chain()
    for g in (9.81, 4.0):
        if g != 9.81:
            opened.slider("g", g)
            opened.page.wait_for_function(f"() => window.explorer.state().values.g === {g} && "
                                          "!document.querySelector('#equations').classList.contains('stale')", timeout=30000)
        js = opened.page.evaluate("() => window.explorer.modes()")
        lib = skewpend.normal_modes(replace(chain, g=g))  # computed again, at this g
        np.testing.assert_allclose(js["frequencies"], lib.frequencies, rtol=1e-9)
        for k in range(3):  # the same shapes (up to sign)
            a, b = np.array(js["shapes"][k]), lib.shapes[:, k]
            assert min(np.abs(a - b).max(), np.abs(a + b).max()) < 1e-9
        assert opened.page.locator("#modes li").count() == 3
        latex = opened.page.evaluate("() => window.explorer.equations().latex")
        assert "M_0" in latex and f"{lib.K[0, 0]:.4g}" in latex  # K0 at this g, rounded to 4 digits
    assert opened.page.locator("#equations .katex").count() == 1 and opened.page.locator("#equations .katex-error").count() == 0
    opened.slider("g", 9.81)
    # a mode's button starts along that mode's shape, the largest angle 10 degrees
    opened.page.locator("#modes li button").nth(2).click()
    s = opened.state()
    q = np.radians([s["values"][f"q{k}_0"] for k in (1, 2, 3)])
    shape = skewpend.normal_modes(chain).shapes[:, 2]
    np.testing.assert_allclose(q / np.abs(q).max(), shape / shape[np.abs(shape).argmax()], atol=1e-12)
    assert np.abs(q).max() == pytest.approx(np.radians(10.0), rel=1e-12)
    assert opened.errors() == []


def test_the_flip_map_is_the_library_s_and_a_click_starts_there(opened):
    chain = _chain()
    opened.page.locator("#flipmap").scroll_into_view_if_needed()  # computed once shown
    opened.page.wait_for_function("() => window.explorer.flip() !== null", timeout=180000)
    js = opened.page.evaluate("() => window.explorer.flip()")
    assert js["plane"] == ["q1_0", "q2_0"] and js["failed"] == 0
    lib = skewpend.flip_map(chain, js["n"], t_end=js["t_end"])
    np.testing.assert_array_equal(np.array(js["phi0"]), lib.x0)
    np.testing.assert_array_equal(np.array(js["psi0"]), lib.y0)
    t_js = np.array([[np.nan if v is None else v for v in row] for row in js["flip_time"]])
    np.testing.assert_array_equal(np.isnan(t_js), np.isnan(lib.flip_time))
    which = np.array(js["which"])
    np.testing.assert_array_equal(which, lib.which)  # the angle's index, -1 none: the page's as the library's
    flips = ~np.isnan(t_js)
    assert 0.2 < flips.mean() < 1.0  # a map with flips and without
    assert (np.abs(t_js - lib.flip_time)[flips] <= 1e-3).mean() >= 0.99
    # a cell's click: q1, q2 its centre, q3 at 0 (the map's), running
    box = opened.page.locator("#flipmap").bounding_box()
    n = js["n"]
    i, j = 5, 20
    opened.page.mouse.click(box["x"] + (i + 0.5) * box["width"] / n, box["y"] + box["height"] - (j + 0.5) * box["height"] / n)
    v = opened.state()["values"]
    assert (v["q1_0"], v["q2_0"], v["q3_0"]) == (pytest.approx(np.degrees(lib.x0[i]), abs=1e-9),
                                                 pytest.approx(np.degrees(lib.y0[j]), abs=1e-9), 0)
    assert opened.state()["running"]
    opened.page.screenshot(path=str(artifacts("explorer") / f"chain-explorer-{'static' if opened.url.startswith('file:') else 'served'}.png"))
    assert opened.errors() == [] and opened.blocked == []


def test_dragging_rod_3_turns_joint_3_and_the_address_gives_the_start_back(browser, site):
    # a page of its own at the run file's start (the tests before move the start about), paused at its start:
    # a drag turns the rod as drawn, wherever the motion had got to
    opened = Page(browser, *site)
    try:
        _drag_rod_3(opened, browser, site)
    finally:
        opened.page.close()


def _drag_rod_3(opened, browser, site):
    opened.pause()
    opened.page.click("#reset")
    opened.page.evaluate("() => document.querySelector('#scene').scrollIntoView()")
    before = opened.state()["values"]
    # pointer from 60 % along rod 3 to 80 px across it on the screen: the rod follows the pointer about its hinge
    start = opened.page.evaluate("() => window.explorer.screenOf('rod3')")
    pivot = opened.page.evaluate("() => window.explorer.screenOf('hinge3')")
    along = np.array([start["x"] - pivot["x"], start["y"] - pivot["y"]])
    across = np.array([-along[1], along[0]]) / np.hypot(*along)
    opened.page.mouse.move(start["x"], start["y"])
    opened.page.mouse.down()
    opened.page.mouse.move(start["x"] + 80 * across[0], start["y"] + 80 * across[1], steps=8)
    opened.page.mouse.up()
    after = opened.state()["values"]
    assert abs(after["q3_0"] - before["q3_0"]) > 20.0, (before, after)  # 73 deg on 2026-12-07
    assert (after["q1_0"], after["q2_0"]) == (before["q1_0"], before["q2_0"])
    # the share link holds the start; a page opened at it starts there
    href = opened.page.get_attribute("#share-link", "href")
    query = href.split("?", 1)[1]
    again = Page(browser, site[0], query)
    try:
        got = again.state()["values"]
        assert [got[f"q{k}_0"] for k in (1, 2, 3)] == [after[f"q{k}_0"] for k in (1, 2, 3)]
        assert again.errors() == []
    finally:
        again.page.close()


def test_the_deepmind_acrobots_lower_arm_is_drawn_from_the_elbow_where_its_mass_is(browser, tmp_path):
    """dm_control's acrobot (its zero configuration both arms up, read from its MJCF): the page draws its lower arm
    from the elbow towards the arm's centre of mass, as :func:`skewpend.views.drawing.link_points` does (whose drawn
    end is MuJoCo's ``tip`` site: tests/test_upright_zero.py) -- not along the rod's ``+j``, 2 m the wrong way."""
    from skewpend.interop.importer import read_mjcf
    from skewpend.views.drawing import link_points

    xml = Path(__file__).resolve().parent / "data" / "dm_control_acrobot.xml"
    chain = read_mjcf(xml).chain
    folder = tmp_path / "site"
    ran = run_cli(["serve", "--config", str(xml), "--export", str(folder)])
    assert ran.code == 0, ran.report()
    assert "(open index.html in a browser)" in ran.err  # no start of its own: the page's
    opened = Page(browser, (folder / "index.html").resolve().as_uri(), "")
    try:
        opened.pause()
        y = np.array(opened.state()["y"])
        G = opened.page.evaluate("() => window.explorer.geometry()")
        tips = skewpend.simulate(chain, y, 1e-3, dt_out=1e-3).tips()[0]
        want = link_points(chain, y, tips)[0]  # hinge 1, hinge 2, the lower arm's drawn end
        drawn = np.array([_back(v) for v in G["pivots"] + G["tips"][-1:]]) / G["scale"]
        np.testing.assert_allclose(drawn, want, atol=1e-9)
        assert np.linalg.norm(drawn[2] - tips[3:]) > 1.0  # the rod's +j end is elsewhere: the mirror was needed
        # its shoulder is 2 m above the world's origin: the camera looks at the ball the arms move in, so the roof,
        # both hinges and the tip are on the canvas (the view of a chain hanging from the roof showed none of them)
        box = opened.page.locator("#scene").bounding_box()
        for name in ("hinge1", "hinge2", "tip"):
            at = opened.page.evaluate(f"() => window.explorer.screenOf('{name}')")
            assert box["x"] < at["x"] < box["x"] + box["width"] and box["y"] < at["y"] < box["y"] + box["height"], name
        assert opened.page.evaluate("() => window.explorer.page.frame") == [[0.0, -2.0, 0.0], 2.0]
        # its zero is upright: the linearised equations and the normal modes are about its hanging rest (pi, 0), as
        # normal_modes' (2.666 and 6.879 rad/s; at q = 0 the page said there were none)
        assert opened.page.evaluate("() => window.explorer.physics.REST") == [math.pi, 0.0]
        js, lib = opened.page.evaluate("() => window.explorer.modes()"), skewpend.normal_modes(chain)
        np.testing.assert_allclose(js["frequencies"], lib.frequencies, rtol=1e-9)
        np.testing.assert_allclose(lib.frequencies, [2.666, 6.879], atol=5e-4)
        opened.page.locator("#modes li button").nth(0).click()  # the slow mode's start: about (pi, 0), wrapped
        s = opened.state()
        q = np.radians([s["values"]["phi0"], s["values"]["psi0"]])
        dq = np.mod(q - [math.pi, 0.0] + math.pi, 2 * math.pi) - math.pi
        shape = lib.shapes[:, 0]
        np.testing.assert_allclose(dq / np.abs(dq).max(), shape / shape[np.abs(shape).argmax()], atol=1e-12)
        assert np.abs(dq).max() == pytest.approx(np.radians(10.0), rel=1e-12) and np.all(np.abs(q) <= math.pi)
        assert opened.errors() == [] and opened.blocked == []
    finally:
        opened.page.close()
