"""Sphinx glue for skewpend's docs.

* ``.. skewpend-cli::``: the CLI reference, generated from the Typer app itself (every
  command's help and every option's name, metavar, help and default, as ``--help`` prints
  them), never typed twice;
* a check that every public name (``skewpend.__all__``) is documented in the API reference: a
  name missing from it is a warning, which ``sphinx-build -W`` makes an error.
"""

from __future__ import annotations

import textwrap

import typer
from docutils import nodes
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective

import skewpend
from skewpend.cli import app as _app

logger = logging.getLogger(__name__)

#: the ``skewpend`` command as Click (Typer's own copy of it) sees it
cli_command = typer.main.get_command(_app)


def _rst_escape(text: str) -> str:
    import re

    text = text.replace("\\", "\\\\").replace("*", "\\*").replace("`", "\\`").replace("|", "\\|")
    return re.sub(r"(\w)_(?=\W|$)", r"\1\\_", text)  # a word's trailing _ (model_*) is no reference


def cli_rst() -> list[str]:
    """reStructuredText for every command: its help, then a table of its options."""
    root = cli_command.make_context("skewpend", [], resilient_parsing=True)
    lines: list[str] = []
    for name, cmd in cli_command.commands.items():
        title = f"skewpend {name}"
        lines += [title, "-" * len(title), ""]
        ctx = cmd.make_context(name, [], parent=root, resilient_parsing=True)
        usage = " ".join(cmd.collect_usage_pieces(ctx))
        lines += ["::", "", f"    skewpend {name} {usage}", ""]
        lines += [_rst_escape(line) for line in textwrap.dedent(cmd.help or "").splitlines()] + [""]
        records = [p.get_help_record(ctx) for p in cmd.params]
        records = [r for r in records if r is not None]
        if records:
            lines += [".. list-table::", "   :header-rows: 1", "   :widths: 35 65", "",
                      "   * - option", "     - meaning"]
            for opts, help_text in records:
                lines += [f"   * - ``{opts}``", f"     - {_rst_escape(help_text) or ' '}"]
            lines.append("")
    return lines


class CliDirective(SphinxDirective):
    """``.. skewpend-cli::`` -- the generated reference of every command."""

    has_content = False

    def run(self) -> list[nodes.Node]:
        container = nodes.section() if False else nodes.container()
        self.state.nested_parse(StringList(cli_rst(), source="skewpend --help"), self.content_offset, container,
                                match_titles=True)
        return container.children


def _gallery_scraper(block, block_vars, gallery_conf):
    """sphinx-gallery: every Matplotlib figure a gallery script has made (skewpend's figures are
    built without pyplot, so the default scraper does not see them), saved as the thumbnail and
    image of that script."""
    from matplotlib.figure import Figure
    from sphinx_gallery.scrapers import figure_rst

    seen = block_vars.setdefault("skewpend_figures", set())
    paths = []
    for value in list(block_vars["example_globals"].values()):
        if isinstance(value, Figure) and id(value) not in seen:
            seen.add(id(value))
            path = next(block_vars["image_path_iterator"])
            value.savefig(path, dpi=100, facecolor="white")
            paths.append(path)
    return figure_rst(paths, gallery_conf["src_dir"])


def _get_sg_image_scraper():
    """sphinx-gallery's hook: ``"image_scrapers": ("skewpend_docs",)``."""
    return _gallery_scraper


def public_names() -> list[str]:
    return [name for name in skewpend.__all__ if not name.startswith("__")]


def _check_api(app: Sphinx, env) -> None:
    documented = set(env.get_domain("py").objects)
    missing = [name for name in public_names() if f"skewpend.{name}" not in documented]
    if missing:
        logger.warning("public names missing from the API reference (docs/reference/api.md): %s",
                       ", ".join(missing), type="skewpend", subtype="api")


def _drop_widget_state(app: Sphinx, doctree) -> None:
    """No notebook widget's saved state in a page: without the widget manager (which myst-nb would
    load from a CDN; ``nb_ipywidgets_js = {}``) nothing renders it, and a widget's state carries
    its whole front end (megabytes).  The widget tutorial shows a picture instead."""
    files = getattr(app.env, "nb_metadata", {}).get(app.env.docname, {}).get("js_files", {})
    files.pop("ipywidgets_state", None)


def _patient_katex_server() -> None:
    """sphinxcontrib-katex connects to its Node.js server as soon as the server's socket file exists;
    Node creates the file when it binds and listens a moment later, so on a loaded machine the first
    connection may be refused (seen under CI: the build failed with ConnectionRefusedError). Here the
    connection is retried for a few seconds; the server it started keeps running and is connected to."""
    import socket
    import time

    try:
        from sphinxcontrib import katex
    except ImportError:  # pragma: no cover - the docs extra installs it
        return
    server = katex.KaTeXServer
    if getattr(server.start_server_process, "_skewpend_patient", False):
        return
    original = server.start_server_process.__func__

    def start_server_process(cls, rundir, timeout):
        real_connect = socket.socket.connect

        def connect(sock, address):
            deadline = time.monotonic() + max(float(timeout), 5.0)
            while True:
                try:
                    return real_connect(sock, address)
                except ConnectionRefusedError:  # bound, not yet listening
                    if time.monotonic() > deadline:
                        raise
                    time.sleep(0.02)

        socket.socket.connect = connect
        try:
            return original(cls, rundir, timeout)
        finally:
            socket.socket.connect = real_connect

    start_server_process._skewpend_patient = True  # type: ignore[attr-defined]
    server.start_server_process = classmethod(start_server_process)


def setup(app: Sphinx) -> dict:
    _patient_katex_server()
    app.connect("env-check-consistency", _check_api)
    app.connect("doctree-read", _drop_widget_state)
    app.add_directive("skewpend-cli", CliDirective)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
