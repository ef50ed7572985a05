"""The HTML report (skewpend.views.report) and the display forms of the derivation
(skewpend.symbolic.display), without a browser (tests/test_report_browser.py opens the page).

Display forms: at alpha = 0 the rotation tensor shows cos(phi + psi), not products of single
angles; every displayed entry is proved equal to the derivation's own (checked here again by
sympy.simplify and at random points); the derivation's results are not touched.  The report:
one self-contained file under 10 MB with every section, no reference outside itself, the
specification's check identical, written atomically, its inputs refused before any work."""

from __future__ import annotations

import hashlib
import html
import json
import math
import random
import re
from pathlib import Path

import pytest
import sympy as sp

pytest.importorskip("matplotlib")

import skewpend  # noqa: E402
from skewpend import NotNumericError, ParameterError, Parameters, derive  # noqa: E402
from skewpend.symbolic.display import cost, display_form, display_matrix, display_steps, proven_equal  # noqa: E402
from skewpend.symbolic.symbols import SYMBOLS as S  # noqa: E402
from skewpend.views import report as R  # noqa: E402

phi, psi, dphi, dpsi, alpha = (S[n] for n in ("phi", "psi", "dphi", "dpsi", "alpha"))
MB = 1_000_000
#: Small settings for the variants (the default report is built once, with its defaults).
SMALL = dict(t_end=3.0, clip_seconds=1.0, fps=10.0, clip_size=(160, 120), sweep_points=19)
#: The numeric sections; each whole report runs them all (~10 s): docs/getting-started.md's three
#: `skewpend report` examples (default, damped, a general body: tests/test_readme.py) build every section
#: of those cases end to end; the default and damped runs are the files read below and opened by
#: tests/test_report_browser.py (run once per session: tests/helpers.py's shared_cli_run).
NUMERIC_SECTIONS = ("section_simulation", "section_system", "section_modes", "section_flipmap", "section_orbits",
                    "section_validation", "section_chaos")


def only_sections(monkeypatch, *keep):
    """Replace every numeric section but ``keep`` with a stub: a variant test builds what it checks."""
    for name in NUMERIC_SECTIONS:
        if name not in keep:
            monkeypatch.setattr(R, name, lambda ctx, name=name: f"<p>{name}: not under test</p>")
    if "section_chaos" not in keep:
        monkeypatch.setattr(R, "chaos_jobs", lambda ctx: {})
    if "section_simulation" not in keep:
        monkeypatch.setattr(R, "live_figure", lambda ctx: "")
    if not {"section_simulation", "section_flipmap"} <= set(keep):
        # the kernels built ahead serve those two sections (a stub needs none: a general body's would compile)
        monkeypatch.setattr(R, "_build_ahead", lambda params: None)


def symbolic_sections_stubbed(monkeypatch):
    """Sections 2 and 3 as if read from the cache (stubs): for a test of other sections, with parameters
    whose symbolic sections no other test computes (a second process's SymPy work, seconds)."""
    from skewpend.views.report import cache

    monkeypatch.setattr(cache, "load", lambda params: {"bodies": {"derivation": "<p>derivation: not under test</p>",
                                                                  "check": "<p>check: not under test</p>"},
                                                       "notes": {}, "timings": {}})


# -- display forms -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def planar():
    return derive(Parameters(alpha=0))


@pytest.fixture(scope="module")
def planar_display(planar):
    return display_steps(planar.steps)


def _entries(value):
    return list(value) if isinstance(value, sp.MatrixBase) else [value]


def _numeric_points(a, b, n=5, seed=7):
    rng = random.Random(seed)
    symbols = sorted(a.free_symbols | b.free_symbols, key=sp.default_sort_key)
    for _ in range(n):
        at = {x: rng.uniform(0.2, 1.9) for x in symbols}
        yield complex(a.evalf(subs=at)), complex(b.evalf(subs=at))


def test_planar_rotation_shows_the_compound_angle(planar, planar_display):
    shown = planar_display["P"]
    text = str(shown)
    assert "cos(phi + psi)" in text and "sin(phi + psi)" in text
    assert "cos(phi)*cos(psi)" not in text and "sin(phi)*sin(psi)" not in text
    assert shown == sp.Matrix([[sp.cos(phi + psi), -sp.sin(phi + psi), 0], [sp.sin(phi + psi), sp.cos(phi + psi), 0], [0, 0, 1]])
    # and so the LaTeX of the report's check
    from skewpend.symbolic.render import tex

    assert r"\cos{\left(\varphi + \psi \right)}" in tex(shown)


