"""``serve``: the live explorer in the browser (the server is :func:`skewpend.views.explorer.serve`)."""

from __future__ import annotations

import sys
from typing import Annotated

import typer

from . import types as T
from .options import command, option

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
) -> None:
    """The live explorer in the browser: the pendulum in 3D with sliders, equations, plots, normal
    modes and a flip map, on physics generated from the derivation (needs skewpend[web]; with
    --export, nothing beyond skewpend itself).

    Ctrl-C stops the server.
    """
    from ..parsing import UsageError

    if export is None:
        if force:
            raise UsageError("--force: only with --export DIR (it replaces an earlier export)")
        from ..views import explorer

        _announce(explorer, host, port)
        explorer.serve(host, port, open_browser=open_browser)
        return
    given = [flag for flag, value, default in (("--host", host, "127.0.0.1"), ("--port", port, "8000")) if str(value) != default]
    if given:
        raise UsageError(f"{', '.join(given)}: not with --export (a static site has no server)")
    if export.strip() == "-":
        raise UsageError("--export -: a static site is a directory, not standard output; give its name")
    from ..views.frontend import export_explorer

    index = export_explorer(export, force=force)
    sys.stderr.write(f"skewpend: wrote the static explorer to {index.parent}/ (open {index.name} in a browser)\n")
    if open_browser:
        import webbrowser

        webbrowser.open(index.resolve().as_uri())


def _announce(explorer, host: str, port: int) -> None:
    """A bad or busy address in one line before starting (the library's check), a warning when
    serving beyond this machine, the address to open."""
    explorer.require_web("skewpend serve")
    address = explorer.check_address(host, port)
    if address.warning:
        sys.stderr.write(f"skewpend: warning: {address.warning}\n")
    sys.stderr.write(f"skewpend explorer on {address.url} (Ctrl-C to stop)\n")
