"""The browser front end's JavaScript, as one set of sources shared by every view that runs in a
browser: the served explorer (``skewpend serve``), the static explorer (:func:`export_explorer`,
``skewpend explorer``), the report's live 3D view and the notebook widget.

The sources are the vendored three.js (from the npm package, never a CDN), the physics generated
from the derivation (:func:`skewpend.numeric.explorer_source.explorer_js`: motion, energy, drawing,
linearisation and the equations' coefficients), the DOP853 tableau, and the page's own scripts in
``web/``.  Each is delivered as a *registration*: a classic script that stores the text with its
import specifiers (``web/loader.js`` turns the modules into ``blob:`` URLs at run time), so the
same page runs from a server, from the file system -- browsers refuse module files from
``file://`` -- and inlined in one HTML file, with no request leaving it.
"""

from __future__ import annotations

import json
import shutil
from contextlib import suppress
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Dict, List, Optional

from .. import schema as _schema

__all__ = ["Source", "sources", "registration", "export_explorer", "inline_page_scripts", "WEB_DIR", "katex_dir",
           "SOURCE_ORDER", "REPLAY_ORDER", "MANIFEST", "EXPORT_ENTRIES", "WIDGET_ORDER", "module_bundle", "replay_data",
           "page_settings", "page_sliders", "start_key", "SLIDER_RANGES", "START_RANGE"]

WEB_DIR = Path(__file__).resolve().parent / "web"
_THREE = WEB_DIR / "vendor" / "three"


@dataclass(frozen=True)
class Source:
    """One registered text: ``code``, its ``imports`` (specifier as written -> source name) and
    whether it is a ``classic`` script (a Web Worker's part) rather than a module."""

    name: str
    code: str
    imports: Dict[str, str] = field(default_factory=dict)
    classic: bool = False


#: The explorer's sources in the order its page loads them (any order works; this one is the
#: dependencies' order).
SOURCE_ORDER = ("three-core", "three", "three-orbit", "physics", "page", "scene", "live", "explorer", "physics-classic",
                "dop853", "flipworker")
#: The live replay's sources (the report's 3D view of a computed motion): no physics at all.
REPLAY_ORDER = ("three-core", "three", "three-orbit", "scene", "live", "replay")
#: The notebook widget's sources (:mod:`skewpend.views.widget`): the live motion, no flip map.
WIDGET_ORDER = ("three-core", "three", "three-orbit", "physics", "scene", "live", "widget")


def _read(path: Path) -> str:
    return path.read_text(encoding="utf-8")


def _checked(src: Source) -> Source:
    """Refuse a module that does not import what its specifiers say (e.g. after a three.js upgrade)."""
    for specifier in src.imports:
        if f'from "{specifier}"' not in src.code and f"from '{specifier}'" not in src.code:
            raise RuntimeError(f"front end: {src.name} does not import {specifier!r}")
    return src


@lru_cache(maxsize=1)
def _static_sources() -> tuple:
    """The sources that do not depend on the bodies: three.js and the page's own scripts."""
    from ..numeric.tableau import dop853_js

    out = [
        Source("three-core", _read(_THREE / "three.core.js")),
        Source("three", _read(_THREE / "three.module.js"), {"./three.core.js": "three-core"}),
        Source("three-orbit", _read(_THREE / "addons" / "controls" / "OrbitControls.js"), {"three": "three"}),
        Source("scene", _read(WEB_DIR / "scene.js"),
               {"three": "three", "three/addons/controls/OrbitControls.js": "three-orbit"}),
        Source("live", _read(WEB_DIR / "live.js")),
        Source("explorer", _read(WEB_DIR / "app.js"),
               {"three": "three", "./scene.js": "scene", "./physics.js": "physics", "./page.js": "page", "./live.js": "live"}),
        Source("replay", _read(WEB_DIR / "replay.js"), {"./scene.js": "scene", "./live.js": "live"}),
        Source("widget", _read(WEB_DIR / "widget.js"), {"./scene.js": "scene", "./physics.js": "physics", "./live.js": "live"}),
        Source("dop853", dop853_js(), classic=True),
        Source("flipworker", _read(WEB_DIR / "flipworker.js"), classic=True),
    ]
    return tuple(_checked(s) for s in out)


