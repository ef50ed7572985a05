"""The report of a chain of links (``skewpend report --config`` with ``[[links]]``: the one report, whose
sections ask the model), built once from the command line for a skewed triple pendulum.

What is checked against something independent: the live view's rod ends at the start against the
chain's forward kinematics composed here by Rodrigues' formula; the modes table of the chain of two
against the double pendulum's normal modes (the symbolic derivation's kernel, not the chain's
recursive one); the two derivations' agreement (section 3) and MuJoCo's (section 9) as verdicts with
their numbers.  The page: every section, no reference outside itself, written atomically."""

from __future__ import annotations

import html
import json
import math
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

pytest.importorskip("matplotlib")

from skewpend import Parameters, normal_modes  # noqa: E402
from skewpend.symbolic.chain import Chain  # noqa: E402
from skewpend.views import report as R  # noqa: E402
from skewpend.views.report import build_report  # noqa: E402
from skewpend.views.report.common import SYMBOLIC_MAX_LINKS, sections  # noqa: E402
from skewpend.views.report.derivation import CHECK_TOL  # noqa: E402
from helpers import example_model  # noqa: E402

#: examples/skewed_triple.toml's chain (damped in its last joint), from a start with q2 moving, for 3 s.
RUN = example_model() + """
[initial]
q0 = ["60deg", -0.3, 0.2]
dq0 = [0, 0.5, 0]

[simulation]
t_end = 3
"""
Q0 = (math.radians(60), -0.3, 0.2)


