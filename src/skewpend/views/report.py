"""One self-contained HTML report that reads like a worked solution (``skewpend report``).

:func:`build_report` computes everything from the library -- the derivation by rotation tensors
and Lagrange's equations, the check of the planar case against the specification, the normal
modes and their dependence on ``alpha``, a simulation with its figures and an animation, the
comparison with MuJoCo -- and writes one HTML file that opens offline: the mathematics is
typeset by KaTeX, bundled into the file (script, style sheet, fonts as ``data:`` URIs), the
figures are PNG and the animation MP4 (H.264) ``data:`` URIs.  Nothing is fetched: the file
has no reference to anything outside itself.

Sections:

1. the system -- a picture of the pendulum with both hinge axes (reference configuration and
   initial state), the parameters with their units, the initial state;
2. the equations of motion, step by step as the specification derives them (``P1``, ``e``,
   ``P``, ``omega2``, the velocity of rod 2's centre of mass, its inertia tensor, ``T``, ``Pi``,
   Lagrange's equations), nonlinear and linearised, then with the values of section 1;
   intermediate results in display form (:mod:`skewpend.symbolic.display`: e.g. ``cos(phi + psi)``
   at ``alpha = 0``; proved equal to the derivation's, which the numeric code uses unchanged);
3. the check at ``alpha = 0``: the planar formulas and linear equations of the specification
   (:mod:`skewpend.symbolic.specification`, typed from its text) against the derivation, with
   the differences computed by ``sympy.simplify`` when the report is made
   (:func:`~skewpend.symbolic.specification.check_planar`);
4. normal modes: frequencies, periods, shapes; the frequencies against ``alpha`` with the
   internal resonances;
5. a simulation: figures, energy drift, the animation;
6. which starts flip: a small flip-time map (:func:`skewpend.flip_map`, released at rest), the
   simulation's start marked on it;
7. how chaotic: the Lyapunov spectrum of the simulation's start, Poincare sections at two
   energies, a largest-exponent map, and the chaotic fraction over (alpha, energy);
8. the validation against MuJoCo (or how to install it);
9. how the report was made: versions, settings, timings.

Sections 2 and 3 are symbolic work (SymPy); on a machine with more than one core a second Python
process computes them while this one simulates and draws (:data:`PARALLEL`; if that process
cannot run, they are computed here).  The file is written atomically (:func:`skewpend.io.atomic_path`):
it appears complete or not at all, also on Ctrl-C, which stops the second process too.
"""

from __future__ import annotations

import base64
import html
import io
import math
import os
import platform
import sys
import tempfile
import time
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from .. import __version__
from ..symbolic.layout import equations_fit, equations_tex, layout, linear_tex, numeric, rounded_linear
from ..errors import ParameterError, SkewpendError
from ..symbolic.model import Parameters

__all__ = [
    "build_report",
    "DEFAULT_PARAMETERS",
    "DEFAULT_INITIAL_STATE",
    "DEFAULT_T_END",
    "REPORT_SUFFIXES",
    "SECTIONS",
    "MAX_T_END",
    "katex_assets",
]