@lru_cache(maxsize=8)
def _physics_sources(physics_params) -> tuple:
    from ..numeric.codegen import classic_js
    from ..numeric.explorer_source import explorer_js

    module = explorer_js(physics_params, _hanging_rest(physics_params))
    return (Source("physics", module), _page_source(page_settings(physics_params)),
            Source("physics-classic", classic_js(module, "physics"), classic=True))


def _hanging_rest(physics_params):
    """The angles of the hanging rest the page linearises at (:func:`skewpend.analysis.control.hanging_rest`: the
    DeepMind acrobot's (pi, 0), whose zero is upright); None (every q = 0) for the exact form or a model without one
    (the page then says the position at q = 0 is no stable equilibrium).  The page's sliders (g, the joints'
    damping) do not move it."""
    from ..errors import EquilibriumError
    from ..numeric.explorer_source import page_form

    form, printed = page_form(physics_params)
    if form == "exact":
        return None
    from ..analysis.control import hanging_rest

    try:
        return [float(v) for v in hanging_rest(printed)[:printed.n]]
    except EquilibriumError:
        return None


def _page_source(settings: dict) -> Source:
    return Source("page", "// the explorer's settings for these bodies (skewpend.views.frontend.page_settings)\n"
                          f"export const PAGE = {json.dumps(settings, ensure_ascii=False)};\n")


#: The sliders, one definition for every model and view: by the schema's stem of the parameter, its range
#: ``(min, max, step)``, unit, whether shown in degrees, and the word after its name -- in the order shown
#: (the schema's ``Field.slider``).
SLIDER_RANGES = {f.stem: (f.slider[1], "°" if f.slider[2] else f.unit, f.slider[2], f.slider[3])
                 for f in sorted((f for f in _schema.FIELDS if f.slider), key=lambda f: f.slider[0])}
#: Each joint's start angle [deg]: its slider's range and step.
START_RANGE = (-180.0, 180.0, 0.5)
#: What a slider sets alone in each form of the page's physics (:func:`~skewpend.numeric.explorer_source.page_form`):
#: the derivation reads every scalar of the double pendulum's parameters; the recursive algorithms' bodies are
#: fixed (a rod's length or mass would move its centre of mass and inertia too), their g and damping are live.
LIVE_STEMS = {"exact": tuple(SLIDER_RANGES), "recursive": ("g", "c")}
#: The coordinates' symbols on the page.
_SYMBOLS = {"phi": "φ", "psi": "ψ", "alpha": "α"}


def _stem(name: str) -> str:
    """The schema's stem of a parameter of the page's physics (``a`` -> ``l``, ``c3`` -> ``c``, ``l2`` -> ``l``)."""
    return _schema.field(name).stem if name in _schema.NAMES else name.rstrip("0123456789")


def start_key(coordinate: str) -> str:
    """The start slider of a coordinate: ``phi0`` (the run file's key), ``q3_0`` (after a digit)."""
    return f"{coordinate}_0" if coordinate[-1].isdigit() else f"{coordinate}0"


