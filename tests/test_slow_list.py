"""tests/slow.txt names tests that exist: a renamed or removed test left there marks nothing, and the
quick selection (``-m "not slow"``) silently grows."""

from __future__ import annotations

import re
from pathlib import Path

HERE = Path(__file__).resolve().parent


def test_every_entry_names_a_test_function_that_exists():
    for line in (HERE / "slow.txt").read_text(encoding="utf-8").splitlines():
        if not line.strip() or line.startswith("#"):
            continue
        seconds, node = line.split(None, 1)
        float(seconds.rstrip("qof"))  # the measured seconds, with their source letter
        path, _, name = node.strip().partition("::")
        function = re.sub(r"\[.*\]$", "", name)
        source = HERE.parent / path
        assert source.is_file(), node
        assert re.search(rf"^def {re.escape(function)}\(", source.read_text(encoding="utf-8"), re.M), node
