"""The bundled three.js (``tools/vendor_three.py``): what SOURCE.json records is what is there, the
licence is MIT, nothing is fetched from the network at run time, every relative import resolves."""

from __future__ import annotations

import hashlib
import importlib.util
import json
import posixpath
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(importlib.util.find_spec("skewpend").origin).parent / "views" / "web" / "vendor" / "three"

# ``import ... from "x"`` / ``export ... from "x"`` / ``import "x"`` starting a line or after ``;`` or
# ``}`` (minified code), not inside ``* import { X } from ...`` doc comments; and ``import("x")``.
_STATIC = re.compile(r"""(?:^|[;}])[ \t]*(?:(?:import|export)\b[\w\s{}*,$]*?\bfrom|import)\s*(['"])([^'"\n]+)\1""",
                     re.MULTILINE)
_DYNAMIC = re.compile(r"""\bimport\s*\(\s*(['"])([^'"\n]+)\1\s*\)""")
# what a browser would fetch from elsewhere: a module or fetch() from an absolute http(s) URL, a CDN
_REMOTE_LOAD = re.compile(r"""\b(?:from|import|fetch|importScripts)\s*\(?\s*['"`]\s*(?:https?:)?//""", re.IGNORECASE)
_CDN = re.compile(r"//cdn|unpkg|jsdelivr", re.IGNORECASE)


def _source() -> dict:
    return json.loads((ROOT / "SOURCE.json").read_text())


def _modules() -> list[str]:
    return sorted(rel for rel in _source()["files"] if rel.endswith((".js", ".mjs")))


def _specifiers(text: str) -> list[str]:
    return [m.group(2) for m in _STATIC.finditer(text)] + [m.group(2) for m in _DYNAMIC.finditer(text)]


def test_source_json_lists_exactly_the_files_there_with_their_sha256():
    source = _source()
    assert source["package"] == "three" and re.fullmatch(r"0\.\d+\.\d+", source["version"])
    assert source["integrity"].startswith("sha512-")
    present = {p.relative_to(ROOT).as_posix() for p in ROOT.rglob("*") if p.is_file()} - {"SOURCE.json"}
    assert present == set(source["files"])
    for rel, digest in source["files"].items():
        assert hashlib.sha256((ROOT / rel).read_bytes()).hexdigest() == digest, rel
    assert source["entry"] in source["files"] and source["entry"].startswith("three.module")
    assert "addons/controls/OrbitControls.js" in source["files"]


def test_license_is_mit():
    assert _source()["license"] == "MIT"
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("The MIT License") and "three.js authors" in text


def test_modules_load_nothing_from_the_network():
    for rel in _modules():
        text = (ROOT / rel).read_text(encoding="utf-8")
        assert not _REMOTE_LOAD.search(text), (rel, _REMOTE_LOAD.search(text).group(0))
        assert not _CDN.search(text), (rel, _CDN.search(text).group(0))
        for spec in _specifiers(text):
            assert not re.match(r"(?:[a-z][a-z0-9+.-]*:|//)", spec, re.IGNORECASE), (rel, spec)


def test_every_relative_import_resolves_to_a_bundled_file():
    files = set(_source()["files"])
    seen = {}
    for rel in _modules():
        specs = seen[rel] = _specifiers((ROOT / rel).read_text(encoding="utf-8"))
        for spec in specs:
            if spec.startswith(("./", "../")):
                target = posixpath.normpath(posixpath.join(posixpath.dirname(rel), spec))
                assert target in files, (rel, spec)
            else:  # bare: only what the page's import map resolves
                assert spec == "three", (rel, spec)
    # the scan is not vacuous: the entry pulls in the core, the controls import "three"
    entry = _source()["entry"]
    assert any(s.startswith("./three.core") for s in seen[entry]), seen[entry]
    assert seen["addons/controls/OrbitControls.js"] == ["three"]


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_modules_load_in_node_through_an_import_map_like_resolution(tmp_path):
    source = _source()
    entry = (ROOT / source["entry"]).as_uri()
    (tmp_path / "hooks.mjs").write_text(
        "export async function resolve(spec, ctx, next) {\n"
        f"  return spec === 'three' ? {{ url: {json.dumps(entry)}, shortCircuit: true }} : next(spec, ctx);\n"
        "}\n")
    (tmp_path / "register.mjs").write_text(
        "import { register } from 'node:module';\nregister('./hooks.mjs', import.meta.url);\n")
    (tmp_path / "check.mjs").write_text(
        f"import * as THREE from {json.dumps(entry)};\n"
        f"import {{ OrbitControls }} from {json.dumps((ROOT / 'addons/controls/OrbitControls.js').as_uri())};\n"
        "const camera = new THREE.PerspectiveCamera(50, 1, 0.1, 100);\n"
        "new OrbitControls(camera).update();\n"
        "console.log(THREE.REVISION, typeof THREE.WebGLRenderer);\n")
    out = subprocess.run(["node", "--import", "./register.mjs", "check.mjs"], cwd=tmp_path,
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == [source["version"].split(".")[1], "function"]
