"""One self-contained HTML report that reads like a worked solution (``skewpend report``).

:func:`build_report` computes everything from the library -- the derivation by rotation tensors
and Lagrange's equations, the check of the planar case against the specification, the normal
modes and their dependence on ``alpha``, a simulation with its figures and a live 3D view, the
comparison with MuJoCo -- and writes one HTML file that opens offline: the mathematics is
typeset by KaTeX, bundled into the file (script, style sheet, fonts as ``data:`` URIs), the
figures are PNG ``data:`` URIs, and the motion is replayed in 3D by three.js (bundled too, the
explorer's scene: :mod:`skewpend.views.frontend`), turnable, from the states the library
computed.  Nothing is fetched: the file has no reference to anything outside itself.

Sections (:func:`~skewpend.views.report.common.sections`): 1. the system (pictures of the reference
configuration and the initial state with the hinge axes, the parameters, the initial state); 2. the
equations of motion step by step as the specification derives them, nonlinear and linearised, in display
form (:mod:`skewpend.symbolic.display`: proved equal to the derivation's, which the numeric code uses
unchanged); 3. the check at ``alpha = 0`` against the specification's planar formulas
(:func:`~skewpend.symbolic.specification.check_planar`, differences by ``sympy.simplify`` when the report
is made); 4. normal modes and their frequencies against ``alpha`` with the internal resonances; 5. a
simulation: figures, energy drift, the motion replayed live in 3D; 6. a flip-time map of starts at rest;
7. the Lyapunov spectrum, Poincare sections, a largest-exponent map and the chaotic fraction over
(alpha, energy); 8. equilibria and nonlinear normal modes; 9. the validation against MuJoCo; 10. how the
report was made: versions, settings, timings.

Every section takes the model and asks it -- its coordinates, its links, the names it answers: a chain
of links gets the same ten sections from the same library calls.  What reads the specification's names
is drawn where the model answers them (:func:`skewpend.views.style.answers_names`): the derivation by
the specification's steps and its check at alpha = 0, the sweep over alpha, the Poincare sections and
the chaos diagram; a chain's equations are derived link by link (displayed up to three links) and
checked against the recursive algorithms, its modes swept over each hinge's tilt.

Sections 2 and 3 are symbolic work (SymPy); on a machine with more than one core a second Python
process computes them while this one simulates and draws (:data:`PARALLEL`; if that process
cannot run, they are computed here).  The file is written atomically (:func:`skewpend.io.atomic_path`):
it appears complete or not at all, also on Ctrl-C, which stops the second process too.
"""

from __future__ import annotations

import os
import sys
import time
from contextlib import suppress
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Union

import numpy as np

from ... import __version__
from ...errors import ParameterError, SkewpendError
from ...progress import stage
from ...symbolic.model import Parameters

from .common import compiled_kernels
from .common import (DEFAULT_PARAMETERS, DEFAULT_INITIAL_STATE, DEFAULT_T_END, MAX_T_END, REPORT_SUFFIXES, SECTIONS, CLIP_SECONDS, CLIP_FPS, CLIP_SIZE, PICTURE_SIZE, FIGURE_DPI, SWEEP_POINTS, VALIDATION_DT, VALIDATION_T_END, VALIDATION_TOL, FLIPMAP_N, FLIPMAP_T_END, CHAOS_LYAPUNOV_T_END, CHAOS_SECTION_LEVELS, CHAOS_SECTION_ORBITS, CHAOS_SECTION_CROSSINGS, CHAOS_MAP_N, CHAOS_MAP_T_END, CHAOS_DIAGRAM, CHAOS_DIAGRAM_LEVELS, FIGURE_DT, FIGURE_MAX_ROWS, esc, inline_math, display_math, prose, fmt_num, fmt_num_tex, fmt_deg, fig_png, rgb_png, data_uri, FIGURE_SLOT, figure_html, live_view_html, number_figures, table_html, facts_html, asset, katex_assets, template, tex_of, array_tex, vector_tex, Context, sections, answers_names)  # noqa: F401
from .orbits import section_orbits
from .analyses import chaos_jobs, mujoco_installed, section_chaos, section_flipmap, section_provenance, section_validation  # noqa: F401
from .derivation import section_check, section_derivation
from .system import LIVE_SLOT, live_figure, section_modes, section_simulation, section_system
from ..frontend import inline_page_scripts

