#!/usr/bin/env python3
"""Vendor three.js into the package, for the browser explorer (served under ``/static/vendor/three/``).

Fetches the ``three`` package from the npm registry with the ordinary client (``npm pack
three@VERSION``: one tarball, no install scripts run), checks it, and copies what the explorer
loads into ``src/skewpend/views/web/vendor/three/``:

* the ES-module build and every module it imports, with the relative imports kept valid: the
  entry is ``build/three.module.min.js`` when the package ships it, else ``build/three.module.js``
  (three r186 and later publish no minified builds, see mrdoob/three.js#33893); both import
  ``./three.core[.min].js``, so the page's module loader (``web/loader.js``, fed by
  ``skewpend.views.frontend``) gives ``"three"`` the entry module and its ``./three.core.js``
  import the core module (the entry's name is recorded in ``SOURCE.json``);
* ``examples/jsm/controls/OrbitControls.js`` as ``addons/controls/OrbitControls.js`` (it imports
  ``'three'``, resolved by the same loader);
* ``LICENSE`` (MIT), and ``SOURCE.json``: version, the tarball's integrity string as the
  registry gave it, the entry module, and the SHA-256 of every copied file (checked by
  ``tests/test_vendor_three.py``).

The produced files are committed; run this only to move to another three.js version::

    python tools/vendor_three.py            # the version pinned below
    python tools/vendor_three.py 0.185.1    # another one (0.185.1 is the last with minified builds)
"""

from __future__ import annotations

import json
import posixpath
import re
import shutil
import sys
import tempfile
from pathlib import Path

from _npm import npm_pack, sha256, summary, write_source  # tools/ is on sys.path when run

#: The three.js version the package ships (``npm view three version`` when it was vendored).
VERSION = "0.187.0"

ROOT = Path(__file__).resolve().parent.parent
DEST = ROOT / "src" / "skewpend" / "views" / "web" / "vendor" / "three"

#: Where the copied modules go: a path in the npm package, by prefix, -> a path under ``DEST``.
#: A relative import must stay inside one of these folders (else it could not stay valid).
PLACES = {"build/": "", "examples/jsm/": "addons/"}
#: The add-ons the explorer uses (paths in the npm package).
ADDONS = ["examples/jsm/controls/OrbitControls.js"]
#: The only bare specifiers a copied module may import: the page's import map resolves them.
BARE_OK = {"three"}

# Static ``import ... from "x"`` / ``export ... from "x"`` / ``import "x"`` at the start of a line
# or after ``;`` or ``}`` (so also in minified code, but not in ``* import { X } from ...`` JSDoc
# examples), and dynamic ``import("x")``.
_STATIC = re.compile(r"""(?:^|[;}])[ \t]*(?:(?:import|export)\b[\w\s{}*,$]*?\bfrom|import)\s*(['"])([^'"\n]+)\1""",
                     re.MULTILINE)
_DYNAMIC = re.compile(r"""\bimport\s*\(\s*(['"])([^'"\n]+)\1\s*\)""")


def module_specifiers(text: str) -> list[str]:
    """The module specifiers ``text`` (an ES module) imports or re-exports from, in order."""
    found = [m.group(2) for m in _STATIC.finditer(text)] + [m.group(2) for m in _DYNAMIC.finditer(text)]
    return list(dict.fromkeys(found))


_sha256 = sha256


def _dest_rel(pkg_rel: str) -> str:
    for prefix, place in PLACES.items():
        if pkg_rel.startswith(prefix):
            return place + pkg_rel[len(prefix):]
    raise SystemExit(f"vendor_three: {pkg_rel} is outside the folders copied ({', '.join(PLACES)})")


def fetch(version: str, workdir: Path) -> tuple[Path, dict]:
    """``npm pack three@version`` into ``workdir``; returns the unpacked ``package/`` and npm's record."""
    return npm_pack("three", version, workdir)


def module_closure(package: Path, roots: list[str]) -> list[str]:
    """``roots`` (paths in the package) and every module they import, relatively, transitively."""
    todo, seen = list(roots), []
    while todo:
        rel = todo.pop(0)
        if rel in seen:
            continue
        path = package / rel
        if not path.is_file():
            raise SystemExit(f"vendor_three: {rel} is not in the package")
        seen.append(rel)
        for spec in module_specifiers(path.read_text(encoding="utf-8")):
            if spec.startswith(("./", "../")):
                target = posixpath.normpath(posixpath.join(posixpath.dirname(rel), spec))
                _dest_rel(target)  # fails if the import would leave the copied folders
                todo.append(target)
            elif spec not in BARE_OK:
                raise SystemExit(f"vendor_three: {rel} imports {spec!r}, which the import map does not resolve")
    return seen


def vendor(version: str = VERSION, dest: Path = DEST) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        package, record = fetch(version, Path(tmp))
        meta = json.loads((package / "package.json").read_text())
        if meta.get("name") != "three" or meta.get("version") != version:
            raise SystemExit(f"vendor_three: npm gave {meta.get('name')}@{meta.get('version')}, expected three@{version}")
        if meta.get("license") != "MIT":
            raise SystemExit(f"vendor_three: three@{version} is under {meta.get('license')!r}, not MIT")
        entry = next((f"build/{name}" for name in ("three.module.min.js", "three.module.js")
                      if (package / "build" / name).is_file()), None)
        if entry is None:
            raise SystemExit("vendor_three: no build/three.module[.min].js in the package")
        modules = module_closure(package, [entry] + ADDONS)
        if dest.exists():
            shutil.rmtree(dest)
        copied = []
        for pkg_rel, rel in [(m, _dest_rel(m)) for m in modules] + [("LICENSE", "LICENSE")]:
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(package / pkg_rel, dest / rel)
            copied.append(rel)
        source = {
            "package": "three",
            "version": version,
            "fetched_with": f"npm pack three@{version}",
            "integrity": record.get("integrity"),
            "shasum": record.get("shasum"),
            "license": meta.get("license"),
            "entry": _dest_rel(entry),
            "files": {rel: _sha256(dest / rel) for rel in copied},
        }
    return write_source(dest, source)


def main(argv: list[str]) -> None:
    version = argv[0] if argv else VERSION
    source = vendor(version)
    print(summary("three", version, DEST, ROOT, source) + f" (import map: \"three\" -> {source['entry']})")


if __name__ == "__main__":
    main(sys.argv[1:])
