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
) -> None:
    """The live explorer in the browser: the pendulum in 3D with sliders, equations, plots, normal
    modes and a flip map, on physics generated from the derivation (needs skewpend[web]).

    Ctrl-C stops the server.
    """
    from ..views import explorer

    _announce(explorer, host, port)
    explorer.serve(host, port, open_browser=open_browser)


def _announce(explorer, host: str, port: int) -> None:
    """A bad or busy address in one line before starting (the library's check), a warning when
    serving beyond this machine, the address to open."""
    explorer.require_web("skewpend serve")
    address = explorer.check_address(host, port)
    if address.warning:
        sys.stderr.write(f"skewpend: warning: {address.warning}\n")
    sys.stderr.write(f"skewpend explorer on {address.url} (Ctrl-C to stop)\n")
