"""Test-session set-up: compiled kernels go to a cache inside the project, not the user's."""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("SKEWPEND_CACHE_DIR", str(Path(__file__).resolve().parent.parent / ".skewpend-test-cache"))


import pytest  # noqa: E402


@pytest.fixture(scope="session")
def reference():
    """The reference case (the README's, the report's and ``skewpend simulate``'s built-in model):
    ``skewpend.reference_parameters()``."""
    from skewpend.config import reference_parameters

    return reference_parameters()


@pytest.fixture(scope="session")
def reference_state():
    """The reference case's initial state ``(phi, psi, dphi, dpsi)``."""
    from skewpend.config import reference_state

    return reference_state()


# -- the quick selection: `python -m pytest -m "not slow"` ------------------------------------------------
#: Modules whose every test is slow: a browser, a report built per module, the docs' build, and the docs'
#: examples (a page's examples run in reading order, each after the ones above it, so a quick selection
#: of them would run the slow ones anyway).
SLOW_MODULES = {"test_report_browser.py", "test_explorer_browser.py", "test_report.py", "test_readme.py", "test_docs.py"}


def _measured_slow() -> set:
    """Node ids of tests measured at >= 1 s (tests/slow.txt, with how they were measured)."""
    path = Path(__file__).resolve().parent / "slow.txt"
    lines = [line.split(None, 1) for line in path.read_text(encoding="utf-8").splitlines()
             if line.strip() and not line.startswith("#")]
    return {node.strip() for _, node in lines}


def pytest_collection_modifyitems(config, items):
    slow = _measured_slow()
    for item in items:
        if item.nodeid in slow or Path(str(item.fspath)).name in SLOW_MODULES:
            item.add_marker(pytest.mark.slow)
