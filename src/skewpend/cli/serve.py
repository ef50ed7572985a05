"""``serve``: the live explorer in the browser (the server is :func:`skewpend.views.explorer.serve`)."""

from __future__ import annotations

import sys
from typing import Annotated

import typer

from .. import schema
from . import types as T
from .options import CONFIG, command, option, resolve

COMMANDS = ("serve",)


@command()
def serve(
    host: option("--host", T.Host(), "address to listen on (default 127.0.0.1: this machine only)", None) = "127.0.0.1",
    port: option("--port", T.Port(), "TCP port (default 8000)", None) = "8000",
    open_browser: Annotated[bool, typer.Option("--open", help="open the page in the web browser")] = False,
    export: Annotated[str, typer.Option("--export", metavar="DIR", show_default=False,
                                        help="write the explorer as a static site to DIR (new, or a directory without the "
                                             "site's files: '.' too; other files in it are never touched) instead of "
                                             "serving it: it runs in any browser from the file system or a static "
                                             "host, with no server and no network")] = None,
    force: Annotated[bool, typer.Option("--force", help="with --export: replace an earlier export in DIR (only the files its "
                                                   "manifest lists; anything else there is refused or left alone)")] = False,
    config: CONFIG = None,
) -> None:
    """The live explorer in the browser: the pendulum in 3D with sliders, equations, plots, normal
    modes and a flip map, on physics generated from the derivation (needs skewpend[web]; with
    --export, nothing beyond skewpend itself).

    A --config run file sets the page's start: its [parameters]' bodies and axes (com1, inertia1,
    axis2, ...) the generated physics; a, b, m1, m2, alpha, g, c1, c2 and [initial] phi0, psi0 the
    sliders (within their ranges; the page's address holds them).  The double pendulum's page has
    no joint torques, Coulomb friction or rotor inertia: non-zero ones are refused.  A chain of
    links ([[links]], [chain]) gets its own page: its n rods, a start slider for each joint
    ([initial] q0), g and each joint's damping, its modes and a flip map over (q1, q2); its links'
    torques, Coulomb friction and rotors are in its physics as the file gives them (no sliders).
    The page starts at rest: [initial] dq0 (dphi0, dpsi0) may only be 0; [simulation] is not used.

    Ctrl-C stops the server.
    """
    from ..parsing import UsageError

    run = resolve("serve", config, defaults=False)
    params, query = _page_start(run)
    if export is None:
        if force:
            raise UsageError("--force: only with --export DIR (it replaces an earlier export)")
        from ..views import explorer

        url = _announce(explorer, host, port, query)
        kw = {} if config is None else {"physics_params": params}
        if open_browser and query:  # the page opened at the address that holds the run's values
            def ready(address, url=url):
                import threading
                import webbrowser

                threading.Thread(target=webbrowser.open, args=(url,), daemon=True).start()
            kw["ready"] = ready
        explorer.serve(host, port, open_browser=open_browser and not query, **kw)
        return
    given = [flag for flag, value, default in (("--host", host, "127.0.0.1"), ("--port", port, "8000")) if str(value) != default]
    if given:
        raise UsageError(f"{', '.join(given)}: not with --export (a static site has no server)")
    if export.strip() == "-":
        raise UsageError("--export -: a static site is a directory, not standard output; give its name")
    from ..views.frontend import export_explorer

    index = export_explorer(export, None if config is None else params, force=force, start=query)
    page = index.name + (f"?{query}" if query else "")
    sys.stderr.write(f"skewpend: wrote the static explorer to {index.parent}/ (open {page} in a browser)\n")
    if open_browser:
        import webbrowser

        webbrowser.open(index.resolve().as_uri() + (f"?{query}" if query else ""))


def _announce(explorer, host: str, port: int, query: str = "") -> str:
    """A bad or busy address in one line before starting (the library's check), a warning when
    serving beyond this machine, the address to open (with the run's values)."""
    explorer.require_web("skewpend serve")
    address = explorer.check_address(host, port)
    if address.warning:
        sys.stderr.write(f"skewpend: warning: {address.warning}\n")
    url = address.url + (f"?{query}" if query else "")
    sys.stderr.write(f"skewpend explorer on {url} (Ctrl-C to stop)\n")
    return url


