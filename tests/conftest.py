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
