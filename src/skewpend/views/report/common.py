"""What every section of the report shares: its settings (the built-in case, the sizes and
lengths of its runs), the small HTML helpers (escaping, mathematics for KaTeX, figures, tables),
the bundled KaTeX, the LaTeX of expressions, and the context the sections fill."""

from __future__ import annotations

import base64
import html
import io
import math
import threading
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Callable, Dict, Optional, Sequence, Tuple

import numpy as np

from ... import __version__
from ...config import DEFAULT_RUN, reference_state
from ...errors import SkewpendError
from ...progress import detail
from ...symbolic.model import Parameters
from ..style import answers_names

#: The built-in case (the README's benchmark case, as ``skewpend simulate`` runs it).
DEFAULT_PARAMETERS = dict(DEFAULT_RUN["parameters"])
DEFAULT_INITIAL_STATE = reference_state()
DEFAULT_T_END = float(DEFAULT_RUN["simulation"]["t_end"])
#: Longest simulated time a report draws [s] (its figures show every 0.01 s up to 20,000 rows).
MAX_T_END = 1000.0
#: File names a report is written to.
REPORT_SUFFIXES = (".html", ".htm")


def sections(model) -> Tuple[Tuple[str, str], ...]:
    """(id, title) of the report's sections for ``model``, in order: the same ten for every model, two titles
    naming what the model provides -- the specification's check at alpha = 0 and its planar pictures of chaos
    for a model that answers the specification's names (:func:`~skewpend.views.style.answers_names`), the
    check of two derivations and the Lyapunov spectrum otherwise."""
    named = answers_names(model)
    return (
        ("system", "The system"),
        ("derivation", "Equations of motion, step by step"),
        ("check", "Check: the planar case α = 0" if named else "Check: two derivations of one model"),
        ("modes", "Small oscillations: normal modes"),
        ("simulation", "Simulation"),
        ("flipmap", "Which starts flip: the flip-time map"),
        ("chaos", "How chaotic: Lyapunov exponents, Poincaré sections and the skew" if named
         else "How chaotic: the Lyapunov spectrum"),
        ("orbits", "Beyond small oscillations: equilibria and nonlinear normal modes"),
        ("validation", "Validation against MuJoCo"),
        ("provenance", "How this report was made"),
    )


#: The sections of the built-in case's report.
SECTIONS = sections(Parameters(**DEFAULT_PARAMETERS))
#: Animation: length of the clip [s of motion], frames per second, frame size [px].
CLIP_SECONDS = 10.0
CLIP_FPS = 30.0
CLIP_SIZE = (720, 480)
#: Pictures of section 1 [px].
PICTURE_SIZE = (560, 420)
#: Resolution of the figures [dots per inch].
FIGURE_DPI = 110
#: Sweep of each hinge's skew (alpha, or a chain's tilts) for the frequency curves: 0..180 deg in this many
#: points for one skew; a sweep a hinge takes fewer past two links (SWEEP_POINTS_BY_LINKS, else LONG_SWEEP_POINTS).
SWEEP_POINTS = 181
SWEEP_POINTS_BY_LINKS = {3: 61}
LONG_SWEEP_POINTS = 31
#: The longest chain whose equations the report derives and displays by SymPy link by link (four links take
#: 45 s and expressions of thousands of terms; the recursive algorithms serve any length).
SYMBOLIC_MAX_LINKS = 3
#: Validation: MuJoCo's step and horizon, and the agreement required.
VALIDATION_DT = 1e-4
VALIDATION_T_END = 2.0
VALIDATION_TOL = 1e-6
#: The flip-time map of section 6: cells per side and how long each start is followed [s]; past two links
#: fewer cells (FLIPMAP_N_BY_LINKS, else LONG_FLIPMAP_N: the work grows with the links, 16 s for 96 x 96 at six).
FLIPMAP_N = 144
FLIPMAP_N_BY_LINKS = {3: 96}
LONG_FLIPMAP_N = 64
FLIPMAP_T_END = 10.0
#: Section 7: the Lyapunov run [s], the Poincare sections (energies as fractions of the
#: potential's span, orbits, crossings), the largest-exponent map (cells per side, seconds) and
#: the chaos diagram (alphas, energies, starts per cell, seconds).
CHAOS_LYAPUNOV_T_END = 500.0
#: ... past three links (2 n tangent vectors) [s]
LONG_LYAPUNOV_T_END = 200.0
CHAOS_SECTION_LEVELS = (0.15, 0.5)
CHAOS_SECTION_ORBITS = 24
CHAOS_SECTION_CROSSINGS = 300
CHAOS_MAP_N = 24
CHAOS_MAP_T_END = 50.0
CHAOS_DIAGRAM = dict(n_alpha=7, samples=12, t_end=80.0)
#: ... at these fractions of the potential's span (denser where chaos sets in)
CHAOS_DIAGRAM_LEVELS = (0.1, 0.17, 0.25, 0.35, 0.5, 0.75, 1.0)
#: Rows drawn by the figures: every FIGURE_DT seconds, at most FIGURE_MAX_ROWS.
FIGURE_DT = 0.01
FIGURE_MAX_ROWS = 20000