#: What the page's sliders take (web/live.js SLIDERS), by section: the keys a run sets there.
_SLIDER_KEYS = {"parameters": ("alpha",) + schema.LENGTH_NAMES + schema.MASS_NAMES + ("g",) + schema.DAMPING_NAMES,
                "initial": ("phi0", "psi0")}
_DEGREES = ("alpha", "phi0", "psi0")  # shown (and held in the address) in degrees


def _slider_ranges() -> dict:
    """key -> (min, max) of the page's sliders, read from web/live.js (the one place they are written)."""
    import re

    from ..views.frontend import WEB_DIR

    text = (WEB_DIR / "live.js").read_text(encoding="utf-8")
    return {m.group(1): (float(m.group(2)), float(m.group(3)))
            for m in re.finditer(r'\[\s*"(\w+)",\s*"[^"]*",\s*(-?[\d.]+),\s*(-?[\d.]+),', text)}


def _chain_query(run, chain) -> str:
    """The address query of a chain's start angles ([initial] q0, in degrees: the sliders ``q<k>_0``)."""
    import math
    from urllib.parse import urlencode

    from ..parsing import UsageError
    from ..views.frontend import CHAIN_START

    if not run.is_given("initial", "q0"):
        return ""
    where = run.option("initial", "q0")
    q0 = run.initial_state()[:chain.n]
    lo, hi, _ = CHAIN_START
    values = {}
    for k, q in enumerate(q0, start=1):
        shown = math.degrees(q)
        if not lo <= shown <= hi:
            raise UsageError(f"{where}: joint {k}'s start {shown:.6g} deg is outside the explorer's slider range {lo:g} to "
                             f"{hi:g} deg; give angles within it")
        values[f"q{k}_0"] = repr(float(f"{shown:.15g}"))
    return urlencode(values)


def _page_start(run):
    """The run's model (its bodies and axes make the page's physics) and the page's address query
    of the slider values it sets; what the explorer cannot show is refused in one line."""
    import math
    from urllib.parse import urlencode

    from ..config import as_text
    from ..parsing import UsageError, parse_scalar

    params = run.parameters()
    for k in ("dphi0", "dpsi0", "dq0"):  # the page starts at rest: a start's rates are read to be checked 0
        if not run.is_given("initial", k):
            continue
        value, where = run.raw("initial", k), run.option("initial", k)
        items = [parse_scalar(as_text(x, where), where) for x in (value if isinstance(value, (list, tuple)) else [value])]
        if any(x != 0 for x in items):
            sliders = "each joint's start angle, q0" if k == "dq0" else "phi0 and psi0"
            raise UsageError(f"{where}: the explorer starts at rest (its sliders set {sliders}); give 0 "
                             "or leave it out, and simulate a start with speeds with skewpend simulate")
    if run.is_chain:  # a chain of links: its bodies, axes and joint terms are the page's physics, [initial] q0 its sliders
        return params, _chain_query(run, params)
    terms = schema.TORQUE_NAMES + schema.FRICTION_NAMES + schema.ROTOR_NAMES
    absent = [run.option("parameters", k) for k in terms
              if run.is_given("parameters", k) and getattr(params, k) != schema.default(k)]
    if absent:
        defaults = ", ".join(f"{k} {schema.default(k):g}" for k in terms if schema.default(k) != 0)
        raise UsageError(f"{', '.join(absent)}: the explorer has no joint torques, Coulomb friction or rotor inertia (its "
                         f"sliders cannot set them); leave them out or at their defaults (0; {defaults}), and simulate the "
                         "full model with skewpend simulate")
    ranges = _slider_ranges()
    values = {}
    for section, keys in _SLIDER_KEYS.items():
        for k in keys:
            if not run.is_given(section, k):
                continue
            where = run.option(section, k)
            value = run.scalar(section, k, angle=k in _DEGREES)
            if value is None:
                raise UsageError(f"{where}: the explorer's sliders need a number, not 'sym'")
            shown = math.degrees(value) if k in _DEGREES else value
            lo, hi = ranges[k]
            if not lo <= shown <= hi:
                unit = " deg" if k in _DEGREES else ""
                raise UsageError(f"{where} = {shown:.6g}{unit} is outside the explorer's slider range {lo:g} to {hi:g}{unit}; "
                                 "give a value within it")
            values[k] = repr(float(f"{shown:.15g}"))  # 30deg -> 30.0 (not the rounding of its radians)
    return params, urlencode(values)