def test_planar_steps_read_like_the_specification(planar_display):
    d = planar_display
    assert d["omega2"] == sp.Matrix([0, 0, dphi + dpsi])
    v = d["v_c"]
    assert "cos(phi + psi)" in str(v[0]) and "sin(phi + psi)" in str(v[1])
    assert "cos(phi + psi)**2" in str(d["Theta2"][0, 0])  # m2 b^2/12 (E - e~ e~), e~ = P j
    assert "cos(phi + psi)" in str(d["Pi"]) and "cos(phi)*cos(psi)" not in str(d["Pi"])
    assert "(dphi + dpsi)**2" in str(d["T"])  # grouped by parameters, as the specification writes T2


def test_every_displayed_entry_equals_the_derivations(planar, planar_display):
    general = derive(Parameters())
    shown_general = display_steps(general.steps, keys=("P", "v_c", "T", "Pi", "f"))
    for eom, shown in ((planar, planar_display), (general, shown_general)):
        for key, value in eom.steps.items():
            for orig, new in zip(_entries(value), _entries(shown[key])):
                if orig == new:
                    continue
                assert cost(new) < cost(orig), (key, new)
                assert sp.simplify(sp.expand_trig(orig - new)) == 0, (key, orig, new)
                for x, y in _numeric_points(orig, new):
                    assert abs(x - y) <= 1e-12 * max(1.0, abs(x)), (key, orig, new)


def test_display_leaves_the_derivation_alone(planar):
    before = {k: sp.srepr(v) for k, v in planar.steps.items()}
    display_steps(planar.steps)
    assert {k: sp.srepr(v) for k, v in planar.steps.items()} == before
    assert "cos(phi)*cos(psi)" in str(planar.steps["P"])  # the numeric code's form is unchanged


def test_proof_of_equality_is_exact():
    assert proven_equal(sp.sin(phi) ** 2, 1 - sp.cos(phi) ** 2)
    assert proven_equal(sp.cos(2 * (phi + psi)), 2 * sp.cos(phi + psi) ** 2 - 1)
    assert not proven_equal(sp.cos(phi + psi), sp.cos(phi - psi))
    assert not proven_equal(sp.sin(phi) * sp.cos(psi), sp.sin(phi + psi))
    # a difference far below any numerical tolerance is still a difference
    assert not proven_equal(sp.cos(phi), sp.cos(phi) + sp.Rational(1, 10**30) * sp.sin(psi))


def test_display_keeps_what_it_cannot_shorten():
    e = sp.cos(phi) + sp.sin(psi)
    assert display_form(e) == e
    assert display_matrix(sp.Matrix([[e, 0], [0, 1]])) == sp.Matrix([[e, 0], [0, 1]])



def test_the_form_shown_does_not_depend_on_the_clock(planar, planar_display, monkeypatch):
    """A loaded machine once showed a longer potential energy (a 2 s clock cut the candidates
    short); the form shown comes from the entry's size alone: a clock that races ahead by an
    hour at every reading changes nothing."""
    import skewpend.symbolic.display as D

    ticks = iter(range(0, 10**9, 3600))
    monkeypatch.setattr(D.time, "perf_counter", lambda: float(next(ticks)))
    shown = display_steps(planar.steps, keys=("P", "v_c", "T", "Pi"))
    for key in ("P", "v_c", "T", "Pi"):
        assert shown[key] == planar_display[key], key
    assert "cos(phi + psi)" in str(shown["Pi"])  # the grouped form, as the specification writes it

# -- the report ------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def default_report(tmp_path_factory):
    """The report with every default: the command `skewpend report` of docs/getting-started.md, run once
    per session (tests/helpers.py's shared_cli_run; test_readme checks its outcome, and
    tests/test_report_browser.py opens the same file)."""
    from helpers import default_report as built

    path = built(tmp_path_factory)
    return path, path.read_text(encoding="utf-8"), None


def _section(page: str, key: str) -> str:
    start = page.index(f'<section class="report-section" id="{key}"')
    return page[start: page.index("</section>", start)]


def test_default_report_is_one_small_file(default_report):
    path, page, _ = default_report
    assert path.name == "report.html" and path.stat().st_size <= 10 * MB
    # nothing beside it (its folder also holds the examples/ every documented command's folder has), no temporary file
    assert sorted(p.name for p in path.parent.iterdir()) == ["examples", "report.html"]
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")


