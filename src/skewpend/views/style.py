"""One style for every skewpend figure, and the captions that say what a figure shows.

Nothing here imports matplotlib at module level.  :func:`style` is a context manager that
applies :data:`RC` (fonts, line widths, grid) only while a figure is built or saved -- the
global ``matplotlib.rcParams`` are left as they were.  :func:`caption`,
:func:`sweep_caption` and :func:`flipmap_caption` are plain strings (the parameters and settings a figure shows), so
they can be tested and reused without drawing anything.
"""

from __future__ import annotations

import contextlib
import math
from typing import Any, Dict, Iterator, List, Mapping

__all__ = [
    "RC", "COLORS", "SYMBOL", "DPI", "style", "fmt", "parameter_text", "settings_text", "initial_text", "caption",
    "sweep_caption", "flipmap_window", "window_text", "flipmap_caption",
]

#: The rcParams every figure is built and saved with (applied by :func:`style`).
RC: Dict[str, Any] = {
    "font.size": 9.5, "axes.titlesize": 10.5, "axes.titleweight": "normal", "axes.labelsize": 9.5,
    "xtick.labelsize": 8.5, "ytick.labelsize": 8.5, "legend.fontsize": 8.5, "legend.framealpha": 0.85,
    "legend.edgecolor": "0.8", "figure.titlesize": 10, "lines.linewidth": 1.1, "lines.markersize": 5,
    "axes.grid": True, "grid.alpha": 0.3, "grid.linewidth": 0.6, "axes.spines.top": False, "axes.spines.right": False,
    "axes.formatter.limits": (-4, 5), "axes.formatter.use_mathtext": True, "mathtext.fontset": "dejavusans",
    "figure.facecolor": "white", "savefig.facecolor": "white", "path.simplify": True,
    "pdf.fonttype": 42,  # TrueType: text stays text in PDF
    "svg.fonttype": "path",  # SVG looks the same without the fonts installed
}

#: Colours: phi (hinge 1, end of rod 1, mode 1) blue, psi (hinge 2, end of rod 2, mode 2) red.
COLORS: Dict[str, str] = {"phi": "#1f63a8", "psi": "#c8312b", "path": "#3b3b4f", "energy": "#2b2b2b",
                          "reference": "0.45", "rods": "0.35", "start": "#2a9d4b", "end": "#222222"}

#: Resolution of raster output [dots per inch].
DPI = 150

# Symbols in labels (matplotlib mathtext; rendered with the same DejaVu Sans as the text).
SYMBOL = {"phi": r"$\varphi$", "psi": r"$\psi$", "dphi": r"$\dot\varphi$", "dpsi": r"$\dot\psi$"}


@contextlib.contextmanager
def style() -> Iterator[None]:
    """Build or save a figure in the skewpend style; rcParams are restored afterwards."""
    import matplotlib

    with matplotlib.rc_context(RC):
        yield


def fmt(x: float, digits: int = 4) -> str:
    """A number as people write it: ``1``, ``0.8``, ``9.81``, ``1e-10``, ``-0.05``."""
    x = float(x)
    if x == 0:
        return "0"
    if not math.isfinite(x):
        return str(x)
    s = f"{x:.{digits}g}"
    if "e" in s:
        mant, exp = s.split("e")
        s = f"{mant}e{int(exp)}"
    return s


def _vec(v) -> str:
    return "(" + ", ".join(fmt(c, 3) for c in v) + ")"


def answers_names(model) -> bool:
    """Whether ``model`` answers the schema's scalar names (``a``, ``b``, ``m1``, ..., ``alpha``: the double
    pendulum's facade of the chain of two) -- what the texts and sections that read those names ask, never
    the model's type; a model without them is told by its links."""
    from .. import schema

    return all(hasattr(model, name) for name in schema.SCALAR_NAMES)