def page_sliders(model=None) -> list:
    """The page's sliders for ``model``: ``[key, label, min, max, step, default, unit, degrees]`` for each
    parameter of its physics that a slider sets alone (:data:`LIVE_STEMS`; in :data:`SLIDER_RANGES`' order;
    the skew ``alpha`` only where it enters) at the model's values (the reference case's where symbolic),
    then a start angle for each coordinate (``phi0``, ``psi0``; ``q<k>_0``) at the reference start
    (:data:`~skewpend.config.DEFAULT_RUN`'s ``[initial]``; a chain's joints at ``CHAIN_Q0``)."""
    import math

    from ..config import CHAIN_Q0, DEFAULT_RUN
    from ..numeric.explorer_source import page_vector

    form, printed, order, values = page_vector(model)
    rank = list(SLIDER_RANGES)
    live = sorted(((k, v) for k, v in zip(order, values) if _stem(k) in LIVE_STEMS[form]
                   and (k != "alpha" or printed.uses_alpha)), key=lambda kv: rank.index(_stem(kv[0])))
    out = []
    for k, v in live:
        (lo, hi, step), unit, degrees, word = SLIDER_RANGES[_stem(k)]
        i = "".join(ch for ch in k if ch.isdigit()) or str(order.index(k) + 1)
        label = f"{_SYMBOLS.get(k, k)} {word.format(i=i)}".strip()
        out.append([k, label, lo, hi, step, round(math.degrees(v), 2) if degrees else v, unit, degrees])
    for c in printed.coordinates:
        key, start = start_key(c), float(DEFAULT_RUN["initial"].get(f"{c}0", CHAIN_Q0))
        label = f"{_SYMBOLS.get(c, c)}{'0' if key == c + '0' else ''} start"
        out.append([key, label, *START_RANGE, round(math.degrees(start), 2), "°", True])
    return out


def page_settings(physics_params=None) -> dict:
    """What the explorer's page (web/app.js) needs beside the generated physics, for any model: its ``title``
    and ``lead`` (the header's words), its coordinates' ``names``, the ``sliders`` (:func:`page_sliders`), and
    by their index in the physics' parameter vector its rods' ``lengths`` (the drawn axes' scale, the
    camera's reach), the drawn rig's ``reach`` [m] (:func:`skewpend.views.drawing.drawn_reach`: a small rig is
    drawn magnified), where the camera looks when hinge 1 is away from the roof (``frame``:
    :func:`skewpend.views.drawing.drawn_frame`, else None), the terms that make the energy not conserved (``dissipative``: damping, torques,
    friction, from the schema's roles) and the ``torques``."""
    from ..numeric.explorer_source import page_vector
    from .drawing import drawn_frame, drawn_reach

    form, printed, order, values = page_vector(physics_params)
    roles = {f.stem: f.role for f in _schema.FIELDS if f.per_body}  # a joint's terms (cfs, the chain's, is none)
    where = lambda *rs: [i for i, k in enumerate(order) if roles.get(_stem(k)) in rs]  # noqa: E731
    lengths = [i for i, k in enumerate(order) if _stem(k) == "l"]
    title = printed.title
    if form == "exact" and printed.uses_alpha:
        whose = "The double pendulum whose second hinge axis is skewed by α"
    else:
        axes = [printed.axis1 or (0, 0, 1), printed.axis2] if form == "exact" else [link.axis for link in printed.links]
        axes = ", ".join("(" + ", ".join(f"{float(x):.3g}" for x in axis) + ")" for axis in axes)
        whose = (f"{title[0].upper()}{title[1:]} whose hinge axes are {axes}, each in its parent's frame with the chain "
                 "hanging (j points down)")
    source = ("the symbolic derivation (Lagrange's equations with rotation tensors)" if form == "exact" else
              "the chain's recursive algorithms (the composite-rigid-body and Newton-Euler algorithms)")
    return {"title": title, "lead": f"{whose} — every number here comes from {source}: the "
            "motion, the equations, the normal modes and the flip map are computed in your browser by JavaScript generated "
            "from it.", "names": [_SYMBOLS.get(c, c) for c in printed.coordinates], "sliders": page_sliders(physics_params),
            "lengths": lengths,  # the exact form's drawn reach: its rods' lengths end to end
            "reach": drawn_reach(printed) if form != "exact" else float(sum(values[i] for i in lengths)),
            "frame": drawn_frame(printed) if form != "exact" else None,
            "dissipative": where("damping", "torque", "friction"), "torques": where("torque")}