def by_links(n: int, first: float, table: Dict[int, float], long: float):
    """A size of the report's work for a model of ``n`` links: ``first`` up to two links, ``table[n]``, else
    ``long`` (each link multiplies the work of a run)."""
    return first if n <= 2 else table.get(n, long)


# -- small helpers ----------------------------------------------------------------------------
def telling(what: str, unit: str = "") -> Callable[[float, float], None]:
    """A ``progress(done, total)`` for a library call inside a section: its progress said as the section's
    sub-step on the live line (``what: 40 of 128 unit``; issue 51: no silence over 2 s on a terminal)."""
    suffix = f" {unit}" if unit else ""

    def told(done, total, label=None):
        detail(f"{what}: {float(done):.4g} of {float(total):.4g}{suffix}" if label is None else f"{what}: {label}")

    return told


def esc(text) -> str:
    return html.escape(str(text), quote=True)


def inline_math(tex: str) -> str:
    """Inline mathematics (typeset in the browser by KaTeX; the LaTeX is the element's text)."""
    return f'<span class="math">{esc(tex)}</span>'


def display_math(tex: str) -> str:
    """Display mathematics."""
    return f'<div class="math display">{esc(tex)}</div>'


def prose(text: str) -> str:
    """Prose written in this module with inline mathematics between ``$`` signs (the text
    itself is trusted HTML; the mathematics is escaped into a KaTeX element)."""
    parts = text.split("$")
    if len(parts) % 2 == 0:
        raise ValueError(f"unbalanced $ in {text[:60]!r}")
    return "".join(p if i % 2 == 0 else inline_math(p) for i, p in enumerate(parts))


def fmt_num(x: float, digits: int = 6) -> str:
    """A number for the text: ``1``, ``0.8``, ``9.81``, ``1.83×10⁻¹¹`` (HTML)."""
    x = float(x)
    if x == 0:
        return "0"
    if not math.isfinite(x):
        return "∞" if x > 0 else ("−∞" if x < 0 else "not a number")
    s = f"{x:.{digits}g}"
    if "e" in s:
        mant, exp = s.split("e")
        return f"{mant.replace('-', '−')}×10<sup>{str(int(exp)).replace('-', '−')}</sup>"
    return s.replace("-", "−")


def fmt_num_tex(x: float, digits: int = 6) -> str:
    s = f"{float(x):.{digits}g}"
    if "e" in s:
        mant, exp = s.split("e")
        return rf"{mant}\times 10^{{{int(exp)}}}"
    return s


def fmt_deg(x: float) -> str:
    return f"{fmt_num(math.degrees(x), 5)}°"


#: zlib level of the report's PNGs: 3 writes them in about half the time of Pillow's default 6 (and a
#: fifth of ``optimize=True``) for files a few per cent larger.
PNG_LEVEL = 3


def fig_png(fig, dpi: int = FIGURE_DPI) -> bytes:
    """The figure as PNG bytes (:func:`skewpend.views.figures.base.print_figure`); the figure is cleared."""
    from ..figures.base import print_figure

    buf = io.BytesIO()
    print_figure(fig, buf, "png", dpi, {"Software": f"skewpend {__version__}"}, pil_kwargs={"compress_level": PNG_LEVEL})
    fig.clear()
    return buf.getvalue()


def rgb_png(rgb: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb, "RGB").save(buf, format="PNG", compress_level=PNG_LEVEL)
    return buf.getvalue()


def data_uri(data: bytes, mime: str) -> str:
    return f"data:{mime};base64," + base64.b64encode(data).decode("ascii")


#: Stands for a figure's number until the page is assembled (figures are numbered in page order).
FIGURE_SLOT = "\x00FIGURE\x00"


def figure_html(data: bytes, caption: str, alt: str) -> str:
    """A numbered PNG figure; ``caption`` is HTML."""
    return (
        f'<figure id="figure-{FIGURE_SLOT}"><img src="{data_uri(data, "image/png")}" alt="{esc(alt)}">'
        f"<figcaption><b>Figure {FIGURE_SLOT}.</b> {caption}</figcaption></figure>"
    )