__all__ = ["build_report", "DEFAULT_PARAMETERS", "DEFAULT_INITIAL_STATE", "DEFAULT_T_END", "REPORT_SUFFIXES",
           "SECTIONS", "MAX_T_END", "katex_assets"]


def _require_libraries() -> None:
    """The report draws with Matplotlib (and Pillow): say which is missing before any work starts."""
    import importlib.util

    missing = [name for name, module in (("matplotlib", "matplotlib"), ("Pillow", "PIL"))
               if importlib.util.find_spec(module) is None]
    if missing:
        raise SkewpendError(f"the report needs {', '.join(missing)}: pip install {' '.join(missing)}")


def _check_inputs(params, y0, t_end, method, rtol, atol, dt, max_steps, clip_seconds, fps, clip_size, sweep_points,
                  validate, out):
    from ...io import check_output_path
    from ... import checks
    from ...config import CHAIN_Q0, DEFAULT_RUN
    from ...numeric.simulation import METHODS
    from ...parsing import initial_state, positive_number

    _require_libraries()
    params = checks.numeric_model(Parameters(**DEFAULT_PARAMETERS) if params is None else params, "a report")
    if params.n < 2:
        raise ParameterError(f"a report draws models of two links or more (its maps and paths are over two angles); "
                             f"this one has {params.n}", parameter="links")
    if y0 is None:  # the built-in case's start of each coordinate it names; else turned by CHAIN_Q0, at rest
        start = DEFAULT_RUN["initial"]
        y0 = ([float(start.get(f"{c}0", CHAIN_Q0)) for c in params.coordinates]
              + [float(start.get(f"d{c}0", 0.0)) for c in params.coordinates])
    y = initial_state(y0, params.coordinates)
    t_end = positive_number("t_end", t_end)
    if t_end > MAX_T_END:
        raise ParameterError(f"t_end = {t_end:g} s is longer than a report draws (at most {MAX_T_END:g} s); "
                             "use skewpend simulate --out for long runs")
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
    if sweep_points is not None and (isinstance(sweep_points, bool) or not isinstance(sweep_points, (int, np.integer))
                                     or not 2 <= sweep_points <= 2001):
        raise ParameterError(f"sweep_points must be a whole number from 2 to 2001 (or None: by the model), got {sweep_points!r}")
    if validate is not None and not isinstance(validate, bool):
        raise ParameterError(f"validate must be True, False or None (when MuJoCo is installed), got {validate!r}")
    if validate:
        from ...interop.export import import_mujoco

        import_mujoco()  # a clear error now, not after the work
    if out is not None:
        check_output_path(out, REPORT_SUFFIXES, option="--out")
    return params, tuple(float(v) for v in y), t_end, clip_seconds, fps, (w, h)


#: Compute the symbolic sections in a second process when the machine has more than one core.
PARALLEL = True
#: What each part of the report is, as said when it begins (:func:`skewpend.progress.stage`), in the
#: order it is built: the start of the background work (not counted: it has no section), the
#: numeric sections, sections 2 and 3, then the live view and section 10.
PARTS = {
    "start": "starting the work in the background: sections 2 and 3, the kernels, section 7's ensembles",
    "simulation": "section 5, the simulation",
    "system": "section 1, pictures of the system",
    "modes": "section 4, the normal modes against the hinges' skew",
    "flipmap": "section 6, the flip-time map",
    "orbits": "section 8, equilibria and nonlinear normal modes",
    "validation": "section 9, the comparison with MuJoCo",
    "chaos": "section 7, Lyapunov exponents (and the double pendulum's Poincare sections and chaos diagram)",
    "parallel": "sections 2 and 3, the derivation and its check (SymPy, in a second process)",
    "symbolic": "sections 2 and 3, deriving the equations and checking them (SymPy)",
    "cached": "sections 2 and 3, read from the cache",
    "live": "the live 3D view and section 10",
}
#: Python's thread switch interval [s] while a report is built (restored after; the default is
#: 0.005).  Section 7's ensembles run in worker threads whose compiled calls release the GIL and
#: need it back between calls, while the main thread draws with it; at the default a worker waits up
#: to 5 ms each time, and a core stands idle.  At 0.5 ms, 6 interleaved pairs of warm whole-process
#: reports on 2 cores: wall 0.978x (0.91-1.00) for 1.03x the CPU.
SWITCH_INTERVAL = 0.0005