def sources(physics_params=None, order=SOURCE_ORDER) -> Dict[str, Source]:
    """The sources named in ``order`` (default: the explorer's, :data:`SOURCE_ORDER`), by name; the
    physics for the bodies and axes of ``physics_params`` (default: the specification's thin rods)."""
    found = {s.name: s for s in _static_sources()}
    if any(name.startswith("physics") for name in order):
        found.update({s.name: s for s in _physics_sources(physics_params)})
    return {name: found[name] for name in order}


def inline_page_scripts(order=REPLAY_ORDER, entry: str = "replay", physics_params=None) -> str:
    """``<script>`` elements for one self-contained HTML file: the registrations of ``order`` and
    the loader, which imports ``entry`` once the page has parsed (the scripts go at the end of
    the body)."""
    parts = [f"<script>\n{registration(s)}</script>" for s in sources(physics_params, order).values()]
    loader = _read(WEB_DIR / "loader.js")
    if "</" in loader:  # it would end the script element
        raise RuntimeError("front end: loader.js must not contain '</'")
    parts.append(f'<script data-entry="{entry}">\n{loader}</script>')
    return "\n".join(parts)


def replay_data(trajectory) -> dict:
    """What a browser view replays of a computed run (``web/replay.js``, the widget): the rows'
    times ``t`` [s], states ``y``, the library's rod ends ``tips`` (the last as drawn: its body's side of its
    hinge, :func:`~skewpend.views.drawing.last_link_sign`), the hinges' positions ``hinges``
    (:func:`skewpend.views.drawing.link_points`: each link drawn from its hinge to the next one) and hinge
    axes ``axes`` at each row (a chain's n rods and axes), the length scale ``size`` [m] of the drawn axes
    and the drawn rig's ``reach`` [m] (:func:`~skewpend.views.drawing.drawn_reach`: a small rig is drawn
    magnified) -- plain lists, written exactly."""
    from .drawing import drawn_reach, link_points

    model = trajectory.params
    lengths = [link.length for link in model.as_chain().links]  # the model's n rods
    tips = trajectory.tips()
    n = len(lengths)
    points = link_points(model, trajectory.y, tips)
    hinges = points[:, :n].reshape(-1, 3 * n)
    tips[:, 3 * (n - 1):] = points[:, n]  # the last link's drawn end (mirrored where its mass lies: last_link_sign)
    return {"t": trajectory.t.tolist(), "y": trajectory.y.tolist(), "tips": tips.tolist(), "hinges": hinges.tolist(),
            "axes": trajectory.axes().tolist(), "size": max(float(v) for v in lengths), "reach": drawn_reach(model)}


def module_bundle(order=WIDGET_ORDER, entry: str = "widget", physics_params=None) -> str:
    """One ES module holding the sources of ``order`` with the loader (for a notebook widget:
    anywidget imports one module); its default export is ``entry``'s (anywidget's ``{render}``).

    Each source is registered under its name and a digest of its text and imports
    (``three@1f0c...``), and the loader keeps its ``blob:`` URLs page-wide: widgets on one page
    share one three.js (one module instance) while each keeps the physics of its own bodies."""
    import hashlib

    found = sources(physics_params, order)
    if entry not in found:
        raise RuntimeError(f"front end: the entry {entry!r} is not among the sources {order}")
    keyed: Dict[str, str] = {}

    def key(name: str) -> str:  # a name for this exact text, its dependencies' included
        if name not in keyed:
            src = found[name]
            deps = {spec: key(dep) for spec, dep in src.imports.items()}
            digest = hashlib.sha256(json.dumps([src.code, deps, src.classic]).encode()).hexdigest()[:16]
            keyed[name] = f"{name}@{digest}"
        return keyed[name]

    registry = {key(n): {"code": found[n].code, "imports": {spec: key(dep) for spec, dep in found[n].imports.items()},
                         "classic": found[n].classic} for n in found}
    loader = _read(WEB_DIR / "loader.js")
    return "\n".join([
        "// skewpend's front end as one module: three.js (vendored from npm), the physics generated from",
        "// the derivation and the view's code, made blob: URLs by skewpend's loader (loader.js).",
        f"const sources = {json.dumps(registry, ensure_ascii=False)};",
        "const registry = (self.SKEWPEND_SOURCES = self.SKEWPEND_SOURCES || {});",
        "for (const [name, source] of Object.entries(sources)) if (!(name in registry)) registry[name] = source;",
        loader,
        f"const entry = self.skewpend.import({json.dumps(key(entry))});",
        "export default {",
        "  async initialize(context) { const m = await entry; if (m.default.initialize) return m.default.initialize(context); },",
        "  async render(context) { const m = await entry; return m.default.render(context); },",
        "};",
        "",
    ])