def parameter_text(params, *, skip: tuple = (), symbols: bool = False, sep: str = ", ") -> str:
    """The parameters as ``a = 1 m, b = 0.8 m, m1 = 1 kg, m2 = 0.7 kg, alpha = 34.38°, g = 9.81 m/s²``,
    then each optional term that differs from its default (damping, torques, Coulomb friction, the
    rotors: ``cf1 = 0.1 N m``) and any general body or axis that was given; every name, unit and
    symbol from :mod:`skewpend.schema`.  Names are those of :class:`skewpend.Parameters` and the
    command-line options, or with ``symbols`` the mathematical symbols (``m₁``, ``α``, ``τ₁``: an
    animation's title); ``sep`` joins the parts."""
    from .. import schema

    if not answers_names(params):  # told by its links
        return chain_text(params, sep=sep)
    d = params.to_dict()
    parts: List[str] = []
    for name in schema.SCALAR_NAMES:
        value = d.get(name)
        if name in skip or value is None:
            continue
        if schema.default(name) is not None and value == schema.default(name):
            continue
        label = schema.symbol(name) if symbols else name
        if isinstance(value, str):  # left symbolic
            parts.append(f"{label} = {value}")
        elif schema.field(name).bound == "angle":
            parts.append(f"{label} = {fmt(math.degrees(value))}°")
        else:
            unit = schema.unit(name)
            parts.append(f"{label} = {fmt(value)}" + ("" if unit in ("", "1") else f" {unit}"))
    for name in schema.AXIS_NAMES:
        if d.get(name) is not None and name not in skip:
            parts.append(f"{name} = {_vec(d[name])}")
    custom = [n for n in schema.COM_NAMES + schema.INERTIA_NAMES if d.get(n) is not None]
    if custom:
        parts.append("custom " + ", ".join(custom))
    return sep.join(parts)


def settings_text(method: str, settings: Mapping[str, Any]) -> str:
    """``dop853, rtol = 1e-10, atol = 1e-10, t_end = 5 s, rows every 0.01 s``."""
    parts = [str(method)]
    for key, unit in (("rtol", ""), ("atol", ""), ("dt", " s"), ("t_end", " s")):
        if settings.get(key) is not None:
            parts.append(f"{key} = {fmt(settings[key])}{unit}")
    if settings.get("dt_out") is not None:
        parts.append(f"rows every {fmt(settings['dt_out'])} s")
    else:
        parts.append("rows at the integrator's steps")
    return ", ".join(parts)


def chain_text(model, sep: str = ", ") -> str:
    """A model told by its links in one line: their number, each link's length, mass and hinge axis, g, and the
    joints' terms that are on (``3 links; l = 0.5, 0.4, 0.3 m; m = 1, 0.8, 0.5 kg; ...``)."""
    def listed(values, unit=""):
        return ", ".join(fmt(v) for v in values) + unit

    chain = model.as_chain()
    links = chain.links
    parts = [f"{chain.n} links", f"l = {listed([k.length for k in links], ' m')}", f"m = {listed([k.mass for k in links], ' kg')}",
             "axes " + "; ".join("(" + ", ".join(fmt(x) for x in k.axis) + ")" for k in links), f"g = {fmt(chain.g)} m/s²"]
    for key, unit in (("damping", " N m s"), ("torque", " N m"), ("coulomb", " N m"), ("rotor", " kg m²")):
        values = [getattr(k, key) for k in links]
        if any(values):
            parts.append(f"{key} {listed(values, unit)}")
    return sep.join(parts)


def initial_text(y0) -> str:
    """``phi0 = 68.75°, psi0 = -45.84°, dphi0 = 0 rad/s, dpsi0 = 0 rad/s`` (a chain's ``q0 = (...)°,
    dq0 = (...) rad/s``)."""
    if len(y0) != 4:
        n = len(y0) // 2
        return (f"q0 = ({', '.join(fmt(math.degrees(float(v))) for v in y0[:n])})°, "
                f"dq0 = ({', '.join(fmt(float(v)) for v in y0[n:])}) rad/s")
    phi, psi, dphi, dpsi = (float(v) for v in y0)
    return (f"phi0 = {fmt(math.degrees(phi))}°, psi0 = {fmt(math.degrees(psi))}°, "
            f"dphi0 = {fmt(dphi)} rad/s, dpsi0 = {fmt(dpsi)} rad/s")


def caption(tr) -> str:
    """What a trajectory figure shows, in three lines: the parameters; the initial state;
    the method and its settings (and a fourth if the run stopped early: why)."""
    lines = [parameter_text(tr.params), initial_text(tr.y[0]), settings_text(tr.method, tr.settings)]
    if getattr(tr, "status", 0) != 0:
        lines.append(f"run stopped early at t = {fmt(tr.t[-1])} s: {tr.message}")
    return "\n".join(lines)


