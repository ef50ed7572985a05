"""The identification report: one self-contained HTML file for :func:`skewpend.identify` (issue 27).

:func:`write_identification_report` writes what an identification found, in the look of
``skewpend report`` (its style sheet, its tables and figures): what was fitted and how, the base
parameters with their 95 % intervals and expressions, the ratios a free swing determines, what
the data cannot determine, the skew angle (a chain's hinge tilt), the held-out prediction per piece beside the start's
(``params0``), the figure (:func:`~skewpend.views.figures.identification.plot_identification`,
a PNG ``data:`` URI) and how to use the fitted model.  No mathematics is typeset (no KaTeX): the
expressions are the library's text.  Nothing is fetched: the file references nothing outside
itself; it is written atomically (:func:`skewpend.io.atomic_path`).
"""

from __future__ import annotations

import math
import platform
import time
from pathlib import Path
from typing import List, Sequence, Tuple, Union

import numpy as np

from ... import __version__
from .common import REPORT_SUFFIXES, data_uri, esc, facts_html, fmt_num, table_html, template

__all__ = ["write_identification_report", "identification_html", "IDENTIFICATION_SECTIONS", "FIGURE_DPI"]

#: (id, title) of the sections, in order.
IDENTIFICATION_SECTIONS = (
    ("fit", "What was fitted"),
    ("parameters", "The base parameters"),
    ("ratios", "Ratios: what a free swing determines"),
    ("undetermined", "What the data cannot determine"),
    ("skew", "The skew angle or a hinge's tilt"),
    ("heldout", "Prediction of held-out motion"),
    ("figure", "Figure"),
    ("use", "How to use it"),
    ("provenance", "How this report was made"),
)
#: Resolution of the embedded figure [dots per inch]: 1600 x 1000 px.
FIGURE_DPI = 150

#: Styles added to the report's style sheet.
EXTRA_CSS = """
figure.wide { width: min(1500px, calc(100vw - 2rem)); position: relative; left: 50%; transform: translateX(-50%); }
td.expr code { white-space: nowrap; background: none; padding: 0; }
td.muted, span.muted { color: var(--muted); }
.status { display: inline-block; padding: 0.05rem 0.55rem; border-radius: 999px; font-weight: 650; font-size: 0.9rem; }
.status.ok { background: #e4f4e9; color: var(--good); }
.status.bad { background: #fbe9e8; color: var(--accent2); }
.better { color: var(--good); }
.worse { color: var(--warn); }
ul.plain { margin: 0.4rem 0; padding-left: 1.3rem; }
ul.plain li { margin: 0.25rem 0; }
pre code { background: none; padding: 0; font-size: 1em; }
.nowrap { white-space: nowrap; }
table.params td, table.params th { padding-left: 0.45rem; padding-right: 0.45rem; }
"""


# -- formatting --------------------------------------------------------------------------------------
def _num(x: float, digits: int = 6) -> str:
    x = float(x)
    return "—" if not math.isfinite(x) else fmt_num(x, digits)


def _interval(lo: float, hi: float, digits: int = 6) -> str:
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return '<span class="muted">not determined</span>'
    return f'<span class="nowrap">[{_num(lo, digits)}, {_num(hi, digits)}]</span>'


def _relative(v: float, lo: float, hi: float) -> str:
    if not (math.isfinite(lo) and math.isfinite(hi) and math.isfinite(v)) or v == 0:
        return "—"
    return f"{fmt_num(50.0 * (hi - lo) / abs(v), 2)} %"


def _rms(x: float, kind: str) -> str:
    """A held-out RMS as the library reports it (rad or N m, 4 digits)."""
    if not math.isfinite(x):
        return '<span class="muted">failed</span>'
    return f"{x:.4g} {'rad' if kind == 'angle' else 'N m'}"


def _deg(x: float, digits: int = 3) -> str:
    return "—" if not math.isfinite(x) else f"{math.degrees(x):.{digits}f}°".replace("-", "−")


