"""The browser front end's JavaScript, as one set of sources shared by every view that runs in a
browser: the served explorer (``skewpend serve``), the static explorer (:func:`export_explorer`,
``skewpend explorer``), the report's live 3D view and the notebook widget.

The sources are the vendored three.js (from the npm package, never a CDN), the physics generated
from the derivation (:func:`skewpend.numeric.codegen.explorer_js`: motion, energy, drawing,
linearisation and the equations' coefficients), the DOP853 tableau, and the page's own scripts in
``web/``.  Each is delivered as a *registration*: a classic script that stores the text with its
import specifiers (``web/loader.js`` turns the modules into ``blob:`` URLs at run time), so the
same page runs from a server, from the file system -- browsers refuse module files from
``file://`` -- and inlined in one HTML file, with no request leaving it.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources
from pathlib import Path
from typing import Dict, List

__all__ = ["Source", "sources", "registration", "export_explorer", "inline_page_scripts", "WEB_DIR", "katex_dir",
           "SOURCE_ORDER", "REPLAY_ORDER", "WIDGET_ORDER", "module_bundle", "replay_data"]

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
SOURCE_ORDER = ("three-core", "three", "three-orbit", "physics", "scene", "live", "explorer", "physics-classic", "dop853",
                "flipworker")
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
    from ..numeric.codegen import dop853_js

    out = [
        Source("three-core", _read(_THREE / "three.core.js")),
        Source("three", _read(_THREE / "three.module.js"), {"./three.core.js": "three-core"}),
        Source("three-orbit", _read(_THREE / "addons" / "controls" / "OrbitControls.js"), {"three": "three"}),
        Source("scene", _read(WEB_DIR / "scene.js"),
               {"three": "three", "three/addons/controls/OrbitControls.js": "three-orbit"}),
        Source("live", _read(WEB_DIR / "live.js")),
        Source("explorer", _read(WEB_DIR / "app.js"),
               {"three": "three", "./scene.js": "scene", "./physics.js": "physics", "./live.js": "live"}),
        Source("replay", _read(WEB_DIR / "replay.js"), {"./scene.js": "scene", "./live.js": "live"}),
        Source("widget", _read(WEB_DIR / "widget.js"), {"./scene.js": "scene", "./physics.js": "physics", "./live.js": "live"}),
        Source("dop853", dop853_js(), classic=True),
        Source("flipworker", _read(WEB_DIR / "flipworker.js"), classic=True),
    ]
    return tuple(_checked(s) for s in out)


@lru_cache(maxsize=8)
def _physics_sources(physics_params) -> tuple:
    from ..numeric.codegen import classic_js, explorer_js
    from ..symbolic.model import Parameters

    module = explorer_js(physics_params if physics_params is not None else Parameters())
    return (Source("physics", module), Source("physics-classic", classic_js(module, "physics"), classic=True))


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
    times ``t`` [s], states ``y``, the library's rod ends ``tips`` and hinge axes ``axes`` at
    each row, and the length scale ``size`` [m] of the drawn axes -- plain lists, written exactly."""
    p = trajectory.params
    return {"t": trajectory.t.tolist(), "y": trajectory.y.tolist(), "tips": trajectory.tips().tolist(),
            "axes": trajectory.axes().tolist(), "size": max(float(p.a), float(p.b))}


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


def export_explorer(directory, params=None, *, force: bool = False) -> Path:
    """Write the static explorer to ``directory``: ``index.html`` with the page's files beside it
    (``static/``: styles, KaTeX, the loader; ``sources/``: three.js, the generated physics and the
    page's scripts as registrations; ``LICENSES/``).  It runs entirely in the browser, opened from
    the file system or any static web host, with the network off; the physics is generated for
    the bodies and axes of ``params`` (default: the specification's thin rods).

    ``directory`` must not exist, or be empty, or (``force=True``) be an earlier export (it is
    then replaced); anything else is refused with :class:`ParameterError`.  The site is written
    to a temporary directory beside it and moved into place, so an interruption leaves no half
    site.  Returns the path of ``index.html``."""
    from ..errors import ParameterError

    target = Path(directory)
    marker = ".skewpend-explorer"
    if target.exists():
        if not target.is_dir():
            raise ParameterError(f"explorer export: {target} exists and is not a directory; give a new directory")
        existing = list(target.iterdir())
        if existing and not (force and (target / marker).exists()):
            what = "an earlier export: pass force=True (--force) to replace it" if (target / marker).exists() else \
                "a directory with other files in it; give a new or empty directory"
            raise ParameterError(f"explorer export: {target} is {what}")
    if not target.parent.is_dir():
        raise ParameterError(f"explorer export: the parent directory {target.parent} does not exist")
    srcs = sources(params)  # generated first: an error leaves nothing behind
    tmp = target.parent / f".{target.name}.tmp-export"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        (tmp / "static").mkdir(parents=True)
        (tmp / "sources").mkdir()
        (tmp / "LICENSES").mkdir()
        for name in ("app.css", "loader.js"):
            shutil.copy2(WEB_DIR / name, tmp / "static" / name)
        shutil.copytree(katex_dir(), tmp / "static" / "katex")
        for src in srcs.values():
            (tmp / "sources" / f"{src.name}.js").write_text(registration(src), encoding="utf-8")
        for path, name in _licences():
            shutil.copy2(path, tmp / "LICENSES" / f"{name}.txt")
        (tmp / "index.html").write_text(_read(WEB_DIR / "index.html"), encoding="utf-8")
        from .. import __version__

        (tmp / marker).write_text(json.dumps({"skewpend": __version__}) + "\n", encoding="utf-8")
        if target.exists():
            old = target.parent / f".{target.name}.old-export"
            shutil.rmtree(old, ignore_errors=True)
            target.rename(old)
            tmp.rename(target)
            shutil.rmtree(old, ignore_errors=True)
        else:
            tmp.rename(target)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return target / "index.html"