def _symbolic_sections(params) -> Dict[str, Dict]:
    """Sections 2 and 3 (pure SymPy): ``{"bodies": ..., "notes": ..., "timings": ...}`` (JSON-able)."""
    from types import SimpleNamespace

    ctx = SimpleNamespace(params=params, notes={}, eom=None)
    bodies, timings = {}, {}
    for key, build in (("derivation", section_derivation), ("check", section_check)):
        t0 = time.perf_counter()
        bodies[key] = build(ctx)
        timings[key] = time.perf_counter() - t0
    return {"bodies": bodies, "notes": dict(ctx.notes), "timings": timings}


def _worker_main() -> None:
    """Entry point of the second process: the model as JSON on stdin, the sections as JSON on stdout."""
    import json

    from ...symbolic.model import model_from_mapping

    params = model_from_mapping(json.loads(sys.stdin.read()))
    sys.stdout.write(json.dumps(_symbolic_sections(params)))


class _Background:
    """Sections 2 and 3 computed by ``python -c`` in a child process (started by this process, and
    stopped by it -- by its process id -- if it is still running when the report ends)."""

    def __init__(self, proc) -> None:
        self.proc = proc
        self.error: List[str] = []

    @classmethod
    def start(cls, params) -> Optional["_Background"]:
        import json
        import subprocess

        root = str(Path(__file__).resolve().parents[3])  # the directory holding the package
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


def _build_ahead(params) -> None:
    """Load or compile the model's kernel, then the flip map's, in a daemon thread, while the main
    thread starts on section 1 and the prefetch thread on the chaos kernel: on a first run the
    builds (compiler processes) then run side by side instead of one after the other as sections 5
    and 6 come to them (2 s of a cold report).  A failure is left to the section's own call, which
    says it; in a warm run the thread only loads the libraries."""
    import threading

    from ...analysis.flipmap import flip_kernel
    from ...numeric.kernels import model_kernel

    def build() -> None:
        with suppress(Exception):  # a failure is reported by the section that needs the kernel
            model_kernel(params)
            flip_kernel(params)

    threading.Thread(target=build, name="skewpend-report-kernels", daemon=True).start()


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
    sweep_points: Optional[int] = None,
    validate: Optional[bool] = None,
    command: Optional[str] = None,
) -> Union[Path, str]:
    """Build the report; write it to ``out`` (``.html``/``.htm``, atomically: the file appears
    complete or not at all) and return the path, or return the HTML text when ``out`` is None.

    ``params``: the model, numeric -- :class:`~skewpend.Parameters` (default :data:`DEFAULT_PARAMETERS`)
    or a chain of links (:class:`~skewpend.symbolic.chain.Chain`): every section asks it;
    ``y0 = (phi, psi, dphi, dpsi)``: the simulation's initial state over the model's coordinates
    (default :data:`DEFAULT_INITIAL_STATE`; a chain of other coordinates ``(q1 … qn, dq1 … dqn)``,
    default every link turned by 0.5 rad, at rest); ``t_end`` [s]: its length (at most :data:`MAX_T_END`);
    ``method``, ``rtol``, ``atol``, ``dt``, ``max_steps``: as for :func:`skewpend.simulate`.
    ``clip_seconds``, ``fps``, ``clip_size``: the live 3D view (the first ``clip_seconds`` of the
    motion, at most ``t_end``, replayed from ``fps`` computed states per second, at most 1200, on
    a canvas of ``clip_size`` pixels).  ``sweep_points``: values of each skew (alpha, or a chain's
    tilts) in 0..180 deg for the frequency curves (None: :data:`SWEEP_POINTS` for one skew, fewer a
    hinge for longer chains).  ``validate``: compare with MuJoCo (None: when MuJoCo is
    installed; True: it must be).  ``command``: the command line that made the report, shown in
    section 10.  ``progress(done, total)`` is called as each of the ten parts is finished
    (the seven numeric sections, sections 2 and 3, the live view with section 10, the page); in a
    ``skewpend`` command each part is also said as it begins (:data:`PARTS`,
    :func:`skewpend.progress.stage`: a line per part off a terminal, the live line on one).

    Every argument is checked before any work starts (:class:`~skewpend.ParameterError`).
    """
    switch = sys.getswitchinterval()
    sys.setswitchinterval(min(switch, SWITCH_INTERVAL))
    try:
        return _build_report(params, y0, t_end, method, rtol, atol, dt, max_steps, out, progress, clip_seconds, fps,
                             clip_size, sweep_points, validate, command)
    finally:
        sys.setswitchinterval(switch)


