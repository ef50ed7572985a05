"""The documentation site builds with warnings as errors, and what it shows holds.

* ``sphinx-build -W`` over ``docs/``: the tutorials are executed (a failing cell, an ``assert``
  among them included, fails the build), the gallery's scripts run, internal links resolve, and
  every public name must be in the API reference (``docs/_ext/skewpend_docs.py``);
* the built site is offline: no page or stylesheet loads anything from another machine, and the
  mathematics is rendered to HTML at build time (no formula left for JavaScript to typeset);
* the docstring examples of the public API run (doctest).
"""

from __future__ import annotations

import doctest
import importlib
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import skewpend

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
BUILD_TIMEOUT = 1500  # s: the whole site, notebooks executed, on 2 cores (measured: see the README)


#: The build of this process (a worker may set the module's fixture up again after another module's
#: tests): its site, or why it failed.
_BUILD: dict = {}


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    from helpers import missing_node, skip_or_fail

    skip_or_fail(missing_node())  # KaTeX renders the formulas under Node.js at build time
    if not _BUILD:
        _BUILD.update(_built_once(tmp_path_factory))
    assert "error" not in _BUILD, _BUILD.get("error")
    return _BUILD["site"]


def _built_once(tmp_path_factory) -> dict:
    """The site built once per test session, whichever worker asks first (two builds at once race in
    the source tree's docs/auto_gallery, which sphinx-gallery writes; the workers' module groups do not
    always hold)."""
    from helpers import once_per_session

    done = once_per_session(tmp_path_factory, "docs-build",
                            lambda folder: {k: str(v) for k, v in _build(folder / "site").items()})
    return {"site": Path(done["site"])} if "site" in done else done