def registration(src: Source) -> str:
    """The classic script registering ``src`` (safe to inline in HTML: ``</`` is escaped)."""
    entry = {"code": src.code, "imports": src.imports, "classic": src.classic}
    text = json.dumps(entry, ensure_ascii=False).replace("</", "<\\/").replace("<!--", "<\\!--")
    return f"(self.SKEWPEND_SOURCES = self.SKEWPEND_SOURCES || {{}})[{json.dumps(src.name)}] = {text};\n"


def katex_dir() -> Path:
    return Path(str(resources.files("skewpend.views") / "assets" / "katex"))


def _licences() -> List[tuple]:
    return [(_THREE / "LICENSE", "three.js"), (katex_dir() / "LICENSE", "KaTeX")]


#: The export's manifest: the version that wrote it and every file it wrote (relative paths).
MANIFEST = ".skewpend-explorer"
#: What the export writes at the top of its directory (the manifest last).
EXPORT_ENTRIES = ("index.html", "static", "sources", "LICENSES", MANIFEST)


def export_explorer(directory, params=None, *, force: bool = False, start: str = "") -> Path:
    """Write the static explorer to ``directory``: ``index.html`` with the page's files beside it
    (``static/``: styles, KaTeX, the loader; ``sources/``: three.js, the generated physics and the
    page's scripts as registrations; ``LICENSES/``; ``.skewpend-explorer``, the manifest of every
    file written).  It runs entirely in the browser, opened from the file system or any static
    web host, with the network off; the physics is generated for the bodies and axes of
    ``params`` (a :class:`~skewpend.Parameters`; default: the specification's thin rods), or for a chain
    of links (a :class:`~skewpend.symbolic.chain.Chain`: its page, :func:`page_settings`).  ``start``: the
    sliders' values the page opens with, as an address query (``alpha=30&phi0=60``: a run file's, from
    ``skewpend serve --config --export``); an address's own query, if any, goes over it.

    ``directory`` may be new, or an existing directory (``"."`` too) in which none of those five
    names exists -- or, with ``force=True``, in which they are an earlier export's, holding only
    the files its manifest lists: those are replaced.  Nothing else in ``directory`` is ever
    touched (a ``CNAME`` beside the site stays); a symbolic link as ``directory`` or among the
    export's entries, a file the export did not write where it would write, or a directory that
    cannot be written is refused with one :class:`ParameterError`, before anything is written.
    The site is built in a temporary directory made exclusively (``tempfile.mkdtemp``: a new,
    random name, never an existing path) beside ``directory`` -- inside it when it exists -- and
    moved into place, so an error or an interruption leaves no half site.  Returns the path of
    ``index.html``."""
    import os
    import tempfile

    from ..errors import ParameterError, SkewpendError

    if params is not None and not hasattr(params, "as_chain"):  # a model: the double pendulum's or a chain
        raise ParameterError(f"params must be a skewpend.Parameters, a Chain or None, got {type(params).__name__}")
    if isinstance(force, str) or not isinstance(force, (bool, int)):
        raise ParameterError(f"force must be True or False, got {force!r}")
    try:
        target = Path(os.fspath(directory))
    except TypeError:
        raise ParameterError(f"directory must be a path, got {type(directory).__name__}") from None
    if not str(directory).strip():
        raise ParameterError("explorer export: the directory is empty text; give a directory name")
    what = "explorer export"
    replaced = _export_plan(target, bool(force), what)  # refusals first: nothing is written yet
    if not isinstance(start, str):
        raise ParameterError(f"start must be an address query (text), got {type(start).__name__}")
    srcs = sources(params)  # generated before anything is written: an error leaves nothing behind
    if start:  # the page opens at the run's values with or without the query in its address (issue 51)
        srcs["page"] = _page_source(dict(page_settings(params), start=start))
    exists = os.path.lexists(target)
    parent = target if exists else (target.parent if str(target.parent) else Path("."))
    try:
        from ..io import short_name

        staging = Path(tempfile.mkdtemp(prefix=".skewpend-export-" if exists else f".{short_name(target.name)}.skewpend-export-",
                                        dir=parent))
    except OSError as exc:
        raise ParameterError(f"{what}: cannot write {target}: {exc.strerror or exc}") from None
    site = staging / "site" if exists else staging
    try:
        try:
            _write_site(site, srcs)
        except OSError as exc:
            raise SkewpendError(f"{what}: cannot write {target}: {exc.strerror or exc}") from None
        if exists:
            _swap_in(target, staging, site, replaced, what)
        else:
            try:
                os.rename(staging, target)  # an empty directory made meanwhile is replaced; anything else refused
            except OSError as exc:
                raise ParameterError(f"{what}: cannot create {target}: {exc.strerror or exc}") from None
    finally:
        if os.path.lexists(staging) and not os.path.islink(staging):
            shutil.rmtree(staging, ignore_errors=True)  # ours: made by mkdtemp, it holds only what we put there
    return target / "index.html"