def _section(key: str, title: str, n: int, body: str) -> str:
    return (f'<section class="report-section" id="{key}" aria-labelledby="{key}-title">\n'
            f'<h2 id="{key}-title"><span class="num">{n}</span>{esc(title)}</h2>\n{body}\n</section>')


def _describe(m) -> str:
    """``26 pieces, 69342 samples over 69.3 s; speeds measured, no torques; from x.mat``."""
    if m is None:
        return "—"
    try:
        sources = list(m.metadata.get("sources", ()))
    except AttributeError:
        sources = []
    src = Path(str(sources[0])).name + (f" and {len(sources) - 1} more" if len(sources) > 1 else "") if sources else ""
    speeds = "speeds measured" if m.has_velocities else "speeds estimated from the angles"
    torques = "joint torques measured" if m.has_torques else "no torques (a free swing)"
    return (f"{len(m)} piece{'s' if len(m) != 1 else ''}, {m.samples} samples over {m.duration:.4g} s; "
            f"{speeds}, {torques}" + (f"; from <code>{esc(src)}</code>" if src else ""))


def _names(names: Sequence[str], limit: int = 8) -> str:
    names = [str(n) for n in names]
    if len(names) <= limit:
        return ", ".join(esc(n) for n in names)
    return ", ".join(esc(n) for n in names[:limit - 2]) + f", … , {esc(names[-1])}"


# -- sections ----------------------------------------------------------------------------------------
def _section_fit(r, measurements, validation, drawn: float) -> str:
    from ..style import parameter_text

    ok = r.ok
    st = r.settings if isinstance(r.settings, dict) else {}
    method = st.get("method", r.method)
    details = []
    if st.get("smoothing") is not None:
        details.append(f"Savitzky-Golay window {fmt_num(st['smoothing'])} s, order {st.get('order', 4)}")
    if st.get("segment") is not None:
        details.append(f"shooting segments of {fmt_num(st['segment'])} s ({st.get('segments', '?')} segments)")
    if st.get("iterations") is not None:
        details.append(f"{st['iterations']} iterations, " + ("converged" if st.get("converged") else "not converged"))
    note = r.intervals_note if hasattr(r, "intervals_note") else ""
    if note.startswith("95 %"):
        details.append(note)
    elif st.get("bootstrap"):
        over = note[len("clusters: "):] if note.startswith("clusters: ") else "pieces"
        details.append(f"intervals: sandwich and {st.get('bootstrap_used', st['bootstrap'])} bootstrap re-fits over "
                       f"{over} (seed {st.get('seed', 0)})")
    free = [n for n in r.free if n != r.reference]
    if st.get("alpha_free"):
        free.append(getattr(r, "angle", "alpha"))
    seconds = r.stats.get("seconds") if isinstance(r.stats, dict) else None
    facts: List[Tuple[str, str]] = [
        ("status", f'<span class="status {"ok" if ok else "bad"}">{"success" if ok else "not successful"}</span> '
                   f"{esc(r.message)}"),
        ("fitted on", _describe(measurements) if measurements is not None else f"{len(r.pieces)} piece{'' if len(r.pieces) == 1 else 's'}"),
        ("fitting pieces", _names(r.pieces)),
        ("held out", (_describe(validation) + "<br>" + _names(r.validation)) if len(r.validation)
         else '<span class="muted">no pieces held out (give them with --validate DATA on the command line, validation=... in Python, to predict motion the fit never saw)</span>'),
        ("method", esc(method) + (f"<br><span class=\"note\">{esc('; '.join(details))}</span>" if details else "")),
        ("freed", _names(free, 20) + (f" (the scale: {esc(r.reference)} from params0)" if r.reference else "")),
        ("start (params0)", esc(parameter_text(r.params0))),
        ("time taken", (f"{float(seconds):.3g} s to identify" if seconds is not None else "—")
         + f", {drawn:.2g} s to draw this report"),
    ]
    if isinstance(r.stats, dict) and r.stats.get("samples"):
        facts.insert(3, ("samples fitted", f"{r.stats['samples']} (after the filter's ends are dropped)"))
    what = model_name(r.params0)
    lead = (f"<p class=\"lead\">The measured motion of a real {what}, fitted by skewpend's model: the "
            "combinations of its parameters that the motion determines (the <b>base parameters</b>) with 95 % "
            "intervals, then each held-out piece predicted by simulation from its first measured state.</p>")
    warn = "" if ok else f'<p class="callout warn"><b>The identification did not succeed:</b> {esc(r.message)}</p>'
    return lead + warn + facts_html(facts)