#: The built-in case (the README's benchmark case, as ``skewpend simulate`` runs it).
DEFAULT_PARAMETERS = dict(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
DEFAULT_INITIAL_STATE = (1.2, -0.8, 0.0, 0.0)
DEFAULT_T_END = 20.0
#: Longest simulated time a report draws [s] (its figures show every 0.01 s up to 20,000 rows).
MAX_T_END = 1000.0
#: File names a report is written to.
REPORT_SUFFIXES = (".html", ".htm")
#: (id, title) of the sections, in order.
SECTIONS = (
    ("system", "The system"),
    ("derivation", "Equations of motion, step by step"),
    ("check", "Check: the planar case α = 0"),
    ("modes", "Small oscillations: normal modes"),
    ("simulation", "Simulation"),
    ("flipmap", "Which starts flip: the flip-time map"),
    ("chaos", "How chaotic: Lyapunov exponents, Poincaré sections and the skew"),
    ("validation", "Validation against MuJoCo"),
    ("provenance", "How this report was made"),
)
#: Animation: length of the clip [s of motion], frames per second, frame size [px].
CLIP_SECONDS = 10.0
CLIP_FPS = 20.0
CLIP_SIZE = (480, 360)
#: Pictures of section 1 [px].
PICTURE_SIZE = (560, 420)
#: Resolution of the figures [dots per inch].
FIGURE_DPI = 110
#: Sweep of alpha for the frequency curves: 0..180 deg in this many points.
SWEEP_POINTS = 181
#: Validation: MuJoCo's step and horizon, and the agreement required.
VALIDATION_DT = 1e-4
VALIDATION_T_END = 2.0
VALIDATION_TOL = 1e-6
#: The flip-time map of section 6: cells per side and how long each start is followed [s].
FLIPMAP_N = 144
FLIPMAP_T_END = 10.0
#: Section 7: the Lyapunov run [s], the Poincare sections (energies as fractions of the
#: potential's span, orbits, crossings), the largest-exponent map (cells per side, seconds) and
#: the chaos diagram (alphas, energies, starts per cell, seconds).
CHAOS_LYAPUNOV_T_END = 500.0
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


# -- small helpers ----------------------------------------------------------------------------
def _e(text) -> str:
    return html.escape(str(text), quote=True)


def _m(tex: str) -> str:
    """Inline mathematics (typeset in the browser by KaTeX; the LaTeX is the element's text)."""
    return f'<span class="math">{_e(tex)}</span>'


def _md(tex: str) -> str:
    """Display mathematics."""
    return f'<div class="math display">{_e(tex)}</div>'


def _t(text: str) -> str:
    """Prose written in this module with inline mathematics between ``$`` signs (the text
    itself is trusted HTML; the mathematics is escaped into a KaTeX element)."""
    parts = text.split("$")
    if len(parts) % 2 == 0:
        raise ValueError(f"unbalanced $ in {text[:60]!r}")
    return "".join(p if i % 2 == 0 else _m(p) for i, p in enumerate(parts))


def _num(x: float, digits: int = 6) -> str:
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


def _num_tex(x: float, digits: int = 6) -> str:
    s = f"{float(x):.{digits}g}"
    if "e" in s:
        mant, exp = s.split("e")
        return rf"{mant}\times 10^{{{int(exp)}}}"
    return s


def _deg(x: float) -> str:
    return f"{_num(math.degrees(x), 5)}°"


def _png(fig, dpi: int = FIGURE_DPI) -> bytes:
    from .style import style

    buf = io.BytesIO()
    with style():
        fig.savefig(buf, format="png", dpi=dpi, metadata={"Software": f"skewpend {__version__}"})
    fig.clear()
    return buf.getvalue()


def _rgb_png(rgb: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb, "RGB").save(buf, format="PNG", optimize=True)
    return buf.getvalue()


def _data_uri(data: bytes, mime: str) -> str:
    return f"data:{mime};base64," + base64.b64encode(data).decode("ascii")


#: Stands for a figure's number until the page is assembled (figures are numbered in page order).
_FIG = "\x00FIGURE\x00"


def _figure(data: bytes, caption: str, alt: str) -> str:
    """A numbered PNG figure; ``caption`` is HTML."""
    return (
        f'<figure id="figure-{_FIG}"><img src="{_data_uri(data, "image/png")}" alt="{_e(alt)}">'
        f"<figcaption><b>Figure {_FIG}.</b> {caption}</figcaption></figure>"
    )


def _video(data: bytes, caption: str, poster: Optional[bytes], size: Tuple[int, int]) -> str:
    """The MP4 (H.264) clip as a data URI in a looping, muted, autoplaying <video>."""
    poster_attr = f' poster="{_data_uri(poster, "image/png")}"' if poster else ""
    return (
        f'<figure id="figure-{_FIG}"><video controls loop muted autoplay playsinline preload="auto" '
        f'width="{size[0]}" height="{size[1]}"{poster_attr}>'
        f'<source src="{_data_uri(data, "video/mp4")}" type="video/mp4">'
        "Your browser cannot play H.264 video.</video>"
        f"<figcaption><b>Figure {_FIG}.</b> {caption}</figcaption></figure>"
    )


def _number_figures(page: str) -> str:
    count = 0
    out = []
    for i, part in enumerate(page.split(_FIG)):
        if i:
            out.append(str((count // 2) + 1))  # two marks per figure: its id and its caption
            count += 1
        out.append(part)
    return "".join(out)


def _table(head: Sequence[str], rows: Sequence[Sequence[str]], *, numeric: Sequence[int] = (), caption: str = "",
           compact: bool = False) -> str:
    cap = f"<caption>{caption}</caption>" if caption else ""
    th = "".join(f'<th{" class=num" if i in numeric else ""}>{h}</th>' for i, h in enumerate(head))
    body = "".join(
        "<tr>" + "".join(f'<td{" class=num" if i in numeric else ""}>{c}</td>' for i, c in enumerate(r)) + "</tr>"
        for r in rows
    )
    cls = ' class="compact"' if compact else ""
    return f'<div class="table-wrap"><table{cls}>{cap}<thead><tr>{th}</tr></thead><tbody>{body}</tbody></table></div>'


def _facts(items: Sequence[Tuple[str, str]]) -> str:
    return '<dl class="facts">' + "".join(f"<dt>{k}</dt><dd>{v}</dd>" for k, v in items) + "</dl>"


# -- the bundled KaTeX ------------------------------------------------------------------------
def _asset(*parts: str) -> bytes:
    return resources.files(__package__).joinpath(*parts).read_bytes()


def katex_assets() -> Tuple[str, str, str]:
    """``(css, js, version)`` of the bundled KaTeX; the CSS's fonts are inlined as WOFF2 ``data:``
    URIs (the WOFF and TTF alternatives are dropped), so the style sheet references no file."""
    import json
    import re

    source = json.loads(_asset("assets", "katex", "SOURCE.json"))
    css = _asset("assets", "katex", "katex.min.css").decode("utf-8")

    def src(match: "re.Match[str]") -> str:
        urls = re.findall(r"url\(([^)]+)\)\s*format\([\"']?(\w+)[\"']?\)", match.group(1))
        for url, fmt in urls:
            if fmt == "woff2":
                name = url.strip("\"'").rsplit("/", 1)[-1]
                data = _asset("assets", "katex", "fonts", name)
                return "src:url(" + _data_uri(data, "font/woff2") + ') format("woff2")'
        raise SkewpendError(f"bundled KaTeX: no woff2 font in {match.group(0)[:80]}")

    css = re.sub(r"src:([^;}]+)", src, css)
    if re.search(r"url\((?!data:)", css):
        raise SkewpendError("bundled KaTeX: the style sheet still references a file")
    js = _asset("assets", "katex", "katex.min.js").decode("utf-8").replace("</script", "<\\/script")
    return css, js, str(source.get("version", "?"))


def _template(name: str) -> str:
    return _asset("templates", name).decode("utf-8")


# -- LaTeX of derived expressions (the layout engine: skewpend.symbolic.layout) ---------------------
def _tex(expr) -> str:
    from ..symbolic.render import tex

    return tex(expr)


def _np_tex(a: np.ndarray, digits: int = 5) -> str:
    rows = [" & ".join(_num_tex(x, digits) for x in row) for row in np.asarray(a, dtype=float)]
    return r"\begin{bmatrix}" + r" \\ ".join(rows) + r"\end{bmatrix}"


def _vector_tex(v, digits: int = 4) -> str:
    return r"\begin{bmatrix}" + r" \\ ".join(_num_tex(x, digits) for x in v) + r"\end{bmatrix}"


# -- the report -------------------------------------------------------------------------------
@dataclass
class _Context:
    params: Parameters
    y0: Tuple[float, float, float, float]
    t_end: float
    method: str
    rtol: Optional[float]
    atol: Optional[float]
    dt: Optional[float]
    max_steps: Optional[int]
    clip_seconds: float
    fps: float
    clip_size: Tuple[int, int]
    sweep_points: int
    validate: Optional[bool]
    command: Optional[str]
    timings: Dict[str, float] = field(default_factory=dict)
    notes: Dict[str, str] = field(default_factory=dict)
    clip: object = None  # the animation's trajectory (row 0: the initial state)
    video: Optional[bytes] = None
    still: Optional[bytes] = None  # section 1's picture of the initial state (also the video's poster)


def _require_libraries() -> None:
    """The report draws with Matplotlib (and Pillow) and encodes its video with the ffmpeg of the
    imageio-ffmpeg wheel: say which is missing before any work starts."""
    import importlib.util

    missing = [name for name, module in (("matplotlib", "matplotlib"), ("Pillow", "PIL"), ("imageio-ffmpeg", "imageio_ffmpeg"))
               if importlib.util.find_spec(module) is None]
    if missing:
        raise SkewpendError(f"the report needs {', '.join(missing)}: pip install {' '.join(missing)}")


def _check_inputs(params, y0, t_end, method, rtol, atol, dt, max_steps, clip_seconds, fps, clip_size, sweep_points,
                  validate, out):
    from ..io import check_output_path
    from ..numeric.simulation import METHODS
    from ..parsing import initial_state, positive_number

    _require_libraries()
    if params is None:
        params = Parameters(**DEFAULT_PARAMETERS)
    if not isinstance(params, Parameters):
        raise ParameterError(f"params must be skewpend.Parameters, got {type(params).__name__}")
    params.require_numeric("a report")
    y = initial_state(DEFAULT_INITIAL_STATE if y0 is None else y0)
    t_end = positive_number("t_end", t_end)
    if t_end > MAX_T_END:
        raise ParameterError(
            f"t_end = {t_end:g} s is longer than a report draws (at most {MAX_T_END:g} s); "
            "use skewpend simulate --out for long runs"
        )
    if method not in METHODS:
        raise ParameterError(f"unknown method {method!r}; allowed: {', '.join(METHODS)}")
    if method == "dop853" and dt is not None:
        raise ParameterError("dt is the step of rk4 and gauss; dop853 chooses its own steps (set rtol/atol instead)")
    if method != "dop853" and (rtol is not None or atol is not None):
        raise ParameterError(f"rtol and atol are tolerances of dop853; {method} takes fixed steps dt")
    if max_steps is not None and (isinstance(max_steps, bool) or not isinstance(max_steps, (int, np.integer)) or max_steps < 1):
        raise ParameterError(f"max_steps must be a positive whole number, got {max_steps!r}")
    clip_seconds = positive_number("clip_seconds", clip_seconds)
    fps = positive_number("fps", fps)
    if not 1 <= fps <= 60:
        raise ParameterError(f"fps must be between 1 and 60, got {fps:g}")
    if min(clip_seconds, t_end) * fps > 1200:
        raise ParameterError(f"the animation would have {min(clip_seconds, t_end) * fps:.0f} frames; at most 1200 (clip_seconds * fps)")
    try:
        w, h = (int(v) for v in clip_size)
    except (TypeError, ValueError):
        raise ParameterError(f"clip_size must be (width, height) in pixels, got {clip_size!r}") from None
    if w % 2 or h % 2 or not (64 <= w <= 1280 and 64 <= h <= 960):
        raise ParameterError(f"clip_size must be even sizes between 64x64 and 1280x960 pixels, got {clip_size!r}")
    if isinstance(sweep_points, bool) or not isinstance(sweep_points, (int, np.integer)) or not 2 <= sweep_points <= 2001:
        raise ParameterError(f"sweep_points must be a whole number from 2 to 2001, got {sweep_points!r}")
    if validate is not None and not isinstance(validate, bool):
        raise ParameterError(f"validate must be True, False or None (when MuJoCo is installed), got {validate!r}")
    if validate:
        from ..interop.export import import_mujoco

        import_mujoco()  # a clear error now, not after the work
    if out is not None:
        check_output_path(out, REPORT_SUFFIXES, option="--out")
    return params, tuple(float(v) for v in y), t_end, clip_seconds, fps, (w, h)


#: Compute the symbolic sections in a second process when the machine has more than one core.
PARALLEL = True


def _symbolic_sections(params: Parameters) -> Dict[str, Dict]:
    """Sections 2 and 3 (pure SymPy): ``{"bodies": ..., "notes": ..., "timings": ...}`` (JSON-able)."""
    from types import SimpleNamespace

    ctx = SimpleNamespace(params=params, notes={})
    bodies, timings = {}, {}
    for key, build in (("derivation", _section_derivation), ("check", _section_check)):
        t0 = time.perf_counter()
        bodies[key] = build(ctx)
        timings[key] = time.perf_counter() - t0
    return {"bodies": bodies, "notes": dict(ctx.notes), "timings": timings}


def _worker_main() -> None:
    """Entry point of the second process: parameters as JSON on stdin, the sections as JSON on stdout."""
    import json

    params = Parameters.from_mapping(json.loads(sys.stdin.read()))
    sys.stdout.write(json.dumps(_symbolic_sections(params)))


class _Background:
    """Sections 2 and 3 computed by ``python -c`` in a child process (started by this process, and
    stopped by it -- by its process id -- if it is still running when the report ends)."""

    def __init__(self, proc) -> None:
        self.proc = proc
        self.error: List[str] = []

    @classmethod
    def start(cls, params: Parameters) -> Optional["_Background"]:
        import json
        import subprocess

        root = str(Path(__file__).resolve().parent.parent.parent)  # the directory holding the package
        env = dict(os.environ)
        env["PYTHONPATH"] = root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        code = "from skewpend.views.report import _worker_main; _worker_main()"
        try:
            proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, env=env)
            proc.stdin.write(json.dumps(params.to_dict()).encode("utf-8"))
            proc.stdin.close()
            proc.stdin = None  # written: communicate() only reads
        except OSError:
            return None
        return cls(proc)

    def result(self) -> Optional[Dict]:
        """The sections, or None if the child failed (the caller then computes them itself)."""
        import json

        out, err = self.proc.communicate()
        if self.proc.returncode != 0:
            self.error = err.decode("utf-8", "replace").strip().splitlines()[-1:]
            return None
        try:
            return json.loads(out.decode("utf-8"))
        except ValueError:
            return None

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()
        for stream in (self.proc.stdout, self.proc.stderr):
            if stream is not None:
                stream.close()


def build_report(
    params: Optional[Parameters] = None,
    *,
    y0: Optional[Sequence[float]] = None,
    t_end: float = DEFAULT_T_END,
    method: str = "dop853",
    rtol: Optional[float] = None,
    atol: Optional[float] = None,
    dt: Optional[float] = None,
    max_steps: Optional[int] = None,
    out: Optional[Union[str, Path]] = None,
    progress: Optional[Callable[[int, int], None]] = None,
    clip_seconds: float = CLIP_SECONDS,
    fps: float = CLIP_FPS,
    clip_size: Sequence[int] = CLIP_SIZE,
    sweep_points: int = SWEEP_POINTS,
    validate: Optional[bool] = None,
    command: Optional[str] = None,
) -> Union[Path, str]:
    """Build the report; write it to ``out`` (``.html``/``.htm``, atomically: the file appears
    complete or not at all) and return the path, or return the HTML text when ``out`` is None.

    ``params``: numeric :class:`~skewpend.Parameters` (default :data:`DEFAULT_PARAMETERS`);
    ``y0 = (phi, psi, dphi, dpsi)``: the simulation's initial state (default
    :data:`DEFAULT_INITIAL_STATE`); ``t_end`` [s]: its length (at most :data:`MAX_T_END`);
    ``method``, ``rtol``, ``atol``, ``dt``, ``max_steps``: as for :func:`skewpend.simulate`.
    ``clip_seconds``, ``fps``, ``clip_size``: the animation (the first ``clip_seconds`` of the
    motion, at most ``t_end``; at most 1200 frames).  ``sweep_points``: values of alpha in
    0..180 deg for the frequency curves.  ``validate``: compare with MuJoCo (None: when MuJoCo is
    installed; True: it must be).  ``command``: the command line that made the report, shown in
    section 9.  ``progress(done, total)`` is called as each part is finished.

    Every argument is checked before any work starts (:class:`~skewpend.ParameterError`).
    """
    start = time.perf_counter()
    params, y0, t_end, clip_seconds, fps, clip_size = _check_inputs(
        params, y0, t_end, method, rtol, atol, dt, max_steps, clip_seconds, fps, clip_size, sweep_points, validate, out
    )
    if progress is not None and not callable(progress):
        raise ParameterError("progress must be a callable progress(done, total)")
    ctx = _Context(params, y0, t_end, method, rtol, atol, dt, max_steps, min(clip_seconds, t_end), fps, clip_size,
                   int(sweep_points), validate, command)
    # sections 2 and 3 are symbolic work (SymPy, a few seconds): on a machine with more than one
    # core they are computed by a second Python process while this one simulates and draws
    background = _Background.start(params) if PARALLEL and (os.cpu_count() or 1) > 1 else None
    numeric = {
        "simulation": _section_simulation,  # first: section 1's pictures and the animation use its runs
        "system": _section_system,
        "modes": _section_modes,
        "flipmap": _section_flipmap,
        "chaos": _section_chaos,
        "validation": _section_validation,
    }
    total = len(numeric) + 3
    done = 0
    bodies: Dict[str, str] = {}
    try:
        for key, build in numeric.items():
            t0 = time.perf_counter()
            bodies[key] = build(ctx)
            ctx.timings[key] = time.perf_counter() - t0
            done += 1
            if progress is not None:
                progress(done, total)
        symbolic = background.result() if background is not None else None
        if symbolic is None:  # serial, or the second process failed: compute it here
            symbolic = _symbolic_sections(params)
        else:
            ctx.notes["parallel"] = "sections 2 and 3 computed by a second process, in parallel"
    finally:
        if background is not None:
            background.stop()
    bodies.update(symbolic["bodies"])
    ctx.notes.update(symbolic["notes"])
    ctx.timings.update(symbolic["timings"])
    for _ in ("derivation", "check"):
        done += 1
        if progress is not None:
            progress(done, total)
    bodies["simulation"] = bodies["simulation"].replace(_VIDEO_SLOT, _video_figure(ctx))
    ctx.timings["total"] = time.perf_counter() - start
    bodies["provenance"] = _section_provenance(ctx)
    page = _assemble(ctx, bodies)
    result: Union[Path, str] = page
    if out is not None:
        from ..io import atomic_path

        result = Path(out)
        with atomic_path(result) as tmp:
            tmp.write_bytes(page.encode("utf-8"))
    if progress is not None:
        progress(total, total)
    return result


def _assemble(ctx: _Context, bodies: Dict[str, str]) -> str:
    from string import Template

    css, js, _ = katex_assets()
    toc = "\n".join(f'    <li><a href="#{key}">{_e(title)}</a></li>' for key, title in SECTIONS)
    parts = []
    for n, (key, title) in enumerate(SECTIONS, 1):
        parts.append(
            f'<section class="report-section" id="{key}" aria-labelledby="{key}-title">\n'
            f'<h2 id="{key}-title"><span class="num">{n}</span>{_e(title)}</h2>\n{bodies[key]}\n</section>'
        )
    p = ctx.params
    if p.uses_alpha and p.is_thin_rods:
        subtitle = (f"Two thin rods whose hinge axes are skewed by α = {_deg(p.alpha)}: the equations of motion derived "
                    "step by step, checked, analysed and simulated")
    else:
        subtitle = "Two rigid bodies on skewed hinges: the equations of motion derived step by step, checked, analysed and simulated"
    page = Template(_template("report.html")).substitute(
        title="The double pendulum with skewed hinge axes",
        subtitle=subtitle,
        version=_e(__version__),
        katex_css=css,
        report_css=_template("report.css"),
        toc=toc,
        body=_number_figures("\n".join(parts)),
        footer=_e(f"Made by skewpend {__version__}. This one file holds every figure, the video, and the script and fonts "
                  "that typeset its mathematics (KaTeX, MIT licence): it opens offline and fetches nothing."),
        katex_js=js,
        render_js=_template("render.js"),
    )
    return page


# -- section 1: the system ------------------------------------------------------------------------
_UNITS = {"a": "m", "b": "m", "m1": "kg", "m2": "kg", "alpha": "", "g": "m/s²", "c1": "N m s", "c2": "N m s",
          "tau1": "N m", "tau2": "N m"}
_MEANING = {
    "a": "length of rod 1", "b": "length of rod 2", "m1": "mass of rod 1", "m2": "mass of rod 2",
    "alpha": "angle between the hinge axes with the rods hanging", "g": "gravitational acceleration",
    "c1": "viscous damping in hinge 1", "c2": "viscous damping in hinge 2",
    "tau1": "constant torque in hinge 1", "tau2": "constant torque in hinge 2",
}
_SYMBOL_TEX = {"a": "a", "b": "b", "m1": "m_1", "m2": "m_2", "alpha": r"\alpha", "g": "g", "c1": "c_1", "c2": "c_2",
               "tau1": r"\tau_1", "tau2": r"\tau_2", "com1": r"\underline{c}_1", "com2": r"\underline{c}_2",
               "inertia1": r"\underline{\underline{\Theta}}{}^0_1", "inertia2": r"\underline{\underline{\Theta}}{}^0_2",
               "axis1": r"\underline{n}_1", "axis2": r"\underline{e}_0"}
_GENERAL = {
    "com1": ("centre of mass of body 1, in its frame", "m", "rod midpoint (0, a/2, 0)"),
    "com2": ("centre of mass of body 2, in its frame", "m", "rod midpoint (0, b/2, 0)"),
    "inertia1": ("inertia tensor of body 1 about its centre of mass", "kg m²", "thin rod m₁a²/12 (E − jj)"),
    "inertia2": ("inertia tensor of body 2 about its centre of mass", "kg m²", "thin rod m₂b²/12 (E − jj)"),
    "axis1": ("axis of hinge 1", "", "k"),
    "axis2": ("axis of hinge 2 with the rods hanging", "", "e₀ = cos α k + sin α i"),
}


def _unit(unit: str) -> str:
    return f'<span class="unit">{unit}</span>' if unit else ""


def _vec_text(v) -> str:
    return "(" + ", ".join(_num(x, 5) for x in v) + ")"


def _parameter_rows(p: Parameters) -> List[List[str]]:
    rows = []
    for name in ("a", "b", "m1", "m2", "alpha", "g", "c1", "c2", "tau1", "tau2"):
        value = getattr(p, name)
        if name == "alpha":
            if not p.uses_alpha:
                continue
            shown = f"{_deg(value)} = {_num(value)} rad"
        else:
            shown = _num(value)
        rows.append([_m(_SYMBOL_TEX[name]), f"<code>{name}</code>", _MEANING[name], shown, _unit(_UNITS[name])])
    for name, (meaning, unit, default) in _GENERAL.items():
        value = getattr(p, name)
        if value is None:
            shown = f'<span class="note">default: {_e(default)}</span>'
        elif name.startswith("inertia"):
            shown = "<br>".join(_vec_text(r) for r in value)
        else:
            shown = _vec_text(value) + (" (unit vector)" if name.startswith("axis") else "")
        rows.append([_m(_SYMBOL_TEX[name]), f"<code>{name}</code>", meaning, shown, _unit(unit)])
    return rows


def _still(tr) -> bytes:
    """Frame 0 of ``tr`` as drawn by the animation (rods, both hinge axes, the angle between them)."""
    from .animation import FrameRenderer

    r = FrameRenderer(tr, size=PICTURE_SIZE, dpi=100, trail=0.0)
    try:
        r.draw(0)
        return _rgb_png(r.rgb())
    finally:
        r.close()


def _section_system(ctx: _Context) -> str:
    from ..numeric.simulation import simulate

    p, y0 = ctx.params, ctx.y0
    rest = simulate(p, (0.0, 0.0, 0.0, 0.0), 0.01, dt_out=0.01)  # the reference configuration, for its picture
    rest_png = _still(rest)
    ctx.still = _still(ctx.clip)
    thin = p.is_thin_rods
    if p.uses_alpha and p.axis1 is None:
        skew = _t(r"the hinge axes $\underline{k}$ and $\underline{e}_0$ make the angle $\alpha$ = ") + _deg(p.alpha)
    else:
        skew = "the hinge axes are those given in the table below"
    fig_rest = _figure(
        rest_png,
        _t(r"Reference configuration $\varphi = \psi = 0$: both rods hang along $\underline{j}$ (down) and ") + skew
        + ". Green: hinge 1's axis (fixed); magenta: hinge 2's axis; the arc marks the angle between them.",
        "the pendulum hanging at rest, with both hinge axes drawn",
    )
    fig_start = _figure(
        ctx.still,
        _t(r"The initial state of the simulation (section 5): $\varphi_0$ = ") + _deg(y0[0]) + _t(r", $\psi_0$ = ")
        + _deg(y0[1]) + _t(r". The second axis $\underline{e} = \underline{\underline{P}}_1\cdot\underline{e}_0$ has turned with rod 1."),
        "the pendulum in its initial state, with both hinge axes drawn",
    )
    if thin:
        intro = _t(
            r'<p class="lead">A rod hangs from the roof on a cylindrical hinge; a second rod hangs from the end of the first '
            r"on another cylindrical hinge whose axis, when both rods are vertical, makes the angle $\alpha$ with the first "
            r"hinge's axis. Find the equations of motion — and what they predict.</p>"
        )
    else:
        intro = (
            '<p class="lead">Two rigid bodies hang in a chain on two cylindrical hinges whose axes are given below — the '
            "specification's rods generalised to arbitrary bodies and axes. Find the equations of motion — and what they "
            "predict.</p>"
        )
    basis = _t(
        r"<p>Basis $\underline{i}, \underline{j}, \underline{k}$: $\underline{j}$ points <b>down</b> (along both rods when "
        r"they hang), $\underline{k}$ is the axis of the roof hinge, $\underline{i}$ completes the right-handed triple. "
        r"The generalised coordinates are the hinge angles $\varphi$ (hinge 1) and $\psi$ (hinge 2), both zero with the "
        r"rods hanging; gravity acts along $+\underline{j}$. "
        + ("No dissipation unless damping is given.</p>" if not any(getattr(p, k) for k in ("c1", "c2")) else
           "The hinges have viscous damping (below).</p>")
    )
    table = _table(["symbol", "name", "meaning", "value", "unit"], _parameter_rows(p), caption="Parameters (SI units)")
    initial = _table(
        ["", "value", "unit"],
        [
            [_m(r"\varphi_0"), f"{_deg(y0[0])} = {_num(y0[0])} rad", ""],
            [_m(r"\psi_0"), f"{_deg(y0[1])} = {_num(y0[1])} rad", ""],
            [_m(r"\dot\varphi_0"), _num(y0[2]), "rad/s"],
            [_m(r"\dot\psi_0"), _num(y0[3]), "rad/s"],
        ],
        caption="Initial state of the simulation (section 5)",
        compact=True,
    )
    return intro + basis + f'<div class="figure-row">{fig_rest}{fig_start}</div>' + table + initial


# -- section 2: the derivation ---------------------------------------------------------------------------
def _symbolic_model(p: Parameters) -> Tuple[Parameters, bool]:
    """The model the derivation is shown for, and whether it is symbolic: the specification's
    thin rods with every scalar symbolic (damping and torques symbolic where the report's are
    not zero, else 0); general bodies and axes with the report's values."""
    if p.is_thin_rods:
        extra = {k: (None if getattr(p, k) else 0.0) for k in ("c1", "c2", "tau1", "tau2")}
        return Parameters(**extra), True
    return p, False


_P1, _P = r"\underline{\underline{P}}_1", r"\underline{\underline{P}}"


def _step_items(p: Parameters, symbolic: bool, steps: Dict) -> List[Tuple[str, str]]:
    """(title, html) of each step of the derivation, in the specification's order."""
    from ..symbolic.render import LATEX_LABELS as L

    tex = _tex
    n1 = r"\underline{k}" if p.axis1 is None else r"\underline{n}_1"
    rod = "rod" if p.is_thin_rods else "body"
    Rod = rod.capitalize()
    items = []
    rodrigues = (r"\underline{\underline{P}}(\theta,\underline{n}) = \underline{n}\,\underline{n} + (\underline{\underline{E}}"
                 r" - \underline{n}\,\underline{n})\cos\theta + \underline{n} \times \underline{\underline{E}}\,\sin\theta")
    items.append((
        f"Rotation of {rod} 1",
        _t(r"<p>Rodrigues' formula gives the rotation tensor by the angle $\theta$ about the unit axis $\underline{n}$ "
           r"($\underline{\underline{E}}$ the identity):</p>") + _md(rodrigues)
        + _t(f"<p>{Rod} 1 turns by $\\varphi$ about ${n1}$; by components in the basis $\\underline{{i}},\\underline{{j}},\\underline{{k}}$:</p>")
        + _md(layout(L["P1"], 12, steps["P1"], tex, prefix=r"\underline{\underline{P}}(\varphi, " + n1 + ") = ")),
    ))
    if p.axis2 is None:
        e0 = r"\underline{e}_0 = \cos\alpha\,\underline{k} + \sin\alpha\,\underline{i}"
    else:
        e0 = r"\underline{e}_0 = " + _vector_tex(p.axis2)
    items.append((
        "Current axis of the second hinge",
        _t(f"<p>With the rods hanging the second hinge's axis is ${e0}$; it turns with {rod} 1:</p>")
        + _md(layout(L["e"], 10, steps["e"], tex, prefix=_P1 + r" \cdot \underline{e}_0 = ")),
    ))
    items.append((
        f"Rotation of {rod} 2",
        _t(f"<p>{Rod} 2 turns by $\\psi$ about $\\underline{{e}}$ on top of {rod} 1's rotation; as "
           r"$\underline{\underline{P}}(\psi,\underline{e}) = " + _P1 + r"\cdot\underline{\underline{P}}(\psi,\underline{e}_0)\cdot"
           + _P1 + r"^T$:</p>")
        + _md(layout(L["P"], 30, steps["P"], tex, prefix=r"\underline{\underline{P}}(\psi,\underline{e}) \cdot " + _P1
                      + " = " + _P1 + r" \cdot \underline{\underline{P}}(\psi,\underline{e}_0) = ")),
    ))
    items.append((
        f"Angular velocity of {rod} 2",
        _t(r"<p>By the addition of angular velocities, $\underline{\omega}_2 = \underline{\omega}_1 + " + _P1
           + r"\cdot\tilde{\underline{\omega}}_2$ with $\tilde{\underline{\omega}}_2 = \dot\psi\,\underline{e}_0$:</p>")
        + _md(layout(L["omega2"], 14, steps["omega2"], tex, prefix=r"\dot\varphi\," + n1 + r" + \dot\psi\,\underline{e} = ")),
    ))
    c2 = r"\tfrac{b}{2}\,\underline{j}" if p.com2 is None else _vector_tex(p.com2)
    items.append((
        f"Velocity of {rod} 2's centre of mass",
        _t(r"<p>Rod 1 reaches from the pivot to the second hinge, $\underline{a} = " + _P1 + r"\cdot a\,\underline{j}$; "
           f"the centre of mass of {rod} 2 is at $" + _P + r"\cdot\underline{c}_2$ from that hinge, $\underline{c}_2 = "
           + c2 + f"$ in {rod} 2's frame" + (r" (the specification's $\tfrac{1}{2}\underline{b}$)" if p.com2 is None else "")
           + ":</p>")
        + _md(layout(L["v_c"], 30, steps["v_c"], tex, prefix=r"\dot\varphi\," + n1 + r" \times \underline{a} + "
                      r"\underline{\omega}_2 \times (" + _P + r"\cdot\underline{c}_2) = ")),
    ))
    if p.inertia2 is None:
        theta0 = r"\underline{\underline{\Theta}}{}^0_2 = \tfrac{m_2 b^2}{12}(\underline{\underline{E}} - \underline{j}\,\underline{j})"
        extra = (r"; this is the specification's $\underline{\underline{\Theta}}_2 = \tfrac{m_2 b^2}{12}(\underline{\underline{E}} - "
                 r"\tilde{\underline{e}}\,\tilde{\underline{e}})$, $\tilde{\underline{e}} = " + _P + r"\cdot\underline{j}$")
    else:
        theta0 = r"\underline{\underline{\Theta}}{}^0_2 = " + _np_tex(np.array(p.inertia2, dtype=float), 4)
        extra = ""
    items.append((
        f"Inertia tensor of {rod} 2",
        _t(f"<p>About its centre of mass, turned with the {rod}, from ${theta0}$ in its own frame{extra}:</p>")
        + _md(layout(L["Theta2"], 16, steps["Theta2"], tex,
                      prefix=_P + r"\cdot\underline{\underline{\Theta}}{}^0_2\cdot" + _P + "^T = ")),
    ))
    if p.is_thin_rods:
        t1 = r"T_1 = \tfrac{1}{2}\Theta_1\dot\varphi^2$ with $\Theta_1 = \tfrac{m_1 a^2}{3}$ (rod 1 about its hinge)"
    else:
        t1 = (r"T_1 = \tfrac{1}{2}\underline{\omega}_1\cdot\underline{\underline{\Theta}}_1\cdot\underline{\omega}_1 + "
              r"\tfrac{1}{2}m_1\underline{\vartheta}_{c1}^2$")
    items.append((
        "Kinetic energy",
        _t("<p>$" + t1 + r", and $T_2 = \tfrac{1}{2}\underline{\omega}_2\cdot\underline{\underline{\Theta}}_2\cdot"
           r"\underline{\omega}_2 + \tfrac{1}{2} m_2\, \underline{\vartheta}_c\cdot\underline{\vartheta}_c$:</p>")
        + _md(layout("T", 12, steps["T"], tex, prefix="T_1 + T_2 = ")),
    ))
    items.append((
        "Potential energy",
        _t(r"<p>Measured from the hanging position (the specification's $\Pi_2 = m_2 g\,(a + b - \underline{r}_c\cdot"
           r"\underline{j})$ is larger by the constant $m_2 g b/2$, which no equation of motion sees):</p>")
        + _md(layout(r"\Pi", 12, steps["Pi"], tex, prefix=r"\Pi_1 + \Pi_2 = ")),
    ))
    forced = any(getattr(p, k) is None or getattr(p, k) != 0 for k in ("c1", "c2", "tau1", "tau2"))
    q = (r"$Q_i = \tau_i - c_i\,\dot q_i$ (joint torques and viscous damping)" if forced
         else r"$Q_i = 0$ (no dissipation, as in the specification)")
    items.append((
        "Lagrange's equations",
        _t(r"<p>With $q = (\varphi, \psi)$ and the generalised non-potential forces " + q + ":</p>")
        + _md(r"\frac{d}{dt}\frac{\partial T}{\partial \dot{q}_i}-\frac{\partial T}{\partial q_i} = -\frac{\partial \Pi}{\partial q_i}+Q_i")
        + _t(r"<p>$T$ is quadratic in the speeds, so they read $M(q)\,\ddot q = f(q, \dot q)$, the mass matrix $M$ being "
             r"the Hessian of $T$ in the speeds:</p>")
        + _md(layout("M", 3, steps["M"], tex))
        + _md(layout("f", 3, steps["f"], tex)),
    ))
    return items


def _section_derivation(ctx: _Context) -> str:
    from ..symbolic.derivation import derive
    from ..symbolic.display import display_steps

    p = ctx.params
    model, symbolic = _symbolic_model(p)
    eom = derive(model)
    if symbolic:
        steps = display_steps(eom.steps)
    else:  # numbers to 4 significant digits
        steps = {k: numeric(v, 4) for k, v in eom.steps.items()}
    out = []
    if symbolic:
        out.append(_t(
            "<p>The derivation follows the specification: rotation tensors by Rodrigues' formula for the kinematics, "
            "Lagrange's equations for the dynamics. It is written with every parameter symbolic, "
            r"$a, b, m_1, m_2, \alpha, g$" + (", and the damping and torques of section 1" if
                                             any(getattr(model, k) is None for k in ("c1", "c2", "tau1", "tau2")) else "")
            + ", so that each step can be read against the specification; the values of section 1 are put in at the end. "
            "Each intermediate result is shown in the simplest form found, proved equal to the derivation's own "
            "(which the simulation uses).</p>"
        ))
    else:
        out.append(_t(
            "<p>The derivation follows the specification (rotation tensors by Rodrigues' formula, Lagrange's equations) "
            "for the bodies and axes of section 1, with their values; numbers are rounded to 4 significant digits.</p>"
        ))
    items = _step_items(model, symbolic, steps)
    out.append('<ol class="steps">' + "".join(
        f'<li><p class="step-title">{_e(title)}</p>{body}</li>' for title, body in items) + "</ol>")
    tex = _tex  # the steps are in display form (symbolic) or rounded (numbers) already
    out.append("<h3>The equations of motion</h3>")
    if equations_fit(steps["M"]):
        out.append("<p>Written out, the nonlinear equations of motion are</p>")
    else:
        out.append(_t(r"<p>The nonlinear equations of motion, with the entries $M_{mn}$ and $f_m$ of step 9, are</p>"))
    out.append(_md(equations_tex(steps["M"], steps["f"], tex)))
    try:
        lin = eom.linearize()
    except SkewpendError as exc:
        out.append(f'<p class="callout warn">No linearisation about φ = ψ = 0: {_e(exc)}</p>')
    else:
        out.append(_t(
            r"<p>Linearised about the hanging position ($\varphi, \psi$ and their speeds small, first-order terms "
            r"kept), $M_0\,\ddot q + C_0\,\dot q + K_0\,q = 0$:</p>"))
        out.append(_md(linear_tex(lin if symbolic else rounded_linear(lin, 4), tex)))
    if symbolic:
        eom_n = derive(p)
        out.append("<h3>With the values of section 1</h3>")
        out.append("<p>The same equations with the parameters of section 1 (numbers to 5 significant digits):</p>")
        Mn, fn = numeric(eom_n.mass_matrix), numeric(eom_n.forcing)
        out.append(_md(equations_tex(Mn, fn, _tex)))
        if not equations_fit(Mn):
            out.append(_md(layout("M", 3, Mn, _tex)))
            out.append(_md(layout("f", 3, fn, _tex)))
        try:
            lin_n = eom_n.linearize()
        except SkewpendError:
            pass
        else:
            out.append("<p>Linearised:</p>")
            out.append(_md(linear_tex(rounded_linear(lin_n, 5), _tex)))
    ctx.notes["derivation"] = ("the specification's thin rods, every parameter symbolic" if symbolic
                               else "the report's bodies and axes, with their values")
    return "\n".join(out)


# -- section 3: the check at alpha = 0 -----------------------------------------------------------------
def _section_check(ctx: _Context) -> str:
    import sympy as sp

    from ..symbolic.derivation import derive
    from ..symbolic.display import display_form, display_steps
    from ..symbolic.render import LATEX_LABELS as L
    from ..symbolic.specification import check_planar, planar_latex
    from ..symbolic.symbols import SYMBOLS as S

    spec_tex = planar_latex()
    eom0 = derive(Parameters(alpha=0.0))
    lin0 = eom0.linearize()
    checks = {c.key: c for c in check_planar(eom0)}
    steps = display_steps(eom0.steps, keys=("e", "P", "omega2", "v_c", "T", "Pi"))
    v = steps["v_c"]  # shorter to square
    v2 = display_form(sp.expand((v.T * v)[0, 0]), speeds=(S["dphi"], S["dpsi"]))
    ours = {"e": f"{L['e']} = " + _tex(steps["e"]), "P": f"{L['P']} = " + _tex(steps["P"]),
            "omega2": f"{L['omega2']} = " + _tex(steps["omega2"]),
            "v2": r"\underline{\vartheta}_c\cdot\underline{\vartheta}_c = " + _tex(v2),
            "T": "T = " + _tex(steps["T"]), "Pi": r"\Pi = " + _tex(steps["Pi"])}
    blocks = []
    for key, mine in ours.items():
        c = checks[key]
        if key == "Pi":
            line = (r"\Pi_{\text{skewpend}} - \Pi_{\text{spec}} = " + _tex(c.expected)
                    + r"\quad\text{(a constant: the specification's zero level)}")
        else:
            zero = r"\underline{0}" if isinstance(c.difference, sp.MatrixBase) else "0"
            line = r"\text{skewpend} - \text{specification} = " + zero
        verdict = '<span class="verdict ok">✓ identical</span>' if c.identical else '<span class="verdict bad">✗ differs</span>'
        blocks.append(
            f'<li><p class="step-title">{_e(c.title)}</p>'
            f'<p class="note">The specification:</p>{_md(spec_tex[key])}'
            f'<p class="note">This derivation at α = 0:</p>{_md(mine)}'
            f"<p>{_m(line)} &nbsp; {verdict}</p></li>"
        )
    dM, dK = checks["M0"].difference, checks["K0"].difference
    lin_ok = checks["M0"].identical and checks["K0"].identical and checks["C0"].identical
    all_ok = all(c.identical for c in checks.values())
    blocks.append(
        '<li><p class="step-title">The linearised equations of motion</p>'
        '<p class="note">The specification (energies differentiated, first-order terms kept):</p>'
        + _md(spec_tex["linear"])
        + '<p class="note">This derivation at α = 0:</p>'
        + _md(linear_tex(lin0, _tex))
        + "<p>The differences of the matrices, computed by <code>sympy.simplify</code> when this report was made:</p>"
        + _md(r"M_0 - M_0^{\text{spec}} = " + _tex(dM) + r",\qquad K_0 - K_0^{\text{spec}} = " + _tex(dK))
        + ('<p><span class="verdict ok">✓ identical</span></p>' if lin_ok else '<p><span class="verdict bad">✗ differs</span></p>')
        + "</li>"
    )
    ctx.notes["check"] = "every quantity identical" if all_ok else "A DIFFERENCE WAS FOUND"
    verdict = (
        '<p class="callout good"><b>Every quantity agrees.</b> At α = 0 the derivation reproduces the specification\'s '
        "planar formulas and its linear equations exactly: each difference simplifies to zero "
        "(the potential energy's to the constant of its zero level).</p>"
        if all_ok else
        '<p class="callout warn"><b>A difference was found</b> between the derivation at α = 0 and the specification; see below.</p>'
    )
    intro = _t(
        r"<p>The specification checks its method on the particular case $\alpha = 0$: then $\underline{e}_0 = "
        r"\underline{e} = \underline{k}$, both rods turn about $\underline{k}$ and the problem is planar. Each of its "
        "formulas, typed here from its text, stands next to the same quantity from the derivation of section 2 with "
        r"$\alpha = 0$ and the other parameters symbolic"
        + ("" if ctx.params.is_thin_rods else " (the specification's thin rods, not the bodies of this report)")
        + ".</p>"
    )
    return intro + verdict + '<ol class="steps">' + "".join(blocks) + "</ol>"


# -- section 4: normal modes -------------------------------------------------------------------------
def _section_modes(ctx: _Context) -> str:
    from ..analysis.modes import normal_modes, sweep
    from .figures import plot_sweep

    p = ctx.params
    try:
        m = normal_modes(p)
    except SkewpendError as exc:
        ctx.notes["modes"] = "none (see section 4)"
        return (f'<p class="callout warn">No normal modes for these parameters: {_e(exc)}</p>'
                "<p>Normal modes describe small oscillations about a stable hanging equilibrium.</p>")
    out = [_t(
        r"<p>Small oscillations about the hanging position obey the linearised equations $M_0\,\ddot q + C_0\,\dot q + "
        r"K_0\,q = 0$ of section 2; with the values of section 1</p>")]
    mats = r"M_0 = " + _np_tex(m.M) + r"\ \mathrm{kg\,m^2},\qquad K_0 = " + _np_tex(m.K) + r"\ \mathrm{N\,m}"
    if m.damped:
        mats += r",\qquad C_0 = " + _np_tex(m.C) + r"\ \mathrm{N\,m\,s}"
    out.append(_md(mats))
    out.append(_t(
        r"<p>A normal mode $q = v\cos(\omega t - \delta)$ solves $K_0\,v = \omega^2 M_0\,v$: the two values of "
        r"$\omega^2$ are the roots of $\det(K_0 - \omega^2 M_0) = 0$, and the shapes $v$ are normalised with "
        r"$v^T M_0\, v = 1$.</p>"))
    rows = []
    for k in range(2):
        v = m.shapes[:, k]
        ratio = "∞" if not np.isfinite(m.ratios[k]) else _num(m.ratios[k], 5)
        rows.append([str(k + 1), _num(m.frequencies[k]), _num(m.frequencies[k] / (2 * np.pi)), _num(m.periods[k]),
                     f"({_num(v[0], 5)}, {_num(v[1], 5)})", ratio])
    out.append(_table(["mode", "ω [rad/s]", "f [Hz]", "period [s]", "shape (φ, ψ)", "ψ/φ"], rows, numeric=(1, 2, 3, 5),
                      caption="Normal modes (undamped)"))
    beat = "∞ (equal frequencies)" if not np.isfinite(m.beat_period) else f"{_num(m.beat_period)} s"
    out.append(_facts([("frequency ratio ω₂/ω₁", _num(m.frequencies[1] / m.frequencies[0])),
                       ("beat period 2π/(ω₂ − ω₁)", beat)]))
    if m.damped:
        drows = []
        for k in range(2):
            l1, l2 = m.eigenvalue_pairs[k]
            lam = (f"{_num(l1.real)} and {_num(l2.real)} (overdamped)" if m.overdamped[k]
                   else f"{_num(l1.real)} ± {_num(abs(l1.imag))} i")
            drows.append([str(k + 1), lam, _num(m.damped_frequencies[k]), _num(m.damping_ratios[k], 4)])
        out.append(_table(["mode", "eigenvalues λ [1/s]", "damped ω [rad/s]", "damping ratio ζ"], drows,
                          numeric=(2, 3), caption="With the damping of section 1"))
    ctx.notes["modes"] = f"ω = {m.frequencies[0]:.6g}, {m.frequencies[1]:.6g} rad/s"

    out.append("<h3>The frequencies against α</h3>")
    if not p.uses_alpha:
        out.append(
            '<p class="callout warn">Not drawn: hinge 2\'s axis is given explicitly (<code>axis2</code>), so α does not '
            "enter this model and there is nothing to sweep. Without <code>axis2</code> (the skew is then α) the report "
            "shows how the frequencies depend on the skew angle.</p>")
        ctx.notes["sweep"] = "not applicable: axis2 given"
        return "\n".join(out)
    values = np.radians(np.linspace(0.0, 180.0, ctx.sweep_points))
    try:
        sw = sweep(p.replace(alpha=None), "alpha", values)
    except SkewpendError as exc:
        out.append(f'<p class="callout warn">The sweep over α failed: {_e(exc)}</p>')
        ctx.notes["sweep"] = "failed"
        return "\n".join(out)
    fig = plot_sweep(sw)
    ax = fig.axes[0]
    here = math.degrees(p.alpha) % 360.0
    if 0.0 <= here <= 180.0:
        ax.axvline(here, color="#1d7a3e", lw=1.4, ls=":", label=f"this report: α = {here:.4g}°")
        ax.legend(loc="best")
    out.append(_figure(
        _png(fig),
        _t(f"Natural frequencies (top) and the directions of the mode shapes in the $(\\varphi, \\psi)$ plane (bottom) for "
           f"$\\alpha$ from 0 to 180° ({ctx.sweep_points} values), the other parameters as in section 1. Dashed: internal "
           r"resonances $\omega_2 = n\,\omega_1$; dotted green: this report's $\alpha$."),
        "natural frequencies against the skew angle alpha",
    ))
    if sw.resonances:
        items = []
        for r in sw.resonances:
            how = "crossed" if r.crossed else f"approached (ω₂/ω₁ = {_num(r.ratio, 5)})"
            items.append(f"<li><b>{r.order}:1</b> {how} at α = {_deg(r.value)}</li>")
        out.append(f"<p>Internal resonances ω₂/ω₁ = n (n = 1, 2, 3) along the sweep:</p><ul>{''.join(items)}</ul>")
        ctx.notes["sweep"] = ", ".join(f"{r.order}:1 at {math.degrees(r.value):.4g}°" for r in sw.resonances)
    else:
        out.append(f"<p>No internal resonance ω₂/ω₁ ≈ 1, 2 or 3 for α in 0..180° (within {sw.tolerance:g}·n).</p>")
        ctx.notes["sweep"] = "no internal resonance"
    return "\n".join(out)


# -- section 5: simulation ------------------------------------------------------------------------------
#: Where the video goes in section 5's body (its poster, section 1's picture, is made later).
_VIDEO_SLOT = "<!--skewpend:video-->"


def _section_simulation(ctx: _Context) -> str:
    from ..numeric.simulation import simulate
    from . import figures as F
    from .animation import animate
    from .style import settings_text

    p, y0 = ctx.params, ctx.y0
    dt_out = max(FIGURE_DT, ctx.t_end / FIGURE_MAX_ROWS)
    kw: Dict[str, object] = dict(method=ctx.method, rtol=ctx.rtol, atol=ctx.atol, dt=ctx.dt)
    if ctx.max_steps is not None:
        kw["max_steps"] = int(ctx.max_steps)
    if ctx.method != "dop853":  # rows on the integrator's step grid
        step = ctx.dt if ctx.dt is not None else 1e-3
        dt_out = max(step, round(dt_out / step) * step)
    t0 = time.perf_counter()
    tr = simulate(p, y0, ctx.t_end, dt_out=min(dt_out, ctx.t_end), **kw)
    ctx.timings["simulation: integration"] = time.perf_counter() - t0
    st = tr.stats
    if st.get("kernel") == "compiled":
        built = st.get("kernel_build_time")
        kernel = "generated and compiled in this run" + (f" ({built:.2f} s), now cached" if built else "")
    else:
        kernel = "loaded from the cache"
    ctx.notes["kernel"] = kernel
    fin = tr.final_state
    status = ("finished" if tr.success else
              f'<span class="verdict bad">stopped early at t = {_num(tr.t[-1])} s: {_e(tr.message)}</span>')
    out = [_t(
        f"<p>The nonlinear equations of section 2, integrated from the initial state of section 1 over {_num(ctx.t_end)} s "
        f"with {_e(settings_text(tr.method, tr.settings))}, by compiled C generated from the derivation. "
        r"$E$ is the energy, $W$ the work done by damping and torques; $E - W$ is conserved.</p>")]
    out.append(_facts([
        ("status", status),
        ("energy drift", f"{_num(tr.energy_drift, 3)} &nbsp;<span class=\"note\">(largest |E − W − E₀| / max |E| over every row)</span>"),
        ("initial energy E₀", f"{_num(tr.energy[0], 8)} J"),
        ("final state", f"φ = {_deg(fin[0])}, ψ = {_deg(fin[1])}, φ̇ = {_num(fin[2], 5)} rad/s, ψ̇ = {_num(fin[3], 5)} rad/s "
                        f"at t = {_num(tr.t[-1])} s"),
        ("steps", f"{st['steps']} accepted, {st.get('rejected', 0)} rejected, {st['nfev']} evaluations of the equations"),
        ("integration time", f"{st['wall_time'] * 1e3:.2f} ms"),
        ("model code", kernel),
    ]))
    ctx.notes["energy_drift"] = f"{tr.energy_drift:.3e}"
    t0 = time.perf_counter()
    figs = [
        (F.angles_figure, _t(r"The hinge angles $\varphi, \psi$ (unwrapped, degrees) and their speeds against time."),
         "hinge angles and speeds against time"),
        (F.energy_figure, _t(r"Energy error $|E - W - E_0| / \max|E|$ on a log scale; dashed: the reported drift ")
         + _num(tr.energy_drift, 3) + ".", "relative energy error against time"),
        (F.phase_figure, _t(r"Phase portraits $(\varphi, \dot\varphi)$ and $(\psi, \dot\psi)$, angles wrapped to ±180°."),
         "phase portraits"),
        (F.torus_figure, _t(r"The path in configuration space: $(\varphi, \psi)$ wrapped to ±180°, opposite edges "
                            "identified (a torus)."), "path on the configuration torus"),
        (F.tips_figure, _t(r"Paths of both rod ends in 3D; the pendulum hangs down, $z$ is the first hinge axis $\underline{k}$."),
         "3D paths of the rod ends"),
    ]
    for make, caption, alt in figs:
        out.append(_figure(_png(make(tr)), caption, alt))
    ctx.timings["simulation: figures"] = time.perf_counter() - t0

    # the animation: the first clip_seconds of the same motion, one row per frame (dense output)
    t0 = time.perf_counter()
    frame = 1.0 / ctx.fps
    clip_t = max(frame, math.floor(ctx.clip_seconds / frame + 1e-9) * frame)
    clip_kw = {"max_steps": int(ctx.max_steps)} if ctx.max_steps is not None else {}
    ctx.clip = clip = simulate(p, y0, clip_t, dt_out=frame, **clip_kw)
    with tempfile.TemporaryDirectory(prefix="skewpend-report-") as tmp:
        path = Path(tmp) / "clip.mp4"
        animate(clip, path, fps=ctx.fps, speed=1.0, size=ctx.clip_size)
        ctx.video = path.read_bytes()
    ctx.timings["simulation: animation"] = time.perf_counter() - t0
    ctx.notes["clip"] = (f"{_num(clip.t[-1])} s of motion, {clip.t.size} frames at {ctx.fps:g} fps, "
                         f"{ctx.clip_size[0]}×{ctx.clip_size[1]} px, {len(ctx.video) / 1e3:.0f} kB")
    out.append(_VIDEO_SLOT)
    return "\n".join(out)


def _video_figure(ctx: _Context) -> str:
    clip = ctx.clip
    return _video(
        ctx.video,
        f"The first {_num(clip.t[-1])} s of the motion, in real time ({ctx.fps:g} frames per second, H.264): the rods, "
        "both hinge axes (green: hinge 1, magenta: hinge 2, with the angle between them) and the fading trail of rod 2's tip"
        + (" (computed by DOP853, whose dense output gives the states at the frame times)." if ctx.method != "dop853" else "."),
        ctx.still, ctx.clip_size,
    )


# -- section 7: chaos ------------------------------------------------------------------------------------------
def _section_chaos(ctx: _Context) -> str:
    import warnings

    from ..analysis.chaos import chaos_diagram, potential_range
    from ..analysis.lyapunov import lyapunov, lyapunov_map
    from ..analysis.poincare import poincare
    from . import figures as F

    p, y0 = ctx.params, ctx.y0
    out = [_t(
        "<p>Chaos, measured. The <b>Lyapunov exponents</b> are the rates at which nearby motions separate: the state is "
        "integrated together with four tangent vectors — the variational equations "
        r"$\dot v = J(y)\,v$ with the Jacobian $J$ generated from the derivation of section 2, in the same adaptive "
        "DOP853 steps as the state — and every second the vectors are re-orthonormalised (QR), their logarithmic "
        "growths summed (Benettin's method). A positive largest exponent means chaos; without damping and torques "
        r"the spectrum comes in pairs $\pm\lambda$ with two zeros.</p>")]
    notes = []
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        try:
            spec = lyapunov(p, y0, t_end=CHAOS_LYAPUNOV_T_END, throw=False)
        except SkewpendError as exc:
            spec = None
            out.append(f'<p class="callout warn">The Lyapunov spectrum could not be computed: {_e(exc)}</p>')
    if spec is not None:
        fig = F.lyapunov_figure(spec)
        out.append(_figure(_png(fig), _t(
            "Running estimates of the four Lyapunov exponents of the simulation's initial state (section 5), "
            f"over {_num(CHAOS_LYAPUNOV_T_END)} s, QR every {_num(spec.settings['renorm_every'])} s; they settle as the "
            "time grows (the uncertainty is the spread over 10 time windows)."), "Lyapunov exponents against time"))
        facts = [(f"λ{i + 1}", f"{spec.exponents[i]:+.4f} ± {spec.uncertainty[i]:.2g} 1/s") for i in range(spec.k)]
        facts.append(("sum", f"{spec.sum:+.2e} 1/s"))
        facts.append(("work", f"{_count(spec.stats['steps'])} steps in {spec.stats['wall_time']:.2f} s"))
        if spec.status != 0:
            facts.append(("stopped", _e(spec.message)))
        out.append(_facts(facts))
        notes.append(f"Lyapunov {spec.stats['wall_time']:.2f} s")

    conservative = all(getattr(p, k) == 0 for k in ("c1", "c2", "tau1", "tau2"))
    if not conservative:
        out.append(_t("<p class=\"note\">Poincaré sections and the chaos diagram need an energy surface, that is a "
                      "conservative model; with the damping or torques of section 1 they are left out (the Lyapunov "
                      "exponents above include the damping: their sum is the rate of phase-space contraction).</p>"))
        ctx.notes["chaos"] = ", ".join(notes) + "; sections and diagram skipped (not conservative)"
        return "\n".join(out)

    span = potential_range(p)
    out.append(_t(
        "<p>A <b>Poincaré section</b> cuts the motion at fixed energy each time the first rod passes the vertical "
        r"($\varphi = 0$, moving forwards) and plots the second joint's angle and canonical momentum "
        r"$(\psi, p_\psi)$ — coordinates in which the section map preserves area. Regular orbits draw closed curves; "
        "chaotic ones scatter over an area. Each crossing is located on the dense output of the step that made it. "
        f"Left: a low energy, right: a higher one ({CHAOS_SECTION_ORBITS} orbits, up to {CHAOS_SECTION_CROSSINGS} "
        "crossings each).</p>"))
    imgs = []
    for level in CHAOS_SECTION_LEVELS:
        e = level * span
        try:
            sec = poincare(p, e, n_orbits=CHAOS_SECTION_ORBITS, n_crossings=CHAOS_SECTION_CROSSINGS)
        except SkewpendError as exc:
            imgs.append(f'<p class="callout warn">The section at {_num(e, 4)} J could not be made: {_e(exc)}</p>')
            continue
        imgs.append(_figure(_png(F.poincare_figure(sec)), _t(
            f"Section $\\varphi = 0$ at E = {_num(e, 4)} J ({_num(100 * level, 3)} % of the potential's span "
            f"{_num(span, 4)} J): {_count(sec.n_points)} points, energy error at most "
            f"{sec.stats['max_energy_error']:.1e} J."), f"Poincaré section at {e:.3g} J"))
        notes.append(f"section {e:.3g} J {sec.stats['wall_time']:.2f} s")
    out.append('<div class="figure-row">' + "".join(imgs) + "</div>")

    try:
        m = lyapunov_map(p, CHAOS_MAP_N, t_end=CHAOS_MAP_T_END)
        out.append(_figure(_png(F.lyapunov_map_figure(m)), _t(
            f"The largest Lyapunov exponent over {_num(CHAOS_MAP_T_END)} s for starts at rest on a "
            f"{CHAOS_MAP_N}&nbsp;×&nbsp;{CHAOS_MAP_N} grid of $(\\varphi_0, \\psi_0)$ — compare the flip-time map of "
            "section 6: the starts low in the well move regularly (exponent near 0), the wild ones are chaotic."),
            "largest Lyapunov exponent of starts at rest"))
        notes.append(f"map {m.stats['wall_time']:.2f} s")
    except SkewpendError as exc:
        out.append(f'<p class="callout warn">The largest-exponent map could not be made: {_e(exc)}</p>')

    if p.uses_alpha:
        try:
            d = chaos_diagram(p, energy=[level * span for level in CHAOS_DIAGRAM_LEVELS], **CHAOS_DIAGRAM)
        except SkewpendError as exc:
            d = None
            out.append(f'<p class="callout warn">The chaos diagram could not be made: {_e(exc)}</p>')
        if d is not None:
            out.append(_t(
                "<p><b>Does skewing the hinges tame or feed chaos?</b> For each skew angle $\\alpha$ and energy above "
                f"the rest state, {CHAOS_DIAGRAM['samples']} starts spread over the energy surface (on the section "
                "$\\varphi = 0$) are followed for " + _num(CHAOS_DIAGRAM['t_end']) + " s; the fraction whose largest "
                f"exponent exceeds {_num(d.threshold, 3)} 1/s (clearly above the finite-time level of regular motion) "
                "is the chaotic fraction of that energy surface. The other parameters are those of section 1.</p>"))
            out.append(_figure(_png(F.chaos_diagram_figure(d)), _t(
                "Chaotic fraction of the energy surface against $\\alpha$ and the energy above rest. "
                "A larger diagram: <code>skewpend chaos-diagram --out diagram.zarr --plot diagram.png</code>."),
                "chaos diagram over alpha and energy"))
            out.append('<pre class="table">' + _e(d.table()) + "</pre>")
            notes.append(f"diagram {d.stats['wall_time']:.2f} s")
    ctx.notes["chaos"] = ", ".join(notes)
    return "\n".join(out)


# -- section 6: the flip-time map --------------------------------------------------------------------------
def _count(k: int) -> str:
    """A whole number with thin spaces between groups of three digits: ``20 736``."""
    return f"{k:,}".replace(",", "\u2009")


def _section_flipmap(ctx: _Context) -> str:
    import warnings

    from ..analysis.flipmap import flip_map, flip_time
    from . import figures as F
    from .figures import wrap_angle

    p, y0 = ctx.params, ctx.y0
    n, t_end = FLIPMAP_N, FLIPMAP_T_END
    with warnings.catch_warnings(record=True):
        warnings.simplefilter("always")
        try:
            fm = flip_map(p, n, t_end=t_end)
        except SkewpendError as exc:
            ctx.notes["flipmap"] = "could not be made"
            return f'<p class="callout warn">The flip-time map could not be made: {_e(exc)}</p>'
    st = fm.stats
    ctx.notes["flipmap"] = (f"{n} × {n} starts at rest, t_end = {t_end:g} s, DOP853 at rtol = {fm.settings['rtol']:g}, "
                            f"atol = {fm.settings['atol']:g}: {st['flipped']} of {n * n} flip, computed in "
                            f"{st['wall_time']:.2f} s")
    phi_s, psi_s = float(wrap_angle(y0[0])), float(wrap_angle(y0[1]))
    at_rest = y0[2] == 0.0 and y0[3] == 0.0
    margin = F.flipmap_energy_margin(fm)
    forbidden = None if margin is None else margin < 0
    fig = F.flipmap_figure(fm, mark=(phi_s, psi_s), mark_label="start of section 5" + ("" if at_rest else " (its angles)"),
                           forbidden=margin)
    cells = n * n
    flipped, skipped = st["flipped"], st["skipped_energy"]
    n_forbidden = int(np.count_nonzero(forbidden)) if forbidden is not None else skipped
    grey = ("grey: energy forbids any flip, so these starts were not integrated at all — released at rest, the energy "
            + _t(r"$T + V$ with $V = \Pi - \tau\cdot q$ never increases (damping only dissipates), and here it starts "
                 r"below the lowest $V$ on the boundary of the square (−180°, 180°)², which the angles must reach to flip; "))
    if forbidden is None or n_forbidden == 0:
        grey = ""
    caption = (
        _t(r"Flip time of the pendulum released at rest from $(\varphi_0, \psi_0)$ — the first time either hinge angle "
           r"leaves (−180°, 180°) — on a log colour scale (bright: early, dark: late), with $\varphi_0$ across and "
           r"$\psi_0$ up, for the parameters of section 1 (") + f"{n}&nbsp;×&nbsp;{n} starts, followed for {_num(t_end)} s). "
        + f"White: no flip within {_num(t_end)} s; " + grey
        + "red dot: the angles of the simulation's initial state (section 5)"
        + ("." if at_rest else " — which starts with speeds, so its own motion need not follow its cell.")
    )
    out = [_t(
        "<p>The double pendulum is the textbook chaotic mechanical system. Release it at rest from hinge angles "
        r"$(\varphi_0, \psi_0)$ and wait: does a rod go over the top, and when? The <b>flip time</b> is the first time "
        r"either $\varphi$ or $\psi$ leaves (−180°, 180°). Below, each of " + f"{n}&nbsp;×&nbsp;{n} = {_count(cells)}"
        + " starts is one simulation of the equations of section 2 (DOP853 in compiled code generated from the derivation, "
        "several trajectories side by side, each stopped at its flip, located on the dense output): smooth regions where "
        "nearby starts flip alike, and between them the fractal tangle where the outcome depends sensitively on the start."
        "</p>")]
    out.append(_figure(_png(fig), caption, "flip-time map: flip time against the starting hinge angles"))
    facts = [
        ("starts that flip", f"{_count(flipped)} of {_count(cells)} ({_num(100.0 * flipped / cells, 3)} %) within "
                             f"{_num(t_end)} s"),
        ("no flip", f"{_count(cells - flipped)} ({_num(100.0 * (cells - flipped) / cells, 3)} %)"
                    + (f", of which {_count(n_forbidden)} forbidden by energy" if forbidden is not None else "")),
    ]
    if at_rest:
        try:
            one = flip_time(p, phi_s, psi_s, t_end=FLIPMAP_T_END)
            t_flip, joint, never = one.time, (one.which if one.status.ok else -2), one.forbidden
        except SkewpendError:
            t_flip, joint, never = math.nan, -2, False
        if never:
            what = "never flips: energy forbids it"
        elif joint >= 0:
            what = f"flips at t = {_num(t_flip, 5)} s ({'φ' if joint == 0 else 'ψ'}, hinge {joint + 1})"
        elif joint == -1:
            what = f"does not flip within {_num(t_end)} s"
        else:
            what = "could not be computed"
        facts.append(("the start of section 5", f"φ₀ = {_deg(phi_s)}, ψ₀ = {_deg(psi_s)}, at rest: {what}"))
    else:
        facts.append(("the start of section 5", f"φ₀ = {_deg(phi_s)}, ψ₀ = {_deg(psi_s)}, but not at rest "
                                                "(the map is for starts at rest)"))
    how = (f"{_count(st['integrated'])} starts integrated, {_count(st['mirrored'])} mirrored (the map is symmetric "
           f"under (φ₀, ψ₀) → (−φ₀, −ψ₀))" if st["mirrored"] else f"{_count(st['integrated'])} starts integrated")
    how += (f", {_count(skipped)} skipped by the energy bound; {_count(st['steps'])} steps on {st['workers']} "
            f"thread{'s' if st['workers'] != 1 else ''}")
    facts.append(("work", how))
    facts.append(("time to compute the map", f"{st['wall_time']:.2f} s" + (f" (including {st['kernel_build_time']:.2f} s to compile its "
                                                         "kernel, now cached)" if st.get("kernel_build_time") else "")))
    if st.get("failed"):  # (flip_map's warning is caught: said here instead)
        facts.append(("failed", f'<span class="verdict bad">{st["failed"]} starts could not be integrated</span> '
                                "(left white)"))
    out.append(_facts(facts))
    out.append(_t("<p class=\"note\">In Python: <code>skewpend.flip_map(params, 512, t_end=10)</code> gives a larger "
                  "map (a <code>FlipMap</code> with the flip times, the joint that flipped and the settings), "
                  "<code>skewpend.views.figures.flipmap_figure</code> draws it.</p>"))
    return "\n".join(out)


# -- section 8: validation -------------------------------------------------------------------------------
def _mujoco_installed() -> bool:
    import importlib.util

    return importlib.util.find_spec("mujoco") is not None


def _section_validation(ctx: _Context) -> str:
    p, y0 = ctx.params, ctx.y0
    installed = _mujoco_installed()
    if ctx.validate is False or not installed:
        ctx.notes["validation"] = "not run: " + ("MuJoCo is not installed" if not installed else "not asked for")
        why = "MuJoCo is not installed" if not installed else "the comparison was switched off"
        return (
            f'<p class="callout warn"><b>Not run: {why}.</b> To compare with MuJoCo, install it with '
            "<code>pip install 'skewpend[validate]'</code> (or <code>pip install mujoco</code>) and make the report again.</p>"
            "<p>The comparison exports the model as MuJoCo MJCF, simulates it with MuJoCo's RK4 and compares the states with "
            "skewpend's on a common time grid; <code>skewpend validate</code> does the same on the command line.</p>"
        )
    from ..interop.validation import compare_with_mujoco

    horizon = min(VALIDATION_T_END, ctx.t_end)
    try:
        rep = compare_with_mujoco(p, y0, horizon, dt=VALIDATION_DT)
    except SkewpendError as exc:
        ctx.notes["validation"] = "could not be made"
        return f'<p class="callout warn">The comparison with MuJoCo could not be made: {_e(exc)}</p>'
    ok = rep.max_difference <= VALIDATION_TOL
    ctx.notes["validation"] = f"{'AGREE' if ok else 'DISAGREE'}, largest difference {rep.max_difference:.2e}"
    units = {"phi": "rad", "psi": "rad", "dphi": "rad/s", "dpsi": "rad/s"}
    labels = {"phi": r"\varphi", "psi": r"\psi", "dphi": r"\dot\varphi", "dpsi": r"\dot\psi"}
    rows = [[_m(labels[k]), _num(v, 3), units[k]] for k, v in rep.max_abs_diff.items()]
    if ok:
        verdict = (f'<p class="callout good"><span class="verdict ok">AGREE</span> — the largest difference, '
                   f"{_num(rep.max_difference, 3)}, is within the tolerance {_num(VALIDATION_TOL)}.</p>")
    else:
        verdict = (f'<p class="callout warn"><span class="verdict bad">DISAGREE</span> — the largest difference, '
                   f"{_num(rep.max_difference, 3)}, exceeds the tolerance {_num(VALIDATION_TOL)}.</p>")
    return (
        "<p>An independent engine: the model exported as MuJoCo MJCF (full inertia tensors, hinge axes, damping and "
        "torques; thin rods get the tiny axial inertia MuJoCo needs, in both models) is simulated by MuJoCo "
        f"{_e(rep.mujoco_version)} with RK4 at dt = {_num(rep.dt)} s, and by skewpend with DOP853 at rtol = atol = "
        f"10<sup>−12</sup>, from the initial state of section 1 over {_num(rep.t_end)} s; the states are compared at "
        f"{rep.samples} common times.</p>"
        + verdict
        + _table(["state", "largest |skewpend − MuJoCo|", "unit"], rows, numeric=(1,), caption="Largest differences",
                 compact=True)
    )


# -- section 9: provenance -------------------------------------------------------------------------------
def _versions() -> List[Tuple[str, str]]:
    from importlib import metadata

    out = [("skewpend", __version__), ("Python", platform.python_version())]
    for name in ("numpy", "sympy", "scipy", "matplotlib", "imageio-ffmpeg", "mujoco"):
        try:
            out.append((name, metadata.version(name)))
        except metadata.PackageNotFoundError:
            out.append((name, "not installed"))
    return out


def _section_provenance(ctx: _Context) -> str:
    from .style import settings_text

    _, _, katex_version = katex_assets()
    rows = [[_e(k), _e(v)] for k, v in _versions() + [("KaTeX (bundled)", katex_version)]]
    sim = {"t_end": ctx.t_end, "rtol": ctx.rtol, "atol": ctx.atol, "dt": ctx.dt}
    settings = [
        ("simulation", _e(settings_text(ctx.method, {k: v for k, v in sim.items() if v is not None}))
         + " (figures: rows every " + _num(max(FIGURE_DT, ctx.t_end / FIGURE_MAX_ROWS)) + " s)"),
        ("animation", _e(ctx.notes.get("clip", ""))),
        ("α sweep", _e(f"0 to 180° in {ctx.sweep_points} values: {ctx.notes.get('sweep', '')}")),
        ("flip-time map", _e(ctx.notes.get("flipmap", ""))),
        ("chaos", _e(ctx.notes.get("chaos", ""))),
        ("validation", _e(f"MuJoCo RK4, dt = {VALIDATION_DT:g} s, {min(VALIDATION_T_END, ctx.t_end):g} s, tolerance "
                          f"{VALIDATION_TOL:g}: {ctx.notes.get('validation', '')}")),
        ("derivation shown for", _e(ctx.notes.get("derivation", ""))),
        ("check at α = 0", _e(ctx.notes.get("check", ""))),
        ("model code", _e(ctx.notes.get("kernel", ""))),
        ("platform", _e(f"{platform.system()} {platform.machine()}, {platform.python_implementation()} {platform.python_version()}")),
    ]
    if ctx.command:
        settings.insert(0, ("command", f"<code>{_e(ctx.command)}</code>"))
    labels = [
        ("system", "1 · the system: pictures"),
        ("derivation", "2 · derivation and display forms"),
        ("check", "3 · check at α = 0"),
        ("modes", "4 · normal modes and the α sweep"),
        ("simulation", "5 · simulation, all of it"),
        ("simulation: integration", "5 · integration"),
        ("simulation: figures", "5 · figures"),
        ("simulation: animation", "5 · animation"),
        ("flipmap", "6 · flip-time map"),
        ("chaos", "7 · chaos: exponents, sections, diagram"),
        ("validation", "8 · validation against MuJoCo"),
        ("total", "total"),
    ]
    trows = [[_e(label), f"{ctx.timings[key]:.2f}"] for key, label in labels if key in ctx.timings]
    return (
        "<h3>Software</h3>" + _table(["package", "version"], rows, compact=True)
        + "<h3>Settings</h3>" + _facts(settings)
        + "<h3>Timings</h3>"
        + _table(["part", "seconds"], trows, numeric=(1,), compact=True,
                 caption="Wall time of each part in this run" + (
                     " (sections 2 and 3 in a second process, in parallel with the others)" if ctx.notes.get("parallel")
                     else ""))
        + "<p class=\"note\">Everything here was computed when this file was made; opening it computes nothing but the "
          "typesetting of the mathematics.</p>"
    )