def test_report_references_nothing_outside_itself(default_report):
    _, page, _ = default_report
    markup = re.sub(r"<(script|style)\b[^>]*>.*?</\1>", "", page, flags=re.S | re.I)  # the HTML, without code
    refs = re.findall(r"""\b(?:src|href|poster|data)\s*=\s*["']([^"']*)["']""", markup, flags=re.I)
    assert refs, "no src/href attribute found at all"
    for ref in refs:
        assert ref.startswith(("data:", "#")), ref[:80]
    assert not re.search(r"""(?:src|href)\s*=\s*["']?\s*(?:https?:)?//""", page, flags=re.I)
    styles = "".join(re.findall(r"<style\b[^>]*>(.*?)</style>", page, flags=re.S)) + "".join(re.findall(r'style="([^"]*)"', markup))
    assert not re.search(r"url\(\s*['\"]?(?!data:)", styles), "a style sheet refers to a file"
    assert "@import" not in page
    assert re.search(r"<script[^>]*\bsrc=", page) is None and re.search(r"<link\b", page) is None


def test_report_has_every_section_in_order(default_report):
    _, page, _ = default_report
    positions = [page.index(f'id="{key}"') for key, _ in R.SECTIONS]
    assert positions == sorted(positions)
    for key, title in R.SECTIONS:
        assert f'href="#{key}"' in page  # the table of contents


def test_progress_counts_every_part_once_in_order(monkeypatch):
    """``progress(done, total)``: 1, 2, ..., total, one call per part (the numeric sections stubbed,
    the symbolic ones as if read from the cache: what is counted, not what is computed)."""
    only_sections(monkeypatch)
    symbolic_sections_stubbed(monkeypatch)
    calls: list = []
    R.build_report(progress=lambda done, total: calls.append((done, total)), **SMALL)
    total = calls[-1][1]
    assert total >= 10 and calls == [(d, total) for d in range(1, total + 1)]


def test_each_part_is_said_as_it_begins_in_order(monkeypatch, tmp_path):
    """In a command (skewpend.progress.Stages active), the report says each part as it begins, counted
    k of 10, in the order it builds them, after the start of its background work (issue 36: a report
    was silent for 45 s)."""
    import io
    import sys

    from skewpend.progress import STAGE_LINE, Stages

    only_sections(monkeypatch)
    symbolic_sections_stubbed(monkeypatch)
    calls: list = []
    err = io.StringIO()
    monkeypatch.setattr(sys, "stderr", err)
    with Stages("report", terminal=False, grace=60.0) as st:
        R.build_report(out=tmp_path / "r.html", progress=lambda done, total: calls.append(done), **SMALL)
    said = [line.split("... (")[0].removeprefix("skewpend report: ") for line in st.lines]
    order = ("simulation", "system", "modes", "flipmap", "orbits", "validation", "chaos", "cached", "live")
    assert said == [R.PARTS["start"]] + [f"[{k}/10] {R.PARTS[key]}" for k, key in enumerate(order, 1)] + [
        "[10/10] writing r.html"]
    assert err.getvalue().splitlines() == st.lines and all(STAGE_LINE.match(line) for line in st.lines)
    assert calls == list(range(1, 11))  # progress(k, 10) as part k ends, as before


def test_report_section_contents(default_report):
    _, page, _ = default_report
    system = _section(page, "system")
    assert system.count('src="data:image/png;base64,') == 2  # reference configuration and initial state
    for unit in ("kg", "m/s²", "N m s"):
        assert unit in system
    derivation = _section(page, "derivation")
    steps = [html.unescape(t) for t in re.findall(r'<p class="step-title">([^<]*)</p>', derivation)]
    assert steps == [
        "Rotation of rod 1", "Current axis of the second hinge", "Rotation of rod 2", "Angular velocity of rod 2",
        "Velocity of rod 2's centre of mass", "Inertia tensor of rod 2", "Kinetic energy", "Potential energy",
        "Lagrange's equations",
    ]
    assert "With the values of section 1" in derivation and "Linearised" in derivation
    check = _section(page, "check")
    assert check.count("✓ identical") == 7 and "✗" not in check and "Every quantity agrees" in check
    assert r"\cos{\left(\varphi + \psi \right)}" in check.replace("&amp;", "&")
    modes = _section(page, "modes")
    assert "ω [rad/s]" in modes and "2:1</b> crossed at α = 32.489°" in modes and "147.51°" in modes
    sim = _section(page, "simulation")
    assert sim.count('src="data:image/png;base64,') == 6  # 5 figures and the live view's poster
    assert 'class="live-view"' in sim and 'class="live-data"' in sim and "energy drift" in sim
    validation = _section(page, "validation")
    try:
        import mujoco  # noqa: F401
    except ImportError:
        assert "pip install &#x27;skewpend[validate]&#x27;" in validation or "pip install 'skewpend[validate]'" in validation
    else:
        assert "AGREE" in validation and "DISAGREE" not in validation
    provenance = _section(page, "provenance")
    assert skewpend.__version__ in provenance and "KaTeX (bundled)" in provenance and "Timings" in provenance