#: What the model is called by its number of links (else a chain of n links).
MODEL_NAMES = {2: "double pendulum"}


def model_name(model) -> str:
    """``double pendulum``, ``chain of 3 links``: the model by its number of links."""
    return MODEL_NAMES.get(model.n, f"chain of {model.n} links")


def _section_parameters(r) -> str:
    rows = []
    values = np.asarray(r.values, float)
    intervals = np.asarray(r.intervals, float).reshape(-1, 2)
    for n, e, v, (lo, hi) in zip(r.names, r.expressions, values, intervals):
        if n == r.reference:
            iv, rel = '<span class="muted">params0\'s: the scale</span>', "—"
        elif n not in r.free:
            iv, rel = '<span class="muted">held at params0</span>', "—"
        else:
            iv, rel = _interval(lo, hi, 5), _relative(v, lo, hi)
        rows.append([f"<code>{esc(n)}</code>", _num(v, 5), iv, rel, f"<code>{esc(e)}</code>"])
    table = table_html(["base parameter", "estimate", "95 % interval", "± rel.", "expression"], rows,
                       numeric=(1, 3), caption="Base parameters in the standard parameters (SI units: kg m² for "
                       "inertias, kg m for first moments, N m s for damping)")
    table = table.replace("<table>", '<table class="params">')
    table = table.replace("<td><code>", '<td class="expr"><code>')  # expressions keep to one line
    note = ""
    if r.reference:
        note = (f"<p class=\"note\">A free swing determines ratios only: the whole set is in params0's scale of "
                f"<code>{esc(r.reference)}</code> = {_num(values[list(r.names).index(r.reference)])}"
                " (see the ratios below, which do not depend on it).</p>")
    if len(r.fit_rms):
        fr = np.asarray(r.fit_rms, float)
        note += (f"<p class=\"note\">Output error on the fitting pieces (angles, over the shooting segments): median "
                 f"{np.median(fr):.4g} rad, largest {np.max(fr):.4g} rad.</p>")
    elif len(r.residual_rms):
        rr = np.asarray(r.residual_rms, float)
        note += (f"<p class=\"note\">Inverse-dynamics residual on the fitting pieces: median {np.median(rr):.3g} N m, "
                 f"largest {np.max(rr):.3g} N m.</p>")
    return table + note


def _section_ratios(r) -> str:
    if not r.ratios:
        return ("<p>The data include joint torques, which fix the scale: every base parameter above is determined "
                "in its own units, so there are no ratios to report.</p>")
    rows = []
    for n, v in r.ratios.items():
        lo, hi = r.ratio_intervals.get(n, (math.nan, math.nan))
        rows.append([f"<code>{esc(n)}</code>", _num(v), _interval(lo, hi), _relative(v, lo, hi)])
    return (f"<p>Without measured torques one overall scale is free: the motion is the same when every inertia, "
            f"first moment and damping is multiplied by one number. What the data determine are the base parameters' "
            f"ratios to the reference <code>{esc(r.reference)}</code>:</p>"
            + table_html(["ratio", "estimate", "95 % interval", "± relative"], rows, numeric=(1, 3)))


def _section_undetermined(r) -> str:
    items = [f"<li>{esc(u)}</li>" for u in r.undetermined]
    if not items:
        return "<p>The data determine every base parameter the fit freed.</p>"
    return ("<p>These the data leave open; the fitted model takes them from params0 (they change none of the "
            "equations of motion, or only all together):</p><ul class=\"plain\">" + "".join(items) + "</ul>")