def live_view_html(data: dict, caption: str, poster: Optional[bytes], size: Tuple[int, int]) -> str:
    """The live 3D replay of a computed motion (``web/replay.js`` on ``web/scene.js``): a canvas of
    ``size`` pixels with play/pause and a time slider, the states to replay as JSON (``t``,
    ``tips``, ``axes``, ``size``: numbers only, written exactly), and ``poster`` (the start) shown
    until the view draws -- and instead of it where a browser has no WebGL or no JavaScript."""
    import json

    w, h = size
    payload = json.dumps(data, separators=(",", ":"), allow_nan=False)
    poster_html = (f'<img class="live-poster" src="{data_uri(poster, "image/png")}" alt="the pendulum at the start of the motion">'
                   if poster else "")
    return (
        f'<figure id="figure-{FIGURE_SLOT}" class="live-view" style="max-width: {w}px">'
        f'<div class="live-stage">{poster_html}'
        f'<canvas width="{w}" height="{h}" style="aspect-ratio: {w} / {h}" '
        'aria-label="the motion in 3D: drag to turn the view, scroll to zoom"></canvas></div>'
        '<div class="live-controls"><button type="button" class="live-play" aria-pressed="true">Pause</button>'
        '<input type="range" class="live-time" min="0" max="0" step="1" value="0" aria-label="frame of the motion">'
        '<output class="live-clock">t = 0.00 s</output><span class="live-hint">drag: turn · scroll: zoom</span></div>'
        '<p class="live-note"></p>'
        f'<script type="application/json" class="live-data">{payload}</script>'
        f"<figcaption><b>Figure {FIGURE_SLOT}.</b> {caption}</figcaption></figure>"
    )


def number_figures(page: str) -> str:
    first, *rest = page.split(FIGURE_SLOT)
    return first + "".join(f"{i // 2 + 1}{part}" for i, part in enumerate(rest))  # two marks a figure: id, caption


def table_html(head: Sequence[str], rows: Sequence[Sequence[str]], *, numeric: Sequence[int] = (), caption: str = "",
           compact: bool = False) -> str:
    cap = f"<caption>{caption}</caption>" if caption else ""
    th = "".join(f'<th{" class=num" if i in numeric else ""}>{h}</th>' for i, h in enumerate(head))
    body = "".join(
        "<tr>" + "".join(f'<td{" class=num" if i in numeric else ""}>{c}</td>' for i, c in enumerate(r)) + "</tr>"
        for r in rows
    )
    cls = ' class="compact"' if compact else ""
    return f'<div class="table-wrap"><table{cls}>{cap}<thead><tr>{th}</tr></thead><tbody>{body}</tbody></table></div>'


def facts_html(items: Sequence[Tuple[str, str]]) -> str:
    return '<dl class="facts">' + "".join(f"<dt>{k}</dt><dd>{v}</dd>" for k, v in items) + "</dl>"


# -- the bundled KaTeX ------------------------------------------------------------------------
def asset(*parts: str) -> bytes:
    return resources.files("skewpend.views").joinpath(*parts).read_bytes()


def katex_assets() -> Tuple[str, str, str]:
    """``(css, js, version)`` of the bundled KaTeX; the CSS's fonts are inlined as WOFF2 ``data:``
    URIs (the WOFF and TTF alternatives are dropped), so the style sheet references no file."""
    import json
    import re

    source = json.loads(asset("assets", "katex", "SOURCE.json"))
    css = asset("assets", "katex", "katex.min.css").decode("utf-8")

    def src(match: "re.Match[str]") -> str:
        urls = re.findall(r"url\(([^)]+)\)\s*format\([\"']?(\w+)[\"']?\)", match.group(1))
        for url, fmt in urls:
            if fmt == "woff2":
                name = url.strip("\"'").rsplit("/", 1)[-1]
                data = asset("assets", "katex", "fonts", name)
                return "src:url(" + data_uri(data, "font/woff2") + ') format("woff2")'
        raise SkewpendError(f"bundled KaTeX: no woff2 font in {match.group(0)[:80]}")

    css = re.sub(r"src:([^;}]+)", src, css)
    if re.search(r"url\((?!data:)", css):
        raise SkewpendError("bundled KaTeX: the style sheet still references a file")
    js = asset("assets", "katex", "katex.min.js").decode("utf-8").replace("</script", "<\\/script")
    return css, js, str(source.get("version", "?"))


def template(name: str) -> str:
    return asset("templates", name).decode("utf-8")


# -- LaTeX of derived expressions (the layout engine: skewpend.symbolic.layout) ---------------------
def tex_of(expr) -> str:
    from ...symbolic.render import tex

    return tex(expr)


