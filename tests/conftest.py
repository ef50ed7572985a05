"""Test-session set-up: compiled kernels go to a cache inside the project, not the user's."""

from __future__ import annotations

import os
from pathlib import Path

os.environ.setdefault("SKEWPEND_CACHE_DIR", str(Path(__file__).resolve().parent.parent / ".skewpend-test-cache"))