def _section_skew(r) -> str:
    """The freed angle: the double pendulum's skew angle alpha or a chain's hinge tilt (``r.angle``)."""
    name = getattr(r, "angle", "alpha")
    values = r.params0.to_dict()
    if not math.isfinite(r.alpha):
        if "alpha" in values:  # the double pendulum's facade: its skew angle
            alpha0 = values["alpha"] if values["alpha"] is not None else 0.0
            return (f"<p>The skew angle was not freed: the fit held it at params0's α = {_deg(alpha0)}. "
                    "Free it (<code>free=[\"alpha\", ...]</code>) to test whether the hinges are skewed.</p>")
        axes = "; ".join("(" + ", ".join(f"{x:.4g}" for x in link.axis) + ")" for link in r.params0.as_chain().links)
        return (f"<p>No hinge's tilt was freed: the fit held the axes at params0's, {esc(axes)}. Free one "
                "(<code>free=[\"tilt2\", ...]</code>: hinge 2's axis turned about the vertical) to test whether it "
                "is turned.</p>")
    alpha0 = (r.settings or {}).get("angle0")
    if alpha0 is None:  # (written before the start was recorded: the double pendulum's alpha)
        alpha0 = values.get("alpha") or 0.0
    symbol = "α" if name == "alpha" else esc(name)
    lo, hi = r.alpha_interval
    facts = [("angle", "the skew angle α" if name == "alpha" else f"hinge {esc(name[len('tilt'):])}'s tilt {symbol} "
              "(its axis turned about the vertical j; the angle of its projection on the (k, i) plane from k)"),
             ("estimate", _deg(r.alpha)), ("95 % interval", f"[{_deg(lo)}, {_deg(hi)}]"),
             ("start", f"{symbol}₀ = {_deg(alpha0)}")]
    if len(r.profile_alpha):
        a = np.degrees(np.asarray(r.profile_alpha, float))
        span = f"{a.min():.3g}° to {a.max():.3g}°".replace("-", "−")
        facts.append(("profile", f"{len(a)} angles from {span}, every other parameter re-fitted at each (figure panel e)"))
    covers = lo <= alpha0 <= hi
    verdict = ('<p class="verdict ok">The interval covers the start: the data show no skew beyond it.</p>' if covers
               else '<p class="verdict bad">The interval excludes the start\'s angle.</p>')
    note = f'<p class="note">{esc(r.alpha_note)}</p>' if r.alpha_note else ""
    return facts_html(facts) + verdict + note


def _section_heldout(r) -> str:
    if not len(r.validation):
        return ("<p>No pieces were held out, so nothing here shows how the model predicts motion it was not fitted "
                "to. Pass held-out pieces (<code>validation=</code>) to see it.</p>")
    rows = []
    for n, k, x, x0 in zip(r.validation, r.heldout_kind, r.heldout_rms, r.heldout_rms0):
        change = "—"
        if math.isfinite(x) and math.isfinite(x0) and x0 > 0:
            d = 100.0 * (x - x0) / x0
            cls = "better" if d < 0 else "worse"
            change = f'<span class="{cls}">{d:+.1f} %</span>'.replace("-", "−")
        rows.append([f"<code>{esc(n)}</code>", esc(k), _rms(x, k), _rms(x0, k), change])
    which = "both angles" if r.params0.n < 3 else f"all {r.params0.n} angles"
    absolute = r.settings.get("angles") == "absolute"
    frame = ("in the absolute angles the data measured, each rod's from the vertical," if absolute else
             "in the joint angles")
    body = ("<p>Each held-out piece simulated from its first measured state (angles, and speeds as measured or "
            f"estimated) with the fitted model and with params0; the RMS of the angle error over {which} and all "
            f"samples, {frame} (pieces with measured torques: the RMS of the torque prediction).</p>"
            + table_html(["held-out piece", "kind", "RMS, fitted model", "RMS, params0", "change"], rows,
                         numeric=(2, 3, 4)))
    if math.isfinite(r.heldout_median):
        body += facts_html([
            ("median over pieces", f"{r.heldout_median:.4g} rad (params0: {r.heldout_median0:.4g} rad)"),
            ("over every sample", f"{r.heldout_overall:.4g} rad (params0: {r.heldout_overall0:.4g} rad)"),
        ] + ([("median over pieces, joint angles", f"{r.stats['heldout_median_joint']:.4g} rad (params0: "
               f"{r.stats['heldout_median0_joint']:.4g} rad)")] if "heldout_median_joint" in r.stats else []))
    return body