def _build(out: Path) -> dict:
    """sphinx-build into ``out``. Its output goes to a file, not a pipe, and its process group is
    ended afterwards: the KaTeX server it starts (Node.js) outlived a failed build holding the pipe,
    and the test waited for the pipe's end until its timeout."""
    import signal

    env = dict(os.environ, PYTHONWARNINGS="ignore::DeprecationWarning")
    log = out.parent / "sphinx.log"
    with open(log, "w+", encoding="utf-8") as fh:
        proc = subprocess.Popen([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-b", "html", "-q", str(DOCS), str(out)],
                                cwd=ROOT, env=env, stdout=fh, stderr=subprocess.STDOUT, text=True, start_new_session=True)
        try:
            code = proc.wait(timeout=BUILD_TIMEOUT)
        finally:
            try:
                os.killpg(proc.pid, signal.SIGKILL)  # what the build left running (its KaTeX server)
            except ProcessLookupError:
                pass
            proc.wait()
        fh.seek(0)
        text = fh.read()
    if code != 0:
        return {"error": f"sphinx-build -W failed (exit {code}):\n{text[-6000:]}"}
    return {"site": out}


def pages(site: Path) -> list[Path]:
    return sorted(p for p in site.rglob("*.html") if "_static" not in p.parts and "_sources" not in p.parts)


def test_every_page_is_built(site: Path) -> None:
    names = {str(p.relative_to(site)) for p in pages(site)}
    for md in DOCS.rglob("*.md"):
        rel = md.relative_to(DOCS)
        if rel.parts[0].startswith("_"):
            continue
        assert str(rel.with_suffix(".html")) in names, f"{rel} was not built"


# resources a page loads (not links a reader may follow)
_LOADS = re.compile(r"""<(?:script|img|iframe|source|video|audio)\b[^>]*\bsrc\s*=\s*["']([^"']+)["']|"""
                    r"""<link\b[^>]*\bhref\s*=\s*["']([^"']+)["'][^>]*>""", re.I)


def test_the_site_loads_nothing_from_elsewhere(site: Path) -> None:
    remote = []
    for page in pages(site):
        for m in _LOADS.finditer(page.read_text(encoding="utf-8")):
            url = m.group(1) or m.group(2)
            tag = m.group(0)
            if m.group(2) is not None and not re.search(r"rel\s*=\s*[\"']?(stylesheet|preload|icon|modulepreload)", tag):
                continue  # a navigation link, not a resource
            if re.match(r"(https?:)?//", url):
                remote.append(f"{page.relative_to(site)}: {url}")
    for css in site.rglob("*.css"):
        for url in re.findall(r"url\(\s*['\"]?((?:https?:)?//[^)'\"]+)", css.read_text(encoding="utf-8", errors="replace")):
            remote.append(f"{css.relative_to(site)}: {url}")
    assert not remote, "resources loaded from another machine:\n" + "\n".join(remote[:20])


def test_mathematics_is_rendered_at_build_time(site: Path) -> None:
    theory = (site / "theory" / "method.html").read_text(encoding="utf-8")
    assert theory.count('class="katex"') > 20
    assert "katex/katex.min.css" in theory and (site / "_static" / "katex" / "fonts").is_dir()
    for page in pages(site):
        html = page.read_text(encoding="utf-8")
        # sphinxcontrib-katex leaves \( \) or \[ \] for the browser when it does not prerender
        left = re.findall(r'<(?:span|div) class="math[^"]*">\s*\\[\(\[]', html)
        assert not left, f"{page.relative_to(site)}: formulas left for JavaScript"


def test_tutorials_are_executed(site: Path) -> None:
    for md in sorted((DOCS / "tutorials").glob("*.md")):
        if md.name == "index.md":
            continue
        html = (site / "tutorials" / md.with_suffix(".html").name).read_text(encoding="utf-8")
        outputs = html.count('class="cell_output')
        assert outputs >= 3, f"tutorials/{md.name}: {outputs} cell outputs (was it executed?)"
        assert "Traceback" not in html, f"tutorials/{md.name} shows a traceback"


def test_api_reference_lists_every_public_name(site: Path) -> None:
    html = "".join(p.read_text(encoding="utf-8") for p in (site / "reference").rglob("*.html"))
    missing = [n for n in skewpend.__all__ if not n.startswith("__") and f'id="skewpend.{n}"' not in html]
    assert not missing, f"public names without an entry in the API reference: {missing}"


def test_cli_reference_has_every_command(site: Path) -> None:
    import typer

    from skewpend.cli import app

    html = (site / "reference" / "cli.html").read_text(encoding="utf-8")
    group = typer.main.get_command(app)
    for name, cmd in group.commands.items():
        assert f"skewpend {name}" in html
        for param in cmd.params:
            for opt in param.opts:
                assert opt in html, f"skewpend {name} {opt} is not in the CLI reference"


def test_gallery_has_a_thumbnail_per_script(site: Path) -> None:
    scripts = sorted((DOCS / "gallery").glob("plot_*.py"))
    assert scripts, "no gallery scripts"
    index = (site / "auto_gallery" / "index.html").read_text(encoding="utf-8")
    for script in scripts:
        assert f"{script.stem}.html" in index, f"{script.name} has no entry in the gallery"
        assert list((site / "_images").glob(f"sphx_glr_{script.stem}_*.png")), f"{script.name} drew no figure"


def _public_objects():
    seen = set()
    for name in skewpend.__all__:
        if name.startswith("__"):
            continue
        obj = getattr(skewpend, name)
        module = importlib.import_module(getattr(obj, "__module__", None) or "skewpend")
        if module.__name__ not in seen:
            seen.add(module.__name__)
            yield module


def test_docstring_examples_run() -> None:
    """Every ``>>>`` example in the modules behind the public API runs and prints what it shows."""
    finder = doctest.DocTestFinder()
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    examples = 0
    for module in _public_objects():
        for test in finder.find(module):
            examples += len(test.examples)
            runner.run(test)
    assert examples >= 8, f"only {examples} docstring examples found"
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} docstring example(s) failed (see the output above)"


def test_no_page_carries_a_notebook_widget_s_state(site: Path) -> None:
    # the widget tutorial executes a widget; its saved state (the whole front end, megabytes) would
    # be rendered by nothing in an offline page (docs/_ext/skewpend_docs.py drops it)
    page = (site / "tutorials" / "widget.html").read_text(encoding="utf-8")
    assert "widget.png" in page and "refused: m2 must be &gt; 0" in page
    for p in pages(site):
        assert "application/vnd.jupyter.widget-state+json" not in p.read_text(encoding="utf-8"), p
        assert p.stat().st_size < 1_500_000, (p, p.stat().st_size)
