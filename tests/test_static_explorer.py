"""The static explorer's files (``skewpend serve --export DIR``, ``views.frontend.export_explorer``)
without a browser: what is written, what is refused, the registrations' safety, and the numbers
the page's workers integrate with.  The page itself is tested in Chromium from file:// by
test_explorer_browser.py (every test there runs on the served and the static page)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from skewpend.views import frontend

ROOT = Path(__file__).resolve().parents[1]


def test_the_export_is_a_complete_site(tmp_path):
    index = frontend.export_explorer(tmp_path / "site")
    site = index.parent
    assert index.name == "index.html"
    html = index.read_text()
    # every script and style the page names is in the site, by a relative path
    refs = re.findall(r'(?:src|href)="([^"#]+)"', html)
    assert refs and all(not r.startswith(("/", "http:", "https:")) for r in refs), refs
    for ref in refs:
        if not ref.startswith("data:"):
            assert (site / ref).is_file(), ref
    # the page loads exactly the front end's sources, in order
    listed = re.findall(r'src="sources/([\w-]+)\.js"', html)
    assert tuple(listed) == frontend.SOURCE_ORDER
    # KaTeX's fonts and both licences are there
    assert any((site / "static" / "katex" / "fonts").glob("KaTeX_Main-Regular.woff2"))
    assert {p.name for p in (site / "LICENSES").iterdir()} == {"three.js.txt", "KaTeX.txt"}


def test_no_source_loads_anything_from_elsewhere():
    remote = re.compile(r"""\b(?:from|import|fetch|importScripts)\s*\(?\s*['"`]\s*(?:https?:)?//""", re.IGNORECASE)
    for src in frontend.sources().values():
        assert not remote.search(src.code), src.name


def test_registrations_are_safe_to_inline_and_read_back_exactly():
    """A registration is JavaScript that stores the source's exact text -- also when inlined in an
    HTML page (no ``</script>`` or ``<!--`` can end or confuse the script element)."""
    tricky = frontend.Source("x", 'const s = "</script><!-- \\u2028 ü";\n', {"a": "b"})
    text = frontend.registration(tricky)
    assert "</script" not in text.lower() and "<!--" not in text
    prefix = '(self.SKEWPEND_SOURCES = self.SKEWPEND_SOURCES || {})["x"] = '
    assert text.startswith(prefix) and text.endswith(";\n")
    entry = json.loads(text[len(prefix):-2].replace("<\\!--", "<!--"))
    assert entry == {"code": tricky.code, "imports": {"a": "b"}, "classic": False}


def test_every_import_a_source_names_is_in_its_code():
    srcs = frontend.sources()
    for src in srcs.values():
        for specifier, dep in src.imports.items():
            assert dep in srcs
            assert f'from "{specifier}"' in src.code or f"from '{specifier}'" in src.code
    with pytest.raises(RuntimeError, match="does not import"):
        frontend._checked(frontend.Source("y", "export const a = 1;", {"three": "three"}))


def test_a_module_imports_nothing_it_does_not_declare():
    """The loader replaces only the declared specifiers: any other import in a module (three.js
    updated with a new file, say) would fail in the browser, so it must fail here first."""
    pattern = re.compile(r"""^\s*(?:import|export)\b[^;'"]*?\bfrom\s*(['"])([^'"]+)\1""", re.M)
    for src in frontend.sources().values():
        if src.classic:
            continue
        used = {m.group(2) for m in pattern.finditer(src.code)}
        assert used <= set(src.imports), (src.name, used - set(src.imports))


def test_the_export_refuses_what_it_must_not_overwrite(tmp_path):
    from skewpend.errors import ParameterError

    (tmp_path / "busy").mkdir()
    (tmp_path / "busy" / "index.html").write_text("mine")
    with pytest.raises(ParameterError, match="already has index.html, which no export wrote"):
        frontend.export_explorer(tmp_path / "busy")
    with pytest.raises(ParameterError, match="not an earlier export"):
        frontend.export_explorer(tmp_path / "busy", force=True)
    assert [p.name for p in (tmp_path / "busy").iterdir()] == ["index.html"]
    assert (tmp_path / "busy" / "index.html").read_text() == "mine"
    (tmp_path / "file").write_text("x")
    with pytest.raises(ParameterError, match="not a directory"):
        frontend.export_explorer(tmp_path / "file")
    with pytest.raises(ParameterError, match="parent directory"):
        frontend.export_explorer(tmp_path / "missing" / "site")
    # an earlier export: refused without force, replaced with it; a file beside it is kept
    frontend.export_explorer(tmp_path / "site")
    with pytest.raises(ParameterError, match="earlier export"):
        frontend.export_explorer(tmp_path / "site")
    (tmp_path / "site" / "CNAME").write_text("example.org")
    (tmp_path / "site" / "index.html").write_text("old")
    frontend.export_explorer(tmp_path / "site", force=True)
    assert (tmp_path / "site" / "CNAME").read_text() == "example.org"
    assert (tmp_path / "site" / "index.html").read_text() != "old"
    # a directory with other files: the site is added beside them
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "notes.txt").write_text("mine")
    frontend.export_explorer(tmp_path / "notes")
    assert (tmp_path / "notes" / "index.html").is_file() and (tmp_path / "notes" / "notes.txt").read_text() == "mine"
    # nothing temporary is left beside them or inside them
    assert sorted(p.name for p in tmp_path.iterdir()) == ["busy", "file", "notes", "site"]
    assert not [p for p in (tmp_path / "site").iterdir() if "export" in p.name]


def _cli(*args, cwd=None):
    from helpers import without_stages

    r = subprocess.run([sys.executable, "-m", "skewpend", *args], capture_output=True, text=True, cwd=cwd, timeout=300)
    r.stderr = without_stages(r.stderr)[0]  # the stage lines (issue 36) apart from the messages
    return r


def test_the_command_line_export(tmp_path):
    r = _cli("serve", "--export", str(tmp_path / "site"))
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "site" / "index.html").is_file() and "index.html" in r.stderr
    for args, words in ((["--export", str(tmp_path / "site")], "--force"),
                        (["--export", str(tmp_path / "other"), "--port", "9000"], "--port: not with --export"),
                        (["--force"], "--force: only with --export"),
                        (["--export", str(tmp_path / "no" / "site")], "does not exist")):
        r = _cli("serve", *args)
        assert r.returncode == 2 and words in r.stderr and "Traceback" not in r.stderr, (args, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "other").exists()


