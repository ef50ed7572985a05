"""Run files an adversary writes: values no double holds and nesting that would exhaust the reader's
recursion are one line and exit status 2 (issue 29, item 7), never an internal error."""

from __future__ import annotations

import pytest

from helpers import assert_refused, run_cli, snapshot

CASES = {
    "a 330-digit integer": ("[parameters]\na = " + "9" * 330 + "\n", ["[parameters] a", "330 digits", "1.8e308"]),
    "a negative 400-digit integer": ("[initial]\nphi0 = -" + "1" * 400 + "\n", ["[initial] phi0", "400 digits"]),
    "arrays 5000 deep": ("[parameters]\na = " + "[" * 5000 + "]" * 5000 + "\n", ["nests arrays or tables too deeply"]),
    "tables 5000 deep": ("x = " + "{a=" * 5000 + "1" + "}" * 5000 + "\n", ["nests arrays or tables too deeply"]),
    "arrays three deep": ("[parameters]\ninertia1 = [[[1.0]]]\n", ["[parameters] inertia1", "nested too deeply"]),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_hostile_run_file_is_one_line_exit_2(tmp_path, case):
    text, fragments = CASES[case]
    path = tmp_path / "run.toml"
    path.write_text(text, encoding="utf-8")
    before = snapshot(tmp_path)
    ran = run_cli(["simulate", "--config", path, "--t-end", "0.1"], cwd=tmp_path)
    assert_refused(ran, fragments, tmp_path, before)


def test_largest_integer_a_double_holds_is_read_as_a_number(tmp_path):
    """The bound is the double's: 2**1023 is read (and then refused by the model's own check
    that a length is a normal number of metres, not by the reader)."""
    path = tmp_path / "run.toml"
    path.write_text(f"[simulation]\nt_end = {2**20}\n[parameters]\na = 1\n", encoding="utf-8")
    from skewpend.io import read_config

    assert read_config(path)["simulation"]["t_end"] == 2**20
    path.write_text(f"[parameters]\na = {2**1023}\n", encoding="utf-8")
    assert read_config(path)["parameters"]["a"] == 2**1023