def _section_figure(r, measurements, validation) -> Tuple[str, float]:
    import io

    from ..figures.base import print_figure
    from ..figures.identification import plot_identification

    t0 = time.perf_counter()
    fig = plot_identification(r, measurements, validation)
    buf = io.BytesIO()
    print_figure(fig, buf, "png", FIGURE_DPI, {"Software": f"skewpend {__version__}"})
    fig.clear()
    panels = ["(a) measured (wide pale lines) and predicted angles (thin: the fitted model; dashed: params0) of a "
              "few fitting pieces and the held-out ones, each simulated from its first measured state",
              "(b) the held-out prediction error against time",
              "(c) each estimate's 95 % half-width relative to it, on a log scale"
              + (" (the ratios a free swing determines)" if r.ratios else ""),
              "(d) the correlation of the free parameters' estimates" + ("" if np.asarray(r.correlation).size else
                                                                          " (output-error fits only)")]
    if len(r.profile_alpha) > 1:
        panels.append(f"(e) the cost profiled over {'the skew angle' if getattr(r, 'angle', 'alpha') == 'alpha' else r.angle} (every other parameter re-fitted), its 95 % "
                      "interval shaded")
    caption = "; ".join(panels) + "."
    html = (f'<figure class="wide" id="figure-1"><img src="{data_uri(buf.getvalue(), "image/png")}" '
            f'alt="the identification: predictions, errors, precision, correlations" width="1600" height="1000">'
            f"<figcaption><b>Figure 1.</b> {esc(caption)}</figcaption></figure>")
    return html, time.perf_counter() - t0


def _section_use(r) -> str:
    from ..style import parameter_text

    p = r.params
    fitted = esc(parameter_text(p))
    com = ", ".join(f"com{link.index} = ({', '.join(f'{c:.4g}' for c in link.com)}) m" for link in p.as_chain().links)
    warn = "" if r.ok else ('<p class="callout warn">The identification did not succeed, so the model below is the '
                            "start (params0), not a fit.</p>")
    names = list(p.coordinates)
    start = [f"{c}0" for c in names] + [f"d{c}0" for c in names]
    start = f"[{', '.join(start)}]" if len(names) <= 2 else "y0"  # a chain's 2 n numbers: y0
    return (warn + f"<p>The fitted model is a complete <code>skewpend.{type(p).__name__}</code> of {p.n} links: the "
            "base parameters above, with the entries the data do not determine taken from params0. Write it as a run "
            "file and simulate it like any other model:</p>"
            "<pre><code>skewpend identify ... --out fit.toml\nskewpend simulate --config fit.toml</code></pre>"
            "<p>or, in Python, from the result:</p>"
            "<pre><code>import skewpend\n"
            "r = skewpend.identify(measurements, params0, validation=held_out)\n"
            f"tr = skewpend.simulate(r.params, {start}, t_end)\n"
            "print(r.table())</code></pre>"
            + facts_html([("fitted model", fitted + (f"<br><span class=\"note\">{esc(com)}</span>" if com else "")),
                          ("params0", esc(parameter_text(r.params0)))]))