def _write_site(site: Path, srcs: Dict[str, Source]) -> None:
    """The export's files, written into the new directory ``site`` (the manifest last)."""
    import os

    from .. import __version__

    site.mkdir(exist_ok=True)
    mask = os.umask(0o022)
    os.umask(mask)
    os.chmod(site, 0o777 & ~mask)  # mkdtemp made it private; a site is read by web servers
    for folder in ("static", "sources", "LICENSES"):
        (site / folder).mkdir()
    for name in ("app.css", "loader.js"):
        shutil.copyfile(WEB_DIR / name, site / "static" / name)
    shutil.copytree(katex_dir(), site / "static" / "katex", copy_function=shutil.copyfile)
    for src in srcs.values():
        (site / "sources" / f"{src.name}.js").write_text(registration(src), encoding="utf-8")
    for path, name in _licences():
        shutil.copyfile(path, site / "LICENSES" / f"{name}.txt")
    (site / "index.html").write_text(_read(WEB_DIR / "index.html"), encoding="utf-8")
    files = sorted(Path(root, f).relative_to(site).as_posix() for root, _, names in os.walk(site) for f in names)
    (site / MANIFEST).write_text(json.dumps({"skewpend": __version__, "files": files}, indent=1) + "\n",
                                 encoding="utf-8")


def _manifest(target: Path) -> "Optional[set]":
    """The files an earlier export in ``target`` recorded as its own, or None (no manifest, or a
    manifest that is not a regular file skewpend wrote)."""
    import os
    import stat

    path = target / MANIFEST
    try:
        st = os.lstat(path)
        if not stat.S_ISREG(st.st_mode) or st.st_size > 1 << 20:
            return None
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or "skewpend" not in data:
        return None
    files = data.get("files")
    if files is None:  # an export by an earlier skewpend: the files this one writes
        return set(_site_files())
    if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
        return None
    return set(files)


