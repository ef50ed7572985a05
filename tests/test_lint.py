"""The habits CI keeps (issue 16): ruff over the code and mypy over the public API and the
result objects, both configured in pyproject.toml; the version in one place."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def _run(*argv):
    return subprocess.run([sys.executable, "-m", *argv], cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_ruff_finds_nothing():
    pytest.importorskip("ruff")
    r = _run("ruff", "check", "src", "tests", "benchmarks", "tools")
    assert r.returncode == 0, r.stdout + r.stderr


@pytest.mark.slow
def test_mypy_finds_nothing_in_the_public_api():
    pytest.importorskip("mypy")
    r = _run("mypy")
    assert r.returncode == 0, r.stdout + r.stderr


def test_the_version_is_written_once():
    import skewpend

    text = (ROOT / "pyproject.toml").read_text()
    assert 'dynamic = ["version"]' in text and 'attr = "skewpend.__version__"' in text
    r = subprocess.run([sys.executable, "-m", "skewpend", "--version"], capture_output=True, text=True, timeout=60)
    assert r.stdout.strip() == f"skewpend {skewpend.__version__}"