def array_tex(a: np.ndarray, digits: int = 5) -> str:
    a = np.asarray(a, dtype=float)
    scale = float(np.max(np.abs(a))) if a.size else 0.0
    a = np.where(np.abs(a) <= 1e-13 * scale, 0.0, a)  # rounding's -0 and 1e-17 entries: exact zeros of the model
    rows = [" & ".join(fmt_num_tex(x, digits) for x in row) for row in a]
    return r"\begin{bmatrix}" + r" \\ ".join(rows) + r"\end{bmatrix}"


def vector_tex(v, digits: int = 4) -> str:
    return r"\begin{bmatrix}" + r" \\ ".join(fmt_num_tex(x, digits) for x in v) + r"\end{bmatrix}"


# -- the report -------------------------------------------------------------------------------
def compiled_kernels() -> Dict[str, Tuple[str, str, float]]:
    """The model's libraries compiled (not loaded from the cache) in this process so far, in the
    order they were made: ``{file name: (kind, what it is, seconds to build)}`` with kind ``"flip"``,
    ``"chaos"``, ``"taylor"`` or ``"model"`` -- for the timings of section 10."""
    from ...numeric import kernels

    out: Dict[str, Tuple[str, str, float]] = {}
    for kernel in list(getattr(kernels, "_LOADED", {}).values()):
        if getattr(kernel, "origin", None) != "compiled":
            continue
        name = Path(kernel.path).name
        stem = name.split(".")[0]
        if stem.endswith("_flip"):
            kind, what = "flip", "the flip-map kernel"
        elif stem.endswith("_chaos"):
            kind, what = "chaos", "the chaos kernel"
        elif "_taylor" in stem:
            kind, what = "taylor", f"the Taylor kernel of order {getattr(kernel, 'order', '?')}"
        else:
            kind, what = "model", "the model's kernel"
        out[name] = (kind, what, float(kernel.build_time))
    return out


class Prefetch:
    """Computations of later sections started at once in a daemon thread, so that their compiled
    work (which releases the GIL, on every core) overlaps the main thread's drawing of the earlier
    sections.  ``start({name: compute(check)})`` runs them in order; ``result(name, compute)``
    waits for one and returns its value (or raises its exception) -- or computes it now if it was
    never started or was cancelled; ``cancel()`` (at Ctrl-C or SIGTERM) makes the running one stop at
    its next progress call, and the main thread's own computation then meets the signal."""

    class Cancelled(Exception):
        pass

    def __init__(self) -> None:
        self._done: Dict[str, threading.Event] = {}
        self._out: Dict[str, Tuple[bool, object]] = {}
        self._stop = threading.Event()

    def check(self, *_args) -> None:
        if self._stop.is_set():
            raise Prefetch.Cancelled()

    def start(self, jobs: Dict[str, Callable]) -> None:
        for name in jobs:
            self._done[name] = threading.Event()

        def run() -> None:
            for name, compute in jobs.items():
                try:
                    self.check()
                    self._out[name] = (True, compute(self.check))
                except BaseException as exc:  # delivered to whoever asks for it
                    self._out[name] = (False, exc)
                self._done[name].set()

        threading.Thread(target=run, name="skewpend-report-prefetch", daemon=True).start()

    def result(self, name: str, compute: Callable):
        if name not in self._done:
            return compute(None)
        while not self._done[name].wait(0.05):  # in slices: Ctrl-C is seen at once
            pass
        ok, value = self._out[name]
        if isinstance(value, Prefetch.Cancelled):  # stopped by a signal: the main thread's own call raises it
            return compute(None)
        if not ok:
            raise value  # type: ignore[misc]
        return value

    def cancel(self) -> None:
        self._stop.set()


@dataclass
class Context:
    params: Parameters  # the model: the double pendulum's Parameters or a chain of links
    y0: Tuple[float, ...]
    t_end: float
    method: str
    rtol: Optional[float]
    atol: Optional[float]
    dt: Optional[float]
    max_steps: Optional[int]
    clip_seconds: float
    fps: float
    clip_size: Tuple[int, int]
    sweep_points: Optional[int]  # None: by the model (SWEEP_POINTS for one skew, fewer a hinge past two links)
    validate: Optional[bool]
    command: Optional[str]
    timings: Dict[str, float] = field(default_factory=dict)
    notes: Dict[str, str] = field(default_factory=dict)
    clip: object = None  # the animation's trajectory (row 0: the initial state)
    live: Optional[dict] = None  # the live view's frames: t, tips, axes, size
    still: Optional[bytes] = None  # section 1's picture of the initial state (also the live view's poster)
    compiled: Dict[str, Tuple[str, str, float]] = field(default_factory=dict)  # kernels compiled: (what, part, s)
    prefetch: Prefetch = field(default_factory=Prefetch)
    eom: object = None  # the equations derived link by link (section 2), compared in section 3
