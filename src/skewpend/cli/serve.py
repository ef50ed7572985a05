"""``serve``: the live explorer in the browser (the server is :func:`skewpend.views.explorer.serve`)."""

from __future__ import annotations

import sys
from typing import Annotated

import typer

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
    sliders (within their ranges; the page's address holds them).  Constant joint torques (tau1,
    tau2), Coulomb friction (cf1, cf2, cfs) and rotor inertia (Ir, gr) are in the page's physics as
    the file gives them (no sliders); with friction or rotors the physics is the recursive
    algorithms' and the sliders are g, c1, c2 and the start.  A chain of links ([[links]], [chain])
    gets the same page for its n rods: a start slider for each joint ([initial] q0), g and each
    joint's damping, its modes and a flip map over (q1, q2); its links' torques, Coulomb friction
    and rotors are in its physics as the file gives them (no sliders).
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


def _start_angles(run, coordinates) -> dict:
    """The start angles the run gives, by coordinate: ``{k: (value [rad], where as the user knows it)}`` -- a list
    ``[initial] q0`` (``--q0``), or one key a coordinate (``phi0``, ``psi0``)."""
    if run.is_given("initial", "q0"):
        where = run.option("initial", "q0")
        return {k: (q, f"{where} (joint {k + 1})") for k, q in enumerate(run.initial_state()[:len(coordinates)])}
    keys = {k: f"{c}0" for k, c in enumerate(coordinates)}
    return {k: (run.scalar("initial", key, angle=True), run.option("initial", key)) for k, key in keys.items()
            if run.is_given("initial", key)}


def _page_start(run):
    """The run's model (its bodies and axes make the page's physics) and the page's address query
    of the slider values it sets (the sliders: :func:`skewpend.views.frontend.page_sliders`); what the
    explorer cannot show is refused in one line."""
    import math
    from urllib.parse import urlencode

    from ..config import as_text
    from ..parsing import UsageError, parse_scalar
    from ..views.frontend import page_sliders

    params = run.parameters()
    if not params.is_numeric and (params.has_friction or params.has_rotor):
        # the page's physics is then the recursive algorithms' (explorer_source.page_form), its bodies numbers: a value
        # the file leaves out is the reference case's, as the sliders' start is where the derivation prints the page
        from ..config import reference_parameters

        named = [run.option("parameters", k) for k in params.symbolic_names if run.is_given("parameters", k)]
        if named:
            raise UsageError(f"{', '.join(named)}: with Coulomb friction or rotor inertia the page's bodies are numbers "
                             "(its sliders set g and the damping); give a number")
        reference = reference_parameters()
        params = params.replace(**{k: getattr(reference, k) for k in params.symbolic_names})
    for k in ("dphi0", "dpsi0", "dq0"):  # the page starts at rest: a start's rates are read to be checked 0
        if not run.is_given("initial", k):
            continue
        value, where = run.raw("initial", k), run.option("initial", k)
        items = [parse_scalar(as_text(x, where), where) for x in (value if isinstance(value, (list, tuple)) else [value])]
        if any(x != 0 for x in items):
            sliders = "each joint's start angle, q0" if k == "dq0" else "phi0 and psi0"
            raise UsageError(f"{where}: the explorer starts at rest (its sliders set {sliders}); give 0 "
                             "or leave it out, and simulate a start with speeds with skewpend simulate")
    # torques, Coulomb friction and rotors are the page's physics as the file gives them (explorer_source.page_form:
    # the derivation with the constant torques in p; with friction or rotors the recursive form, as a chain's)
    sliders = page_sliders(params)
    n = len(params.coordinates)
    given = {key: (run.scalar("parameters", key, angle=degrees), run.option("parameters", key))
             for key, *_, degrees in sliders[:-n] if run.is_given("parameters", key)}
    given.update({sliders[len(sliders) - n + k][0]: v for k, v in _start_angles(run, params.coordinates).items()})
    ranges = {key: (lo, hi, unit) for key, _, lo, hi, _, _, unit, _ in sliders}
    values = {}
    for key, (value, where) in given.items():
        if value is None:
            raise UsageError(f"{where}: the explorer's sliders need a number, not 'sym'")
        lo, hi, unit = ranges[key]
        unit = " deg" if unit == "°" else ""
        shown = math.degrees(value) if unit else value
        if not lo <= shown <= hi:
            raise UsageError(f"{where} = {shown:.6g}{unit} is outside the explorer's slider range {lo:g} to {hi:g}{unit}; "
                             "give a value within it")
        values[key] = repr(float(f"{shown:.15g}"))  # 30deg -> 30.0 (not the rounding of its radians)
    return params, urlencode(values)
