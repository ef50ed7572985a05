#!/usr/bin/env python3
"""Vendor KaTeX into the package, for the self-contained HTML report (``skewpend report``).

Fetches the ``katex`` package from the npm registry with the ordinary client (``npm pack
katex@VERSION``: one tarball, no install scripts run), checks it, and copies what the report
inlines into ``src/skewpend/views/assets/katex/``:

* ``katex.min.js``, ``katex.min.css`` (the CSS's ``url(fonts/...)`` references are turned into
  data URIs by the report at build time; only the ``woff2`` ones are kept);
* ``fonts/*.woff2`` (every browser the report targets reads WOFF2);
* ``LICENSE`` (MIT), and ``SOURCE.json``: version, the tarball's integrity string as the
  registry gave it, and the SHA-256 of every copied file (checked by ``tests/test_report.py``).

The produced files are committed; run this only to move to another KaTeX version::

    python tools/vendor_katex.py            # the version pinned below
    python tools/vendor_katex.py 0.19.1     # another one
"""

from __future__ import annotations

import json
import shutil
import sys
import tempfile
from pathlib import Path

from _npm import npm_pack, sha256, summary, write_source  # tools/ is on sys.path when run

#: The KaTeX version the package ships (``npm view katex version`` when it was vendored).
VERSION = "0.19.1"

ROOT = Path(__file__).resolve().parent.parent
DEST = ROOT / "src" / "skewpend" / "views" / "assets" / "katex"


_sha256 = sha256


def fetch(version: str, workdir: Path) -> tuple[Path, dict]:
    """``npm pack katex@version`` into ``workdir``; returns the unpacked ``package/`` and npm's record."""
    return npm_pack("katex", version, workdir)


def vendor(version: str = VERSION, dest: Path = DEST) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        package, record = fetch(version, Path(tmp))
        meta = json.loads((package / "package.json").read_text())
        if meta.get("name") != "katex" or meta.get("version") != version:
            raise SystemExit(f"vendor_katex: npm gave {meta.get('name')}@{meta.get('version')}, expected katex@{version}")
        dist = package / "dist"
        fonts = sorted((dist / "fonts").glob("*.woff2"))
        if not fonts:
            raise SystemExit("vendor_katex: no woff2 fonts in the package")
        if dest.exists():
            shutil.rmtree(dest)
        (dest / "fonts").mkdir(parents=True)
        copied = []
        for src, rel in [(dist / "katex.min.js", "katex.min.js"), (dist / "katex.min.css", "katex.min.css"),
                         (package / "LICENSE", "LICENSE")] + [(f, f"fonts/{f.name}") for f in fonts]:
            shutil.copyfile(src, dest / rel)
            copied.append(rel)
        source = {
            "package": "katex",
            "version": version,
            "fetched_with": f"npm pack katex@{version}",
            "integrity": record.get("integrity"),
            "shasum": record.get("shasum"),
            "license": meta.get("license"),
            "files": {rel: _sha256(dest / rel) for rel in copied},
        }
    return write_source(dest, source)


def main(argv: list[str]) -> None:
    version = argv[0] if argv else VERSION
    source = vendor(version)
    print(summary("katex", version, DEST, ROOT, source))


if __name__ == "__main__":
    main(sys.argv[1:])
