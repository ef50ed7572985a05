"""Helpers of the vendoring scripts (``vendor_katex.py``, ``vendor_three.py``): fetch a package from
the npm registry with the ordinary client and record what was copied."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
import tarfile
from pathlib import Path


def sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def npm_pack(name: str, version: str, workdir: Path) -> tuple[Path, dict]:
    """``npm pack NAME@VERSION`` into ``workdir`` (one tarball, no install scripts run); returns the
    unpacked ``package/`` folder and npm's record of the tarball (integrity, shasum, file name)."""
    npm = shutil.which("npm")
    if npm is None:
        raise SystemExit(f"vendoring {name}: npm is needed (apt-get install npm)")
    out = subprocess.run(
        [npm, "pack", f"{name}@{version}", "--json", "--ignore-scripts", "--pack-destination", str(workdir)],
        cwd=workdir, check=True, capture_output=True, text=True,
    ).stdout
    record = json.loads(out[out.index("["):])[0]
    with tarfile.open(workdir / record["filename"]) as tar:
        members = [m for m in tar.getmembers() if m.isfile() and m.name.startswith("package/")
                   and ".." not in Path(m.name).parts]
        tar.extractall(workdir, members=members)
    return workdir / "package", record


def write_source(dest: Path, source: dict) -> dict:
    """Record what was vendored in ``dest/SOURCE.json`` (checked by the tests); returns ``source``."""
    (dest / "SOURCE.json").write_text(json.dumps(source, indent=2) + "\n")
    return source


def summary(name: str, version: str, dest: Path, root: Path, source: dict) -> str:
    size = sum((dest / rel).stat().st_size for rel in source["files"])
    return f"vendored {name} {version}: {len(source['files'])} files, {size / 1e3:.0f} kB in {dest.relative_to(root)}"
