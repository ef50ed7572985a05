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
        float(seconds.rstrip("qofnd"))  # the measured seconds, with their source letter
        path, _, name = node.strip().partition("::")
        function = re.sub(r"\[.*\]$", "", name)
        source = HERE.parent / path
        assert source.is_file(), node
        text = source.read_text(encoding="utf-8")
        found = re.search(rf"^def {re.escape(function)}\(", text, re.M)
        assert found, node
        # a parametrised test's id has its parameters: an entry without them marks nothing
        above = text[: found.start()].splitlines()
        decorators = []
        while above and (above[-1].startswith("@") or above[-1][:1] in (" ", ")", "]")):
            decorators.append(above.pop())
        if any("parametrize" in line for line in decorators) and "[" not in name:
            raise AssertionError(f"{node}: parametrised; name each case, e.g. {node}[...]")
