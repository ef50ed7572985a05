"""A Zarr store's template is made in a directory created exclusively under a random name: a link
planted at the old predictable name (``.NAME.skewpend-PID.tmp``) is never followed, and clean-up
of templates left by dead processes never follows a link (issue 29, item 10's class)."""

from __future__ import annotations

import os
import subprocess
import sys


import skewpend


def _tiny_map(reference, store):
    return skewpend.flip_map(reference, 4, t_end=0.2, store=store)


def test_a_planted_link_at_the_old_temporary_name_is_not_followed(tmp_path, reference):
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "keep.txt").write_text("mine", encoding="utf-8")
    planted = tmp_path / f".m.zarr.skewpend-{os.getpid()}.tmp"
    planted.symlink_to(victim, target_is_directory=True)
    fm = _tiny_map(reference, tmp_path / "m.zarr")
    assert fm.ok
    assert sorted(p.name for p in victim.iterdir()) == ["keep.txt"]  # nothing written into it
    assert (tmp_path / "m.zarr").is_dir() and not (tmp_path / "m.zarr").is_symlink()
    assert planted.is_symlink()  # and nothing of the user's removed
    leftovers = [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp") and p != planted]
    assert leftovers == []


def test_stale_templates_of_dead_processes_go_but_links_stay(tmp_path, reference):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".m.zarr.skewpend-{dead.pid}-abc123.tmp"
    (stale / "store").mkdir(parents=True)
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "keep.txt").write_text("mine", encoding="utf-8")
    link = tmp_path / f".m.zarr.skewpend-{dead.pid}-xyz789.tmp"
    link.symlink_to(victim, target_is_directory=True)
    fm = _tiny_map(reference, tmp_path / "m.zarr")
    assert fm.ok
    assert not stale.exists()
    assert link.is_symlink() and (victim / "keep.txt").read_text(encoding="utf-8") == "mine"