def test_the_workers_tableau_is_the_compiled_integrator_s():
    """The page's DOP853 tableau (from SciPy, printed by dop853_js) has the very numbers of
    integrators.c's tables: both integrators are the same method."""
    from skewpend.numeric.codegen import dop853_js

    js = dop853_js()
    tables = json.loads("{" + re.sub(r"(\b[A-Z0-9]+\b):", r'"\1":', js[js.index("{") + 1:js.rindex("}")]) + "}")
    c = (ROOT / "src" / "skewpend" / "numeric" / "integrators.c").read_text()

    def c_table(name):
        body = re.search(rf"static const double DOP_{name}(?:\[\d+\])+ = \{{(.*?)\}};", c, re.S).group(1)
        return np.array([float(x) for x in re.findall(r"-?\d+\.\d+(?:e-?\d+)?", body)])

    for name in ("A", "C", "E3", "E5", "D"):
        np.testing.assert_array_equal(np.ravel(tables[name]), c_table(name), err_msg=name)
    assert tables["NS"] == 12 and tables["NSTAGES"] == 16


def test_the_generated_equation_terms_rebuild_the_derivation():
    """TERMS x coefficients(p) summed is M and f of the symbolic derivation (a sympy identity), for
    the thin rods and for general bodies and axes."""
    import sympy as sp

    from skewpend import Parameters
    from skewpend.numeric.codegen import equation_terms, expressions, geometry_of
    from skewpend.symbolic.symbols import SYMBOLS as S

    for params in (Parameters(), Parameters(com2=(0.1, 0.5, 0.05), inertia2=((0.05, 0.01, 0.0), (0.01, 0.02, 0.0),
                                                                           (0.0, 0.0, 0.06)))):
        ex = expressions(geometry_of(params))
        terms = equation_terms(ex.M, ex.f)
        state = {S["phi"], S["psi"], S["dphi"], S["dpsi"]}
        for name, value in zip(("M11", "M12", "M22", "f1", "f2"), (ex.M[0, 0], ex.M[0, 1], ex.M[1, 1], ex.f[0], ex.f[1])):
            mine = [(m, c) for n, _, m, c in terms if n == name]
            assert all(not (c.free_symbols & state) for _, c in mine)
            assert sp.expand(sum(m * c for m, c in mine) - value) == 0, name
