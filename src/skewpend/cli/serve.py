"""``serve``: the live explorer in the browser (the server is :func:`skewpend.views.explorer.serve`)."""

from __future__ import annotations

from typing import Annotated

import typer

from . import types as T
from .options import command, option

COMMANDS = ("serve",)


@command()
def serve(
    host: option("--host", T.Host(), "address to listen on (default 127.0.0.1: this machine only)", None) = None,
    port: option("--port", T.Port(), "TCP port (default 8000)", None) = None,
    open_browser: Annotated[bool, typer.Option("--open", help="open the page in the web browser")] = False,
) -> None:
    """The live explorer in the browser: the pendulum in 3D with sliders, equations, plots, normal
    modes and a flip map, on physics generated from the derivation (needs skewpend[web]).

    Ctrl-C stops the server.
    """
    from ..views import explorer

    explorer.serve(**{k: v for k, v in dict(host=host, port=port).items() if v is not None}, open_browser=open_browser)