def test_report_mathematics_is_balanced_latex(default_report):
    _, page, _ = default_report
    maths = re.findall(r'<(?:span|div) class="math(?: display)?">(.*?)</(?:span|div)>', page, flags=re.S)
    assert len(maths) > 100
    for tex in maths:
        assert tex.count("{") == tex.count("}"), tex[:120]
        assert tex.count(r"\left") == tex.count(r"\right"), tex[:120]


def test_the_live_view_replays_the_simulated_motion(default_report):
    """The live view's frames are the simulation's states at the frame times (the default report:
    the first 10 s at 30 per second), as rod ends and hinge axes that satisfy the geometry: |rod 1|
    = a, |rod 2| = b, each rod perpendicular to its hinge axis, unit axes at the angle alpha in the
    reference configuration -- and the report no longer carries a video."""
    import numpy as np

    _, page, _ = default_report
    assert "video/mp4" not in page and "<video" not in page
    data = json.loads(re.search(r'<script type="application/json" class="live-data">(.*?)</script>', page, re.S).group(1))
    p = Parameters(**R.DEFAULT_PARAMETERS)
    t, tips, axes = np.array(data["t"]), np.array(data["tips"]), np.array(data["axes"])
    assert t.size == round(R.CLIP_SECONDS * R.CLIP_FPS) + 1 and tips.shape == axes.shape == (t.size, 6)
    np.testing.assert_allclose(np.diff(t), 1 / R.CLIP_FPS, rtol=1e-9)
    tr = skewpend.simulate(p, R.DEFAULT_INITIAL_STATE, t[-1], dt_out=1 / R.CLIP_FPS, method="dop853")  # the clip's integrator
    np.testing.assert_allclose(tips, tr.tips(), rtol=0, atol=1e-12)
    r1, r2 = tips[:, :3], tips[:, 3:] - tips[:, :3]
    n1, e = axes[:, :3], axes[:, 3:]
    np.testing.assert_allclose(np.linalg.norm(r1, axis=1), p.a, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(r2, axis=1), p.b, rtol=1e-12)
    assert np.abs(np.einsum("ij,ij->i", r1, n1)).max() < 1e-12 and np.abs(np.einsum("ij,ij->i", r2, e)).max() < 1e-12
    np.testing.assert_allclose(np.linalg.norm(e, axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(n1 @ np.array([0.0, 0.0, 1.0]), 1.0)  # the roof's axis k stays
    # e turns with rod 1 about k, so its angle with k stays alpha
    np.testing.assert_allclose(np.einsum("ij,ij->i", n1, e), math.cos(p.alpha), atol=1e-12)
    assert data["size"] == max(p.a, p.b)


def test_report_returns_html_without_out(monkeypatch):
    only_sections(monkeypatch, "section_modes", "section_system", "section_simulation")  # 1 draws 5's motion
    symbolic_sections_stubbed(monkeypatch)
    page = R.build_report(Parameters(a=0.5, b=0.5, m1=1.0, m2=1.0, alpha=math.radians(30), g=9.81, c1=0.05), **SMALL)
    assert isinstance(page, str) and page.startswith("<!DOCTYPE html>")
    modes = _section(page, "modes")
    assert "damping ratio ζ" in modes  # damped modes
    assert "30°" in _section(page, "system")


def test_general_bodies_say_why_there_is_no_sweep(tmp_path, monkeypatch):
    only_sections(monkeypatch, "section_modes")
    p = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, g=9.81, axis2=(1, 0, 1), com2=(0, 0.4, 0),
                   inertia2=((0.02, 0, 0), (0, 0.001, 0), (0, 0, 0.02)))
    page = R.build_report(p, out=tmp_path / "general.html", **SMALL).read_text(encoding="utf-8")
    modes = _section(page, "modes")
    assert "ω [rad/s]" in modes and "axis2" in modes and "nothing to sweep" in modes
    assert "Rotation of body 2" in _section(page, "derivation")
    assert "✓ identical" in _section(page, "check")  # the specification's own thin rods


def test_without_mujoco_the_report_says_how_to_get_it(monkeypatch):
    monkeypatch.setattr(R.analyses, "mujoco_installed", lambda: False)
    monkeypatch.setattr(R, "PARALLEL", False)  # the serial path too
    only_sections(monkeypatch, "section_validation")
    page = R.build_report(**SMALL)
    validation = _section(page, "validation")
    assert "MuJoCo is not installed" in validation and "skewpend[validate]" in validation


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(params=Parameters()), "numeric"),
        (dict(out="report.pdf"), ".html"),
        (dict(t_end=5000.0), "at most"),
        (dict(t_end=-1.0), "positive"),
        (dict(fps=0.0), "fps"),
        (dict(fps=120.0), "fps"),
        (dict(clip_size=(161, 120)), "even"),
        (dict(sweep_points=1), "sweep_points"),
        (dict(method="euler"), "method"),
        (dict(dt=0.01), "dt"),
        (dict(method="rk4", rtol=1e-8), "rtol"),
        (dict(y0=(1.0, 2.0)), "y0"),
        (dict(validate="yes"), "validate"),
        (dict(progress="no"), "progress"),
    ],
)
def test_refused_before_any_work(kwargs, message, tmp_path, monkeypatch):
    def fail(ctx):  # pragma: no cover - must not be reached
        raise AssertionError("work started")

    monkeypatch.setattr(R, "section_simulation", fail)
    params = kwargs.pop("params", None)
    out = kwargs.pop("out", None)
    with pytest.raises((ParameterError, NotNumericError), match=re.escape(message)):
        R.build_report(params, out=None if out is None else tmp_path / out, **kwargs)
    assert list(tmp_path.iterdir()) == []