@pytest.fixture(scope="module")
def triple(tmp_path_factory):
    """The report written by the command line, its text and what the command printed."""
    d = tmp_path_factory.mktemp("chain-report")
    (d / "triple.toml").write_text(RUN)
    out = d / "triple.html"
    proc = subprocess.run([sys.executable, "-m", "skewpend", "report", "--config", str(d / "triple.toml"), "-o", str(out)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    return out, out.read_text(encoding="utf-8"), proc


def _section(page: str, key: str) -> str:
    m = re.search(rf'<section class="report-section" id="{key}".*?</section>', page, re.S)
    assert m, key
    return m.group(0)


def test_every_section_is_there_and_nothing_is_fetched(triple):
    path, page, proc = triple
    assert f"wrote {path.resolve()}" in proc.stdout
    assert "[1/10]" in proc.stderr and "section 9, the comparison with MuJoCo" in proc.stderr
    for n, (key, title) in enumerate(sections(_chain()), 1):
        body = _section(page, key)
        assert f'<span class="num">{n}</span>{html.escape(title)}' in body
    assert "A chain of 3 links with skewed hinge axes" in page
    assert "Check: two derivations of one model" in page and "How chaotic: the Lyapunov spectrum" in page
    assert not re.search(r'(src|href)="(https?:)?//', page)  # no reference outside the file
    assert path.stat().st_size < 10_000_000
    assert not list(path.parent.glob("*.tmp*"))


def _chain() -> Chain:
    import tomllib

    run = tomllib.loads(RUN)
    return Chain.from_mapping({"links": run["links"], **run["chain"]})


def _fk_tips(chain: Chain, q) -> np.ndarray:
    """The rod ends of a chain at angles q, composed here: R_i = R_(i-1) Rot(axis_i, q_i), each hinge at its
    parent's frame's offset, the rod's end at (0, l, 0) in its own frame."""
    def rot(e, a):
        e = np.asarray(e, float) / np.linalg.norm(e)
        E = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
        return np.eye(3) * math.cos(a) + (1 - math.cos(a)) * np.outer(e, e) + E * math.sin(a)

    R, o, tips = np.eye(3), np.zeros(3), []
    for link, qi in zip(chain.links, q):
        o = o + R @ np.asarray(link.offset, float)
        R = R @ rot(link.axis, qi)
        tips.append(o + R @ np.array([0.0, link.length, 0.0]))
    return np.concatenate(tips)


def test_the_live_view_replays_the_chains_own_pose(triple):
    _, page, _ = triple
    sim = _section(page, "simulation")
    data = json.loads(html.unescape(re.search(r'<script type="application/json" class="live-data">(.*?)</script>',
                                              sim, re.S).group(1)))
    tips, axes = np.array(data["tips"]), np.array(data["axes"])
    assert tips.shape[1] == 9 and axes.shape[1] == 9 and len(data["t"]) == tips.shape[0]
    import tomllib

    run = tomllib.loads(RUN)
    chain = Chain.from_mapping({"links": run["links"], **run["chain"]})
    assert np.max(np.abs(tips[0] - _fk_tips(chain, Q0))) <= 1e-12
    assert data["size"] == 0.5  # the longest rod
    assert np.allclose(np.linalg.norm(axes.reshape(len(axes), 3, 3), axis=2), 1.0, atol=1e-12)


def test_the_derivations_agree_and_so_does_mujoco(triple):
    _, page, _ = triple
    check = html.unescape(_section(page, "check"))
    assert "✓ The two derivations agree" in check
    numbers = re.search(r"accelerations to ([\d.]+)×10<sup>−(\d+)</sup>", check)
    assert numbers and float(numbers.group(1)) * 10.0 ** -int(numbers.group(2)) <= CHECK_TOL
    derivation = _section(page, "derivation")
    assert r"\underline{\underline{P}}_{3}" in derivation and "M_{33}" in derivation
    validation = html.unescape(_section(page, "validation"))
    try:
        import mujoco  # noqa: F401
    except ImportError:
        assert "Not run: MuJoCo is not installed" in validation
    else:
        assert "AGREE" in validation and "DISAGREE" not in validation
        assert all(name in validation for name in ("q_{1}", "q_{3}", r"\dot q_{1}", r"\dot q_{3}"))


def test_the_analyses_of_a_chain_are_its_own(triple):
    _, page, _ = triple
    modes = html.unescape(_section(page, "modes"))
    assert modes.count("The 3 natural frequencies against hinge") == 2  # tilts of hinges 2 and 3
    orbits = html.unescape(_section(page, "orbits"))
    assert "8 equilibria" in orbits and "down-down-down" in orbits and "up-up-up" in orbits
    assert "mode 3" in orbits  # the three families of nonlinear normal modes
    chaos = html.unescape(_section(page, "chaos"))
    assert "λ6" in chaos and "λ7" not in chaos
    assert "Poincaré sections and the chaos diagram are planar pictures" in chaos
    assert "Not conservative: viscous damping" in html.unescape(_section(page, "system"))
    # what the one report's sections give every model: the damped modes, the flip map's facts, the orbits drawn
    assert "damping ratio ζ" in modes and "C_0 =" in modes and "q₃/q₁" in modes
    flips = html.unescape(re.sub(r"<[^>]+>", "", _section(page, "flipmap")))
    assert "starts that flip" in flips and "off the map's plane" in flips  # the start's q3 = 0.2 is off (q1, q2)
    assert "0: stable (minimum of V)" in orbits and "3: maximum of V" in orbits
    assert "four of the orbits in the (q₁, q₂) plane" in orbits


def test_a_single_link_is_refused_in_one_line():
    from skewpend import ParameterError

    with pytest.raises(ParameterError, match="two links or more"):
        build_report(Chain.from_lists(1, length=0.5, mass=1.0), t_end=1.0)


def test_the_chain_of_two_has_the_double_pendulums_modes(monkeypatch):
    """The modes table of the chain of two (the recursive kernel) equals the double pendulum's normal modes
    (the symbolic derivation's kernel) to the table's six digits; only sections 4 and 5 are built."""
    from skewpend.views.report import cache

    params = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
    for name in ("section_system", "section_flipmap", "section_orbits", "section_validation", "section_chaos"):
        monkeypatch.setattr(R, name, lambda ctx, name=name: f"<p>{name}</p>")
    monkeypatch.setattr(cache, "load", lambda params: {"bodies": {"derivation": "<p>derivation</p>", "check": "<p>check</p>"},
                                                        "notes": {}, "timings": {}})
    page = build_report(Chain.from_parameters(params), t_end=0.5, clip_seconds=0.5, fps=10.0, clip_size=(160, 120),
                        validate=False, sweep_points=5)
    rows = re.findall(r"<tr><td>(\d)</td><td class=num>([^<]+)</td>", _section(page, "modes"))
    table = [float(v.replace("−", "-")) for _, v in rows]
    expected = normal_modes(params).frequencies
    assert len(table) == 2 and np.allclose(table, expected, rtol=1e-5, atol=0)


def test_a_long_chain_is_not_derived_by_sympy():
    from skewpend.views.report.common import Context
    from skewpend.views.report.derivation import section_derivation

    n = SYMBOLIC_MAX_LINKS + 1
    chain = Chain.from_lists(n, length=0.3, mass=0.5)
    ctx = Context(chain, (0.0,) * 2 * n, 1.0, "dop853", None, None, None, None, 1.0, 10.0, (160, 120), 5, False, None)
    t0 = time.perf_counter()
    body = section_derivation(ctx)
    assert time.perf_counter() - t0 < 5.0  # no SymPy derivation of four links (45 s)
    assert f"A chain of {n} links is past what this report derives" in body and ctx.eom is None


def test_ctrl_c_leaves_no_report(tmp_path):
    (tmp_path / "t.toml").write_text(RUN.replace("t_end = 3", "t_end = 20"))
    out = tmp_path / "t.html"
    proc = subprocess.Popen([sys.executable, "-m", "skewpend", "report", "--config", str(tmp_path / "t.toml"), "-o",
                             str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(6.0)  # in the sections (the imports and the kernels' loading take about a second)
    assert proc.poll() is None
    proc.send_signal(signal.SIGINT)
    t0 = time.monotonic()
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert time.monotonic() - t0 < 5.0
    assert "interrupted" in err and "Traceback" not in err
    assert not out.exists() and not list(tmp_path.glob("*.html*"))


def test_the_page_in_a_browser(triple, tmp_path):
    """Chromium opens the chain's report offline: every math element typeset, no console error, the live view
    draws the three rods (pixel variance) at the simulated rod ends and axes of every 10th frame (1e-9)."""
    from helpers import chromium, missing_browser, skip_or_fail

    if missing_browser():
        skip_or_fail(missing_browser())
    import io

    from PIL import Image

    import skewpend

    path, page_text, _ = triple
    with chromium() as browser:
        page = browser.new_page(viewport={"width": 1100, "height": 900})
        blocked, problems = [], []
        page.route("**/*", lambda r: r.continue_() if r.request.url.startswith(("file:", "data:", "blob:"))
                   else (blocked.append(r.request.url), r.abort()))
        page.on("console", lambda m: problems.append(m.text) if m.type in ("error", "warning") else None)
        page.on("pageerror", lambda e: problems.append(str(e)))
        page.goto(path.as_uri(), wait_until="load")
        page.wait_for_function("document.documentElement.getAttribute('data-math') !== null", timeout=30000)
        page.wait_for_function("window.skewpendReplay && window.skewpendReplay.views.length === 1 && "
                               "window.skewpendReplay.views[0].state().renders > 2", timeout=30000)
        assert not blocked and not problems, (blocked, problems)
        math_count = page.evaluate("document.querySelectorAll('.math').length")
        typeset = page.evaluate("Array.from(document.querySelectorAll('.math')).filter(e => e.querySelector('.katex') "
                                "&& e.getBoundingClientRect().width > 0).length")
        assert math_count > 50 and typeset == math_count
        assert page.evaluate("document.querySelectorAll('.katex-error').length") == 0
        view = "window.skewpendReplay.views[0]"
        frames = page.evaluate(f"{view}.frames")
        import tomllib

        run = tomllib.loads(RUN)
        chain = Chain.from_mapping({"links": run["links"], **run["chain"]})
        fps = 30.0
        tr = skewpend.simulate(chain, (*Q0, 0.0, 0.5, 0.0), (frames - 1) / fps, dt_out=1 / fps, method="dop853")
        assert tr.t.size == frames
        tips, axes = tr.tips(), tr.axes()
        for k in range(0, frames, 10):
            drawn = page.evaluate(f"{view}.show({k})")
            np.testing.assert_allclose(drawn["tips"], tips[k], rtol=0, atol=1e-9)
            np.testing.assert_allclose(drawn["axes"], axes[k], rtol=0, atol=1e-9)
        page.locator("figure.live-view").scroll_into_view_if_needed()
        png = page.locator("figure.live-view canvas").screenshot(animations="disabled")
        pixels = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)
        assert pixels.std() > 8.0
        page.close()
