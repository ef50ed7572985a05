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
    """Transitional (until explorer.serve checks its address itself): a busy port in one line
    before starting, a warning when serving beyond this machine, the address to open."""
    import ipaddress
    import socket

    from ..parsing import UsageError

    explorer.require_web("skewpend serve")
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError as exc:
            raise UsageError(f"--port: cannot listen on {host}:{port}: {exc.strerror or exc}; choose another --port "
                             "or --host") from None
    try:
        loopback = ipaddress.ip_address(host).is_loopback
    except ValueError:
        loopback = host == "localhost"
    if not loopback:
        sys.stderr.write(f"skewpend: warning: serving on {host}:{port}, not only on this machine: anyone who can reach "
                         "it can use the explorer (its work per request is bounded)\n")
    shown = "127.0.0.1" if host in ("0.0.0.0", "::") else (f"[{host}]" if ":" in host else host)
    sys.stderr.write(f"skewpend explorer on http://{shown}:{port}/ (Ctrl-C to stop)\n")