def test_written_atomically(tmp_path, monkeypatch):
    out = tmp_path / "r.html"
    out.write_text("old")

    def boom(ctx):
        raise RuntimeError("boom")

    only_sections(monkeypatch, "section_modes")  # sections computed before the failure, as in a report
    monkeypatch.setattr(R, "section_validation", boom)
    with pytest.raises(RuntimeError):
        R.build_report(out=out, **SMALL)
    assert out.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["r.html"]


# -- the bundled KaTeX -------------------------------------------------------------------------------
def test_bundled_katex_is_what_vendor_katex_recorded():
    root = Path(R.__file__).parent.parent / "assets" / "katex"  # views/assets (R is the views/report package)
    source = json.loads((root / "SOURCE.json").read_text())
    assert source["package"] == "katex" and source["files"]
    for rel, digest in source["files"].items():
        assert hashlib.sha256((root / rel).read_bytes()).hexdigest() == digest, rel
    assert "MIT" in (root / "LICENSE").read_text()
    css, js, version = R.katex_assets()
    assert version == source["version"]
    fonts = sorted(p.name for p in (root / "fonts").glob("*.woff2"))
    assert css.count("data:font/woff2;base64,") == len(fonts)
    assert not re.search(r"url\(\s*['\"]?(?!data:)", css)
    assert "</script" not in js.lower()


def test_interrupted_report_leaves_no_file_and_no_process(tmp_path, monkeypatch):
    started = []
    original = R._Background.start

    def start(params):
        bg = original(params)
        started.append(bg)
        return bg

    def interrupt(done, total):
        raise KeyboardInterrupt

    monkeypatch.setattr(R._Background, "start", staticmethod(start))
    out = tmp_path / "r.html"
    with pytest.raises(KeyboardInterrupt):
        R.build_report(out=out, progress=interrupt, **SMALL)
    assert list(tmp_path.iterdir()) == []
    if started:  # more than one core: the second process was stopped
        assert started[0].proc.poll() is not None


# -- the flip-time map (section 6) -----------------------------------------------------------------------
def _png_size(b64: str):
    import base64
    import io

    from PIL import Image

    data = base64.b64decode(b64)
    with Image.open(io.BytesIO(data)) as im:
        return im.format, im.size, len(data)


def test_report_flipmap_section(default_report):
    import numpy as np

    _, page, _ = default_report
    keys = [k for k, _ in R.SECTIONS]
    assert keys[keys.index("simulation") + 1:keys.index("simulation") + 6] == ["flipmap", "chaos", "orbits", "validation",
                                                                               "provenance"]
    sec = _section(page, "flipmap")
    assert '<span class="num">6</span>Which starts flip: the flip-time map' in sec
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', sec)
    assert len(images) == 1
    fmt, (w, h), nbytes = _png_size(images[0])
    assert fmt == "PNG" and 600 <= w <= 900 and 600 <= h <= 900 and nbytes < 250_000  # small
    text = html.unescape(re.sub(r"<[^>]+>", "", sec))
    n = R.FLIPMAP_N
    for words in (f"{n}\xa0×\xa0{n}", "the first time either hinge angle leaves (−180°, 180°)", "log colour scale",
                  "White: no flip within 10 s", "grey: energy forbids any flip", "red dot: the angles of the simulation's"
                  " initial state (section 5).", "starts that flip", "forbidden by energy", "mirrored"):
        assert words in text, words
    # the figures are numbered on through the page: the map follows the 5 of the simulation
    assert re.search(r"Figure (\d+)\.", sec).group(1) == str(len(re.findall(r'<figure id="figure-', page[:page.index('id="flipmap"')])) + 1)
    # the start of section 5 (at rest) on its own: its flip time agrees with simulate's rows
    m = re.search(r"at rest: flips at t = ([0-9.]+) s \((φ|ψ), hinge ([12])\)", text)
    assert m, text
    t_flip, joint = float(m.group(1)), int(m.group(3)) - 1
    tr = skewpend.simulate(Parameters(**R.DEFAULT_PARAMETERS), R.DEFAULT_INITIAL_STATE, t_flip + 0.01, dt_out=1e-4)
    out = np.abs(tr.y[:, :2]) >= np.pi
    first = int(np.argmax(out.any(axis=1)))
    assert out.any() and out[first, joint]
    assert tr.t[first - 1] <= t_flip + 1e-9 and t_flip <= tr.t[first] + 1e-9
    provenance = _section(page, "provenance")
    assert "6 · flip-time map" in provenance and "9 · validation against MuJoCo" in provenance
    assert f"{n} × {n} starts at rest, t_end = 10 s" in html.unescape(provenance)