@lru_cache(maxsize=1)
def _site_files() -> tuple:
    """The relative paths of the files an export writes (for a manifest that did not list them)."""
    import os

    katex = katex_dir()
    out = ["index.html", "static/app.css", "static/loader.js", *(f"sources/{n}.js" for n in SOURCE_ORDER),
           *(f"LICENSES/{name}.txt" for _, name in _licences())]
    out += [f"static/katex/{Path(root, f).relative_to(katex).as_posix()}" for root, _, names in os.walk(katex) for f in names]
    return tuple(out)


def _export_plan(target: Path, force: bool, what: str) -> List[str]:
    """Check ``target`` before anything is written; return the export's entries in it that are
    an earlier export's own (to be replaced).  Every refusal is one :class:`ParameterError`."""
    import os
    import stat

    from ..errors import ParameterError

    if not os.path.lexists(target):
        parent = target.parent if str(target.parent) else Path(".")
        if not parent.is_dir():
            raise ParameterError(f"{what}: the parent directory {parent} does not exist")
        return []
    if target.is_symlink():
        raise ParameterError(f"{what}: {target} is a symbolic link; give a real directory (the export never writes "
                             "through a link)")
    if not target.is_dir():
        raise ParameterError(f"{what}: {target} exists and is not a directory; give a new directory")
    present = [name for name in EXPORT_ENTRIES if os.path.lexists(target / name)]
    if not present:
        return []
    owned = _manifest(target)
    if not force:
        if owned is not None:
            raise ParameterError(f"{what}: {target} holds an earlier export: pass force=True (--force) to replace it")
        raise ParameterError(f"{what}: {target} already has {present[0]}, which no export wrote; give a new or empty "
                             f"directory, or one without {', '.join(EXPORT_ENTRIES)}")
    if owned is None:
        raise ParameterError(f"{what}: {target} is not an earlier export (it has {present[0]} but no manifest "
                             f"{MANIFEST} that skewpend wrote); nothing was replaced")
    owned_dirs = {str(Path(f).parent.as_posix()) for f in owned}
    owned_dirs |= {d.rsplit("/", i)[0] for d in list(owned_dirs) for i in range(d.count("/") + 1)}
    for name in present:
        if name == MANIFEST:
            continue
        for path in [target / name, *_walk(target / name)]:
            rel = path.relative_to(target).as_posix()
            st = os.lstat(path)
            if stat.S_ISLNK(st.st_mode):
                raise ParameterError(f"{what}: {path} is a symbolic link, which no export wrote; move it away first "
                                     "(nothing was replaced)")
            if stat.S_ISDIR(st.st_mode) and rel in owned_dirs or stat.S_ISREG(st.st_mode) and rel in owned:
                continue
            raise ParameterError(f"{what}: {path} was not written by the export; move it away first (nothing was "
                                 "replaced)")
    return present


def _walk(top: Path) -> List[Path]:
    """Everything below ``top`` (not following symbolic links)."""
    import os

    if top.is_symlink():
        return []
    return [Path(root, n) for root, dirs, files in os.walk(top) for n in dirs + files]


def _swap_in(target: Path, staging: Path, site: Path, replaced: List[str], what: str) -> None:
    """Move the export's entries from ``site`` into the existing directory ``target``, the entries
    of an earlier export (``replaced``) into ``staging`` (removed with it); on an error every
    entry is moved back.  Signals wait until the few renames are done."""
    import os

    from ..errors import SkewpendError
    from ..interrupts import Interrupts

    old = staging / "old"
    done: List[tuple] = []
    with Interrupts():
        try:
            old.mkdir()
            for name in EXPORT_ENTRIES:
                if name in replaced:
                    os.rename(target / name, old / name)
                    done.append((old / name, target / name))
                os.rename(site / name, target / name)
                done.append((target / name, site / name))
        except OSError as exc:
            for moved, back in reversed(done):
                with suppress(OSError):
                    os.rename(moved, back)
            raise SkewpendError(f"{what}: cannot write {target}: {exc.strerror or exc}") from None