def _build_report(params, y0, t_end, method, rtol, atol, dt, max_steps, out, progress, clip_seconds, fps, clip_size,
                  sweep_points, validate, command) -> Union[Path, str]:
    start = time.perf_counter()
    params, y0, t_end, clip_seconds, fps, clip_size = _check_inputs(
        params, y0, t_end, method, rtol, atol, dt, max_steps, clip_seconds, fps, clip_size, sweep_points, validate, out
    )
    if progress is not None and not callable(progress):
        raise ParameterError("progress must be a callable progress(done, total)")
    ctx = Context(params, y0, t_end, method, rtol, atol, dt, max_steps, min(clip_seconds, t_end), fps, clip_size,
                   None if sweep_points is None else int(sweep_points), validate, command)
    seen = set(compiled_kernels())  # kernels compiled in this process before this report

    def note_compiled(part: str) -> None:
        """Kernels compiled since the last call: by ``part`` (the section just built), except the flip
        and chaos kernels, which only sections 6 and 7 (its ensembles run from the start) compile."""
        for name, (kind, what, seconds) in compiled_kernels().items():
            if name not in seen:
                seen.add(name)
                ctx.compiled[name] = (what, {"flip": "flipmap", "chaos": "chaos"}.get(kind, part), seconds)
    # sections 2 and 3 are symbolic work (SymPy, a few seconds): on a machine with more than one
    # core they are computed by a second Python process while this one simulates and draws.
    # Ctrl-C and SIGTERM are recorded and raised between the sections and the compiled calls, never
    # inside a clean-up that Python would only report (a figure's weak-reference callback, say);
    # the second process is stopped at the signal.
    from ...interrupts import Interrupts

    background: Optional[_Background] = None  # the second process, once started

    def stop_background() -> None:
        ctx.prefetch.cancel()
        if background is not None and background.proc.poll() is None:
            background.proc.kill()

    numeric = {
        "simulation": section_simulation,  # first: section 1's pictures and the animation use its runs
        "system": section_system,
        "modes": section_modes,
        "flipmap": section_flipmap,
        "orbits": section_orbits,
        "validation": section_validation,
        "chaos": section_chaos,  # last: its ensembles (prefetched) run while the others draw
    }
    total = len(numeric) + 3  # the numeric sections, sections 2 and 3, the live view with section 10, the page
    done = 0

    def finished() -> None:  # one more part done
        nonlocal done
        done += 1
        if progress is not None:
            progress(done, total)
    bodies: Dict[str, str] = {}
    from . import cache

    t0 = time.perf_counter()
    cached = cache.load(params)  # sections 2 and 3 made earlier for these parameters by this code
    loaded = time.perf_counter() - t0
    stage(PARTS["start"])
    # drawing and SymPy run seconds between checks: a signal no check took within 0.3 s is raised where it is
    with Interrupts(on_signal=stop_background, escalate_after=0.3) as intr:
        background = _Background.start(params) if cached is None and PARALLEL and (os.cpu_count() or 1) > 1 else None
        try:
            _build_ahead(params)  # the model's and the flip map's kernels: compiled now if not in the cache
            # section 7's ensembles run from now on, while sections 1 to 6 draw
            ctx.prefetch.start(chaos_jobs(ctx))
            for key, build in numeric.items():
                intr.check()
                stage(PARTS[key], done + 1, total)
                t0 = time.perf_counter()
                bodies[key] = build(ctx)
                ctx.timings[key] = time.perf_counter() - t0
                note_compiled(key)
                finished()
            intr.check()
            stage(PARTS["cached" if cached is not None else "parallel" if background is not None else "symbolic"],
                  done + 1, total)
            symbolic = background.result() if background is not None else None
            intr.check()
            if cached is not None:
                symbolic = {**cached, "timings": {"derivation": loaded / 2, "check": loaded / 2}}
                ctx.notes["cached"] = ("sections 2 and 3 read from the cache (computed earlier for these parameters by "
                                       "this skewpend)")
            elif symbolic is None:  # serial, or the second process failed: compute it here
                if background is not None:
                    stage(PARTS["symbolic"], done + 1, total)
                symbolic = _symbolic_sections(params)
            else:
                ctx.notes["parallel"] = "sections 2 and 3 computed by a second process, in parallel"
            if cached is None:
                cache.save(params, symbolic)
        finally:
            ctx.prefetch.cancel()  # a no-op once they are done (an error or Ctrl-C: they stop)
            if background is not None:
                background.stop()
    bodies.update(symbolic["bodies"])
    ctx.notes.update(symbolic["notes"])
    ctx.timings.update(symbolic["timings"])
    finished()
    stage(PARTS["live"], done + 1, total)
    bodies["simulation"] = bodies["simulation"].replace(LIVE_SLOT, live_figure(ctx))
    ctx.timings["total"] = time.perf_counter() - start
    bodies["provenance"] = section_provenance(ctx)
    finished()
    stage(f"writing {Path(out).name}" if out is not None else "assembling the page", done + 1, total)
    return _write(_assemble(ctx, bodies), out, progress, total)