def sweep_caption(sw) -> str:
    """The swept range and the parameters held fixed."""
    values = sw.values
    if sw.name == "alpha":
        lo, hi, unit = fmt(math.degrees(values[0])), fmt(math.degrees(values[-1])), "°"
    else:
        u = sw.units().get(sw.name, "")
        lo, hi, unit = fmt(values[0]), fmt(values[-1]), ("" if u in ("", "1") else f" {u}")
    swept = f"{sw.name} from {lo}{unit} to {hi}{unit} ({len(values)} points)"
    # a ratio sweep scales its numerator; a plain sweep replaces the parameter
    fixed = parameter_text(sw.params, skip=(sw.name.split("/")[0],) if "/" in sw.name else (sw.name,))
    return f"{swept}; {fixed}" if fixed else swept


def flipmap_window(fm):
    """``((phi_lo, phi_hi), (psi_lo, psi_hi))`` [rad]: the window a flip map covers (the outer
    edges of its cells), from its settings, or else from its cell centres."""
    out = []
    for key, centres in (("phi_range", fm.phi0[:, 0]), ("psi_range", fm.psi0[0, :])):
        given = fm.settings.get(key)
        if given is not None:
            out.append((float(given[0]), float(given[1])))
            continue
        c = [float(v) for v in centres]
        half = 0.5 * (c[-1] - c[0]) / (len(c) - 1) if len(c) > 1 else 0.0
        out.append((c[0] - half, c[-1] + half))
    return tuple(out)


def window_text(phi_range, psi_range, names=("phi", "psi")) -> str:
    """``phi0 in [-180°, 180°], psi0 in [-90°, 45°]`` (a flip map's window, given in radians; ``names``: the
    plane's two angles, a chain's ``q1(0) in [...]``)."""
    deg = lambda x: fmt(math.degrees(float(x)))  # noqa: E731
    return ", ".join(f"{name}{'(0)' if name[-1].isdigit() else '0'} in [{deg(lo)}°, {deg(hi)}°]"
                     for name, (lo, hi) in zip(names, (phi_range, psi_range)))


def wrap_list(text: str, width: int = 100) -> str:
    """A comma-separated list broken into lines of at most ``width`` characters, between items."""
    lines: List[str] = []
    for item in text.split(", "):
        if lines and len(lines[-1]) + 2 + len(item) <= width:
            lines[-1] += ", " + item
        else:
            if lines:
                lines[-1] += ","
            lines.append(item)
    return "\n".join(lines)


def flipmap_caption(fm) -> str:
    """What a flip-time map shows, in three lines: the model; the grid (window, the angles held, cells,
    released at rest, ``t_end``); the method, its tolerances and how many cells flipped."""
    st, stats = fm.settings, fm.stats
    n0, n1 = fm.flip_time.shape
    t_end = st.get("t_end")
    held = ", ".join(f"{c} = {fmt(math.degrees(float(v)))}°" for c, v in zip(fm.params.coordinates, fm.held)
                     if c not in fm.plane)
    grid = (f"released at rest from {window_text(*fm.window(), names=fm.plane)}" + (f", held {held}" if held else "")
            + f", n = {n0} x {n1} cells")
    if t_end is not None:
        grid += f", t_end = {fmt(t_end)} s"
    parts = [str(st.get("method", "dop853"))]
    parts += [f"{k} = {fmt(st[k])}" for k in ("rtol", "atol") if st.get(k) is not None]
    cells = n0 * n1
    flipped = stats.get("flipped")
    if flipped is None:
        import numpy as np

        flipped = int(np.count_nonzero(np.isfinite(fm.flip_time)))
    parts.append(f"{fmt(100.0 * flipped / cells, 3)}% of the cells flip")
    if st.get("energy_bound") and stats.get("skipped_energy") is not None:
        parts.append(f"{fmt(100.0 * stats['skipped_energy'] / cells, 3)}% forbidden by energy")
    return "\n".join([wrap_list(parameter_text(fm.params)), grid, ", ".join(parts)])