def _section_provenance(r, drawn: float) -> str:
    rows = [("skewpend", __version__),
            ("platform", f"{platform.system()} {platform.machine()}, {platform.python_implementation()} "
                         f"{platform.python_version()}")]
    try:
        import matplotlib

        rows.append(("Matplotlib", matplotlib.__version__))
    except ImportError:  # pragma: no cover - the figure needs it
        pass
    stats = r.stats if isinstance(r.stats, dict) else {}
    timings = [("identification", stats.get("seconds")), ("of it, the output-error fit", stats.get("fit_seconds")),
               ("drawing the figure", drawn)]
    trows = [[esc(k), f"{float(v):.2f}"] for k, v in timings if v is not None]
    return (table_html(["package", "version"], [[esc(a), esc(b)] for a, b in rows], compact=True)
            + table_html(["part", "seconds"], trows, numeric=(1,), compact=True, caption="Wall time")
            + "<p class=\"note\">Everything here was computed when this file was made; it opens offline and "
              "fetches nothing.</p>")


# -- the page ----------------------------------------------------------------------------------------
PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="skewpend {version}">
<title>{title}</title>
<style>
{css}
</style>
</head>
<body>
<header class="report-header">
  <p class="kicker">skewpend identification</p>
  <h1>{title}</h1>
  <p class="subtitle">{subtitle}</p>
</header>
<nav class="toc" aria-label="Contents">
  <h2>Contents</h2>
  <ol>
{toc}
  </ol>
</nav>
<main>
{body}
</main>
<footer class="report-footer">
  <p>{footer}</p>
</footer>
</body>
</html>
"""


def identification_html(result, measurements=None, validation=None) -> str:
    """The report's HTML text (what :func:`write_identification_report` writes)."""
    from ...errors import ParameterError

    if not hasattr(result, "heldout_rms") or not hasattr(result, "params0"):
        raise ParameterError(f"result must be a skewpend Identification (from skewpend.identify), got "
                             f"{type(result).__name__}")
    figure, drawn = _section_figure(result, measurements, validation)
    bodies = {
        "fit": _section_fit(result, measurements, validation, drawn),
        "parameters": _section_parameters(result),
        "ratios": _section_ratios(result),
        "undetermined": _section_undetermined(result),
        "skew": _section_skew(result),
        "heldout": _section_heldout(result),
        "figure": figure,
        "use": _section_use(result),
        "provenance": _section_provenance(result, drawn),
    }
    parts = [_section(key, title, n, bodies[key]) for n, (key, title) in enumerate(IDENTIFICATION_SECTIONS, 1)]
    toc = "\n".join(f'    <li><a href="#{key}">{esc(title)}</a></li>' for key, title in IDENTIFICATION_SECTIONS)
    n_fit = len(result.pieces)
    subtitle = (f"{esc(result.method)} fit of {len(result.names)} base parameters to {n_fit} measured "
                f"piece{'s' if n_fit != 1 else ''}" + (f", {len(result.validation)} held out" if len(result.validation)
                                                        else "") + f": {esc(result.message)}")
    return PAGE.format(
        version=esc(__version__), subtitle=subtitle,
        title="Identification of a measured " + model_name(result.params0),
        css=template("report.css") + EXTRA_CSS, toc=toc, body="\n".join(parts),
        footer=esc(f"Made by skewpend {__version__}. This one file holds its figure and its style: it opens offline "
                   "and fetches nothing."))


def write_identification_report(result, measurements, validation=None,
                                 path: Union[str, Path] = "identification.html") -> Path:
    """Write the identification report of ``result`` (an
    :class:`~skewpend.analysis.identify.Identification`, fitted on ``measurements`` and validated
    on ``validation``) to ``path`` (``.html``/``.htm``) as one self-contained HTML file, atomically
    (it appears complete or not at all); return the path.  The path is checked before any work."""
    from ...io import atomic_path, check_output_path

    out = check_output_path(path, REPORT_SUFFIXES, option="report")
    page = identification_html(result, measurements, validation)
    with atomic_path(out) as tmp:
        tmp.write_bytes(page.encode("utf-8"))
    return out