def _write(page: str, out, progress, total: int) -> Union[Path, str]:
    result: Union[Path, str] = page
    if out is not None:
        from ...io import atomic_path

        result = Path(out)
        with atomic_path(result) as tmp:
            tmp.write_bytes(page.encode("utf-8"))
    if progress is not None:
        progress(total, total)
    return result


def _assemble(ctx: Context, bodies: Dict[str, str]) -> str:
    from string import Template

    from ... import schema

    css, js, _ = katex_assets()
    p = ctx.params
    toc = "\n".join(f'    <li><a href="#{key}">{esc(title)}</a></li>' for key, title in sections(p))
    parts = [f'<section class="report-section" id="{key}" aria-labelledby="{key}-title">\n'
             f'<h2 id="{key}-title"><span class="num">{n}</span>{esc(title)}</h2>\n{bodies[key]}\n</section>'
             for n, (key, title) in enumerate(sections(p), 1)]
    if answers_names(p) and p.uses_alpha and p.is_thin_rods:
        bodies_text = f"Two thin rods whose hinge axes are skewed by α = {fmt_deg(p.alpha)}"
    else:
        bodies_text = f"{schema.count_text(p.n, 'rigid bodies').capitalize()} on skewed hinges"
    return Template(template("report.html")).substitute(
        title=f"{p.title.replace('skewed ', '').capitalize()} with skewed hinge axes",
        subtitle=bodies_text + ": the equations of motion derived step by step, checked, analysed and simulated",
        version=esc(__version__),
        katex_css=css,
        report_css=template("report.css"),
        toc=toc,
        body=number_figures("\n".join(parts)),
        footer=esc(f"Made by skewpend {__version__}. This one file holds every figure, the live 3D view (three.js, MIT "
                  "licence), and the script and fonts "
                  "that typeset its mathematics (KaTeX, MIT licence): it opens offline and fetches nothing."),
        katex_js=js,
        render_js=template("render.js"),
        live_js=inline_page_scripts(),
    )