def test_flipmap_section_for_general_bodies_with_torques_and_speeds():
    from types import SimpleNamespace

    from helpers import general_body

    p = general_body(c1=0.05, tau2=0.2)  # (its flip kernel is the one the report of examples/general_body.toml builds)
    ctx = SimpleNamespace(params=p, y0=(4.0, -0.8, 0.5, 0.0), notes={})  # phi0 beyond 180 deg: wrapped on the map
    sec = R.section_flipmap(ctx)
    assert sec.count('src="data:image/png;base64,') == 1 and "callout" not in sec
    text = html.unescape(re.sub(r"<[^>]+>", "", sec))
    assert "but not at rest (the map is for starts at rest)" in text
    assert f"φ₀ = {math.degrees(4.0 - 2 * math.pi):.5g}°".replace("-", "−") in text
    assert "mirrored" not in text  # torques (and a centre of mass off the plane) break the mirror symmetry
    assert "need not follow its cell" in text
    assert "flip" in ctx.notes["flipmap"]


def test_flipmap_section_start_that_energy_forbids_to_flip():
    from types import SimpleNamespace

    ctx = SimpleNamespace(params=Parameters(**R.DEFAULT_PARAMETERS), y0=(0.3, -0.2, 0.0, 0.0), notes={})
    text = html.unescape(re.sub(r"<[^>]+>", "", R.section_flipmap(ctx)))
    assert "at rest: never flips: energy forbids it" in text
    assert re.search(r"starts that flip\d[\d\u2009]* of 20\u2009736 \(", text), text


def test_report_chaos_section(default_report):
    """Section 7: the Lyapunov spectrum of section 5's start (a Hamiltonian pair structure), two
    Poincare sections, the largest-exponent map and the chaos diagram, each a figure."""
    _, page, _ = default_report
    sec = _section(page, "chaos")
    assert '<span class="num">7</span>How chaotic' in sec
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', sec)
    assert len(images) == 5  # running estimates, two sections, the map, the diagram
    for data in images:
        fmt, (w, h), nbytes = _png_size(data)
        assert fmt == "PNG" and 300 <= w <= 1400 and 300 <= h <= 1400 and nbytes < 600_000
    text = html.unescape(re.sub(r"<[^>]+>", "", sec))
    # each exponent, with its interval once the windows have settled (whether a 500 s run of a chaotic
    # motion has settled depends on its trajectory, i.e. on the rounding of the code that ran it)
    lam = [float(x) for x in re.findall(r"λ[1-4]([+-][0-9.]+)(?: ± \S+)? 1/s", text)]
    assert len(lam) == 4, text
    # the default model is conservative: pairs +-lambda and two zeros, up to O(1/T) with T = 500 s
    # (the finite-time sum is log(det M(q0)/det M(q(T)))/T, |log det ratio| <~ 2 for these rods)
    assert lam[0] > 0.1 and abs(lam[0] + lam[3]) < 0.01 and abs(lam[1]) < 0.02 and abs(lam[2]) < 0.02
    for words in ("Benettin", "Poincaré section", "area", "% of the potential's span", "Does skewing the hinges tame or feed chaos?",
                  "alpha\\E [J]"):
        assert words in text, words
    # the diagram's table: 7 alphas from 0 to 90 deg, fractions in [0, 1], none chaotic at the lowest energy
    rows = re.findall(r"^\s*([0-9.]+) deg((?:\s+[0-9.]+)+)\s*$", text, flags=re.M)
    assert [float(r[0]) for r in rows] == [0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0]
    fractions = [[float(x) for x in r[1].split()] for r in rows]
    assert all(0.0 <= f <= 1.0 for row in fractions for f in row)
    assert all(row[0] == 0.0 for row in fractions) and all(max(row) > 0.5 for row in fractions)
    provenance = html.unescape(_section(page, "provenance"))
    assert "7 · chaos: exponents, sections, diagram" in provenance


def test_chaos_section_for_a_damped_model_explains_what_is_left_out():
    from types import SimpleNamespace

    p = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81, c1=0.05)
    ctx = SimpleNamespace(params=p, y0=(1.2, -0.8, 0.0, 0.0), notes={})
    body = R.section_chaos(ctx)
    text = html.unescape(re.sub(r"<[^>]+>", "", body))
    assert "need an energy surface" in text and len(re.findall(r"<figure", body)) == 1
    # each exponent, with its interval once the windows have settled (whether a 500 s run of a chaotic
    # motion has settled depends on its trajectory, i.e. on the rounding of the code that ran it)
    lam = [float(x) for x in re.findall(r"λ[1-4]([+-][0-9.]+)(?: ± \S+)? 1/s", text)]
    assert len(lam) == 4 and sum(lam) < -0.01, text  # damping contracts phase space


def test_a_friction_and_rotor_model_report_shows_its_terms_and_is_not_called_conservative(monkeypatch):
    """Issue 37: the table, the system's text, the derivation and section 7 of a model with Coulomb
    friction and geared rotors (and no damping, no torques) name those terms; the energy-surface
    analyses are skipped as for damping, saying which terms make the model non-conservative."""
    only_sections(monkeypatch, "section_system", "section_simulation", "section_chaos")
    p = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81, cf1=0.12, cf2=0.05, cfs=50.0, Ir=2e-4, gr=-30.0)
    page = R.build_report(p, **SMALL)
    system = html.unescape(re.sub(r"<[^>]+>", " ", _section(page, "system")))
    system = re.sub(r"\s+", " ", system)
    assert "Not conservative: Coulomb friction in hinge 1, Coulomb friction in hinge 2" in system
    assert "is conserved" not in system
    for row in ("cf1 Coulomb friction in hinge 1 0.12 N m", "cfs smoothing rate of the Coulomb friction's atan 50 s/rad",
                "Ir rotor inertia of each geared motor 0.0002 kg m²", "gr gear ratio of the motors −30"):
        assert row in system, row
    derivation = html.unescape(_section(page, "derivation"))
    assert r"\arctan(c_{fs}" in derivation and "Coulomb friction and the motors' rotors of section 1" in derivation
    assert "I_r" in derivation  # the rotors' kinetic energy, symbolic
    chaos = re.sub(r"\s+", " ", html.unescape(re.sub(r"<[^>]+>", " ", _section(page, "chaos"))))
    assert "need an energy surface" in chaos and "this one is not (Coulomb friction in hinge 1 cf1 = 0.12 N m" in chaos
    assert "Poincaré section at" not in chaos and len(re.findall(r"<figure", _section(page, "chaos"))) == 1
    assert "skipped (not conservative: cf1, cf2)" in html.unescape(_section(page, "provenance"))


def test_report_orbits_section(default_report):
    """Section 8: the equilibria table and the frequency-energy plot, for the report's parameters."""
    import skewpend

    _, page, _ = default_report
    sec = _section(page, "orbits")
    assert '<span class="num">8</span>Beyond small oscillations' in sec
    for label in ("down-down", "down-up", "up-down", "up-up"):
        assert f"<td>{label}</td>" in sec
    assert "none missed" in sec
    images = re.findall(r'src="data:image/png;base64,([^"]+)"', sec)
    assert len(images) == 1
    fmt_, size, _ = _png_size(images[0])
    assert fmt_ == "PNG" and size[0] > 800
    # the facts state the families' end frequencies as the library computes them
    from skewpend.analysis.orbits import nnm

    f2 = nnm(skewpend.reference_parameters(), mode=2, resolution=80)
    assert f"{f2.frequencies[-1]:.5g}" in sec
    assert "nan" not in re.sub(r"<[^>]+>", " ", sec).lower().split()


def test_a_report_at_other_values_computes_only_what_the_values_change(tmp_path, monkeypatch):
    """The check at alpha = 0 and the thin rods' symbolic derivation depend on no value of the report: after one
    report they are read for another skew and other masses (no SymPy display step runs again) and give the HTML a
    cache of their own computes afresh; the values' part of section 2 is that report's own."""
    import json

    from skewpend.symbolic import display
    from skewpend.views.report import derivation

    p = Parameters(a=0.5, b=0.5, m1=1.0, m2=1.0, alpha=math.radians(30), g=9.81, c1=0.05)
    q = p.replace(alpha=math.radians(50), m1=2.0, a=0.3, c1=0.02)  # the same terms on, other values
    monkeypatch.setenv("SKEWPEND_CACHE_DIR", str(tmp_path / "warm"))
    R._symbolic_sections(p)
    monkeypatch.setattr(display, "display_steps", lambda *a, **k: pytest.fail("a SymPy display step ran again"))
    monkeypatch.setattr(derivation, "check_planar", lambda *a: pytest.fail("the check ran again"), raising=False)
    warm = R._symbolic_sections(q)
    monkeypatch.undo()
    monkeypatch.setenv("SKEWPEND_CACHE_DIR", str(tmp_path / "cold"))
    cold = R._symbolic_sections(q)
    assert json.dumps(warm["bodies"]) == json.dumps(cold["bodies"]) and warm["notes"] == cold["notes"]
    assert "0.3" in warm["bodies"]["derivation"].split("With the values of section 1")[1]  # q's rod length a
    assert "every quantity identical" == warm["notes"]["check"]


def test_the_symbolic_sections_are_cached_by_parameters_and_code(tmp_path, monkeypatch):
    """Sections 2 and 3 are kept in the cache directory under a key of the parameters, the version
    and skewpend's own code: a second report with the same parameters reads them (the same HTML),
    other parameters or other code miss, and a damaged entry is computed again.  The first report
    computes them in a second process, the last one in this process: the two agree."""
    from skewpend.numeric.kernels import cache_dir
    from skewpend.views.report import cache

    # a cache of its own for the report's sections, sharing the test session's compiled kernels (a
    # private kernel cache would compile every kernel of the report again: ~10 s, and not under test)
    kernels = cache_dir() / "kernels"
    kernels.mkdir(parents=True, exist_ok=True)
    (tmp_path / "cache").mkdir()
    (tmp_path / "cache" / "kernels").symlink_to(kernels, target_is_directory=True)
    monkeypatch.setenv("SKEWPEND_CACHE_DIR", str(tmp_path / "cache"))

    def numeric_sections_stubbed():  # what is under test is sections 2 and 3
        only_sections(monkeypatch)

    numeric_sections_stubbed()
    p = Parameters(a=0.5, b=0.5, m1=1.0, m2=1.0, alpha=math.radians(30), g=9.81)
    first = R.build_report(p, **SMALL)
    assert "read from the cache" not in first and "in a second process" in first
    entry = tmp_path / "cache" / "report-sections" / f"{cache.key(p)}.json"
    assert entry.is_file()
    second = R.build_report(p, **SMALL)
    assert "sections 2 and 3 read from the cache" in second
    for key in ("derivation", "check"):
        assert _section(first, key) == _section(second, key)
    assert cache.key(p.replace(alpha=math.radians(31))) != cache.key(p)
    monkeypatch.setattr(cache, "_code_digest", lambda: "other code")
    assert cache.load(p) is None  # another version of the code: another key
    monkeypatch.undo()
    monkeypatch.setenv("SKEWPEND_CACHE_DIR", str(tmp_path / "cache"))
    numeric_sections_stubbed()
    entry.write_text('{"bodies": {"derivation": 1}}')
    assert cache.load(p) is None
    entry.write_text("not json")
    assert cache.load(p) is None
    # computed again, in this process this time: the serial path gives what the second process gave
    monkeypatch.setattr(R, "PARALLEL", False)
    third = R.build_report(p, **SMALL)
    assert "read from the cache" not in third and "in a second process" not in third
    for key in ("derivation", "check"):
        assert _section(third, key) == _section(first, key)
    assert cache.load(p) is not None  # and stored again


def test_timings_table_has_a_row_for_each_kernel_compiled_in_the_run():
    """Section 10's timings name each kernel compiled in this run and the section that needed it, before the
    total (the compilations are inside the parts' times); no such row when every kernel was loaded."""
    from skewpend.views.report import common

    p = Parameters(**common.DEFAULT_PARAMETERS)
    ctx = common.Context(p, common.DEFAULT_INITIAL_STATE, 20.0, "dop853", None, None, None, None, 10.0, 30.0, (720, 480),
                         181, None, None)
    ctx.timings.update({"simulation": 2.5, "flipmap": 6.0, "total": 12.0})
    loaded = html.unescape(R.section_provenance(ctx))
    assert "compiling" not in loaded and "no kernel was compiled in this run" in loaded
    ctx.compiled = {"a.so": ("the model's kernel", "simulation", 2.25), "b.so": ("the flip-map kernel", "flipmap", 5.5)}
    text = html.unescape(R.section_provenance(ctx))
    rows = re.findall(r"<tr><td>(.*?)</td><td class=num>([0-9.]+)</td></tr>", text)
    names = [name for name, _ in rows]
    assert ("5 · compiling the model's kernel", "2.25") in rows
    assert ("6 · compiling the flip-map kernel", "5.50") in rows
    assert names[-1] == "total"  # the compilations are inside the parts: listed before the total, not added to it
