"""Files the program writes touch nothing that is not theirs (issue 29, item 10): the static
explorer's export (``serve --export``), the shared atomic writer (``io.atomic_path``) behind the
report, animations, figures and every ``--out``; and the views' public entry points refuse
wrong-typed arguments in one line."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from skewpend.errors import ParameterError, SkewpendError
from skewpend.views import frontend


@pytest.fixture(scope="module")
def site_files():
    return set(frontend._site_files())


def _tree(path: Path) -> dict:
    """Every entry below ``path`` -> its text (files), its target (links) or None (directories)."""
    out = {}
    for p in sorted(path.rglob("*")):
        rel = p.relative_to(path).as_posix()
        out[rel] = os.readlink(p) if p.is_symlink() else (p.read_bytes() if p.is_file() else None)
    return out


# -- the static export --------------------------------------------------------------------------------
def test_planted_temporary_names_are_neither_followed_nor_removed(tmp_path):
    """The old export wrote through ``.site.tmp-export -> victim/`` and deleted ``.site.old-export/``."""
    victim = tmp_path / "victim"
    victim.mkdir()
    (tmp_path / ".site.tmp-export").symlink_to(victim)
    (tmp_path / ".site.old-export").mkdir()
    (tmp_path / ".site.old-export" / "mine.txt").write_text("mine")
    before = _tree(tmp_path)
    frontend.export_explorer(tmp_path / "site")
    frontend.export_explorer(tmp_path / "site", force=True)
    after = _tree(tmp_path)
    assert {k: v for k, v in after.items() if not k.startswith("site")} == before  # untouched, nothing left
    assert (tmp_path / "site" / "index.html").is_file() and list(victim.iterdir()) == []


def test_the_manifest_lists_exactly_the_files_written(tmp_path, site_files):
    import json

    site = frontend.export_explorer(tmp_path / "site").parent
    manifest = json.loads((site / frontend.MANIFEST).read_text())
    written = {p.relative_to(site).as_posix() for p in site.rglob("*") if p.is_file()} - {frontend.MANIFEST}
    assert set(manifest["files"]) == written == site_files
    assert oct(site.stat().st_mode & 0o777) == oct(0o777 & ~_umask())  # not mkdtemp's private 0700


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def test_force_replaces_only_what_the_export_wrote(tmp_path):
    site = tmp_path / "site"
    frontend.export_explorer(site)
    (site / "CNAME").write_text("example.org")  # a static host's file beside the site: kept
    (site / "index.html").write_text("edited")  # the export's own file: replaced
    frontend.export_explorer(site, force=True)
    assert (site / "CNAME").read_text() == "example.org" and "edited" not in (site / "index.html").read_text()
    # a file of the user's inside the export's directories: refused, nothing replaced
    (site / "static" / "custom.css").write_text("mine")
    (site / "index.html").write_text("edited")
    with pytest.raises(ParameterError, match=r"custom\.css was not written by the export"):
        frontend.export_explorer(site, force=True)
    assert (site / "index.html").read_text() == "edited" and (site / "static" / "custom.css").read_text() == "mine"
    (site / "static" / "custom.css").unlink()
    # a symbolic link inside: refused (never followed, never removed)
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_text("keep")
    (site / "sources" / "more").symlink_to(outside)
    with pytest.raises(ParameterError, match="symbolic link"):
        frontend.export_explorer(site, force=True)
    assert (outside / "keep.txt").read_text() == "keep" and (site / "sources" / "more").is_symlink()
    # the manifest's word is needed: without it nothing counts as the export's
    (site / "sources" / "more").unlink()
    (site / frontend.MANIFEST).unlink()
    with pytest.raises(ParameterError, match="not an earlier export"):
        frontend.export_explorer(site, force=True)
    (site / frontend.MANIFEST).symlink_to(tmp_path / "fake-manifest")
    with pytest.raises(ParameterError, match="not an earlier export"):
        frontend.export_explorer(site, force=True)


def test_a_symbolic_link_as_the_directory_is_refused(tmp_path):
    real = tmp_path / "real"
    frontend.export_explorer(real)
    (tmp_path / "link").symlink_to(real)
    before = _tree(real)
    for force in (False, True):
        with pytest.raises(ParameterError, match="symbolic link"):
            frontend.export_explorer(tmp_path / "link", force=force)
    assert _tree(real) == before and (tmp_path / "link").is_symlink()


def test_an_existing_directory_gets_the_site_beside_its_files(tmp_path, monkeypatch):
    """``serve --export .`` (the old export renamed the directory: "Device or resource busy")."""
    work = tmp_path / "work"
    work.mkdir()
    (work / "README").write_text("mine")
    monkeypatch.chdir(work)
    index = frontend.export_explorer(".")
    assert index.is_file() and (work / "README").read_text() == "mine"
    with pytest.raises(ParameterError, match="earlier export"):
        frontend.export_explorer(".")
    frontend.export_explorer(".", force=True)
    assert sorted(p.name for p in work.iterdir()) == sorted(["README", *frontend.EXPORT_ENTRIES])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["work"]
    # an entry of the export's name that is not the export's: refused, untouched
    other = tmp_path / "other"
    other.mkdir()
    (other / "static").mkdir()
    with pytest.raises(ParameterError, match="already has static, which no export wrote"):
        frontend.export_explorer(other)
    assert _tree(other) == {"static": None}


def test_an_error_while_writing_leaves_nothing(tmp_path, monkeypatch):
    site = tmp_path / "site"
    frontend.export_explorer(site)
    before = _tree(tmp_path)

    def full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(frontend.shutil, "copytree", full)
    for target, force in ((site, True), (tmp_path / "new", False)):
        with pytest.raises(SkewpendError, match="cannot write .*: No space left on device"):
            frontend.export_explorer(target, force=force)
        assert _tree(tmp_path) == before  # the earlier export whole, no temporary directory


def test_an_interrupted_swap_puts_the_earlier_export_back(tmp_path, monkeypatch):
    site = tmp_path / "site"
    frontend.export_explorer(site)
    (site / "index.html").write_text("earlier")
    before = _tree(tmp_path)
    real = os.rename
    calls = []

    def failing(src, dst):
        calls.append(dst)
        if len(calls) == 4:  # in the middle of moving the new entries in
            raise OSError(5, "Input/output error")
        return real(src, dst)

    monkeypatch.setattr(os, "rename", failing)
    with pytest.raises(SkewpendError, match="Input/output error"):
        frontend.export_explorer(site, force=True)
    assert _tree(tmp_path) == before


@pytest.fixture
def read_only_dir(tmp_path):
    """A directory this process cannot write: chmod 555, or for root a read-only tmpfs."""
    ro = tmp_path / "ro"
    ro.mkdir()
    if os.geteuid() != 0:
        ro.chmod(0o555)
        yield ro
        ro.chmod(0o755)
        return
    try:
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k,ro", "tmpfs", str(ro)], capture_output=True)
    except OSError as exc:
        pytest.skip(f"root writes into read-only directories, and no read-only tmpfs: {exc}")
    if done.returncode != 0:
        pytest.skip(f"root writes into read-only directories, and no read-only tmpfs: {done.stderr.decode().strip()}")
    try:
        yield ro
    finally:
        subprocess.run(["umount", str(ro)], capture_output=True)


def test_a_read_only_directory_is_one_line(read_only_dir):
    from skewpend.io import check_output_path

    for target in (read_only_dir / "site", read_only_dir):
        with pytest.raises(ParameterError, match=r"^explorer export: cannot write .*: (Permission denied|Read-only)"):
            frontend.export_explorer(target)
    with pytest.raises(ParameterError, match=r"^--out: cannot write .*: (Permission denied|Read-only)"):
        check_output_path(read_only_dir / "r.html", (".html",))
    assert list(read_only_dir.iterdir()) == []


def test_the_export_refuses_wrong_arguments_in_one_line(tmp_path):
    for kwargs, words in (({"params": "x"}, "params must be a skewpend.Parameters"),
                          ({"params": {"a": 1}}, "params must be a skewpend.Parameters"),
                          ({"force": "yes"}, "force must be True or False")):
        with pytest.raises(ParameterError, match=words):
            frontend.export_explorer(tmp_path / "site", **kwargs)
    with pytest.raises(ParameterError, match="directory must be a path"):
        frontend.export_explorer(3)
    assert list(tmp_path.iterdir()) == []


# -- the shared atomic writer -------------------------------------------------------------------------
def test_the_atomic_writer_never_writes_through_a_planted_name(tmp_path):
    """The old temporary name ``.NAME.skewpend-PID.tmp`` was predictable and opened with O_TRUNC
    (following a symbolic link planted under it); check_output_path removed a file of that name."""
    from skewpend.io import atomic_path, check_output_path

    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    out = tmp_path / "out.csv"
    planted = tmp_path / f".out.csv.skewpend-{os.getpid()}.tmp"
    planted.symlink_to(victim)
    check_output_path(out, (".csv",))
    with atomic_path(out) as tmp:
        assert not tmp.exists() or tmp.stat().st_size == 0
        assert tmp.parent == tmp_path and tmp != planted and not tmp.is_symlink()
        tmp.write_text("new")
    assert out.read_text() == "new" and victim.read_text() == "precious" and planted.is_symlink()
    # an error: the temporary file goes, the planted name stays
    with pytest.raises(RuntimeError):
        with atomic_path(out) as tmp:
            tmp.write_text("half")
            raise RuntimeError("boom")
    assert out.read_text() == "new" and sorted(p.name for p in tmp_path.iterdir()) == sorted(
        ["victim.txt", "out.csv", planted.name])


def test_the_atomic_writer_replaces_a_link_never_its_target(tmp_path):
    from skewpend.io import atomic_path

    victim = tmp_path / "victim.html"
    victim.write_text("precious")
    link = tmp_path / "report.html"
    link.symlink_to(victim)
    with atomic_path(link) as tmp:
        tmp.write_text("report")
    assert victim.read_text() == "precious" and not link.is_symlink() and link.read_text() == "report"


def test_a_stale_temporary_file_of_a_dead_process_is_removed_but_never_a_link(tmp_path):
    from skewpend.io import atomic_path

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale = tmp_path / f".out.csv.skewpend-{dead.pid}-abc123.tmp"
    stale.write_text("half")
    link = tmp_path / f".out.csv.skewpend-{dead.pid}.tmp"
    link.symlink_to(tmp_path / "elsewhere")
    with atomic_path(tmp_path / "out.csv") as tmp:
        tmp.write_text("x")
    assert not stale.exists() and link.is_symlink()


def test_the_report_cache_writes_through_an_exclusive_temporary_file(tmp_path, monkeypatch):
    from skewpend import Parameters
    from skewpend.views.report import cache

    monkeypatch.setenv("SKEWPEND_CACHE_DIR", str(tmp_path / "cache"))
    folder = tmp_path / "cache" / "report-sections"
    folder.mkdir(parents=True)
    p = Parameters(a=0.5, b=0.5, m1=1.0, m2=1.0, alpha=0.5, g=9.81)
    victim = tmp_path / "victim"
    victim.write_text("precious")
    name = f"{cache.key(p)}.json"
    planted = folder / f".{name}.{os.getpid()}.tmp"  # the old, predictable name
    planted.symlink_to(victim)
    sections = {"bodies": {"derivation": "d", "check": "c"}, "notes": {}, "timings": {}}
    cache.save(p, sections)
    assert cache.load(p) == sections and victim.read_text() == "precious"
    assert sorted(q.name for q in folder.iterdir()) == sorted([name, planted.name])


# -- Ctrl-C during the report (item 9): a signal no check takes is raised where the work is ------------
def _signal_self_later(delay: float, signum=None):
    import signal
    import threading

    timer = threading.Timer(delay, os.kill, args=(os.getpid(), signum or signal.SIGINT))
    timer.start()
    return timer


#: A hang guard (issue 36: no test asserts an absolute time) [s]: the spins below that a signal must
#: interrupt run this long only if it does not -- the tests see that as their end being reached, not as
#: a duration.
NEVER = 60.0


def _spin(seconds: float, until=None) -> bool:
    """Plain Python work with no check (the report's drawing, SymPy), until ``until()`` holds (True) or
    ``seconds`` have passed (False)."""
    import time

    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if until is not None and until():
            return True
        sum(range(100))
    return False


def _escalations(monkeypatch) -> list:
    """The signals :class:`Interrupts` sends again to the main thread (its escalation), as they are sent."""
    import signal

    sent, real = [], signal.pthread_kill

    def counted(thread, signum):
        sent.append(signum)
        real(thread, signum)

    monkeypatch.setattr(signal, "pthread_kill", counted)
    return sent


def test_a_signal_without_a_check_is_raised_after_the_grace_time():
    from skewpend.interrupts import Interrupts

    ended = []
    with pytest.raises(KeyboardInterrupt):
        with Interrupts(escalate_after=0.1):
            _signal_self_later(0.05)
            _spin(NEVER)
            ended.append("spin")
    assert ended == []  # raised inside the spin, which has no check
    # without escalation the signal waits for the check (the old behaviour, kept for compiled loops)
    with pytest.raises(KeyboardInterrupt):
        with Interrupts() as intr:
            _signal_self_later(0.0)
            assert _spin(NEVER, until=lambda: intr.pending is not None)
            _spin(0.4)  # no escalation meanwhile (a shorter stretch would test less, never fail wrongly)
            assert intr.pending is KeyboardInterrupt


def test_the_escalation_interrupts_a_blocking_wait_and_sigterm_stays_terminated():
    """A compiler's subprocess or a pipe: a real signal is sent again, so the wait ends."""
    import signal

    from skewpend.interrupts import Interrupts, Terminated, terminate_like_interrupt

    ended = []
    with terminate_like_interrupt():
        with pytest.raises(Terminated):
            with Interrupts(escalate_after=0.1):
                _signal_self_later(0.05, signal.SIGTERM)
                subprocess.run(["sleep", str(NEVER)])  # killed by run() when the signal is raised
                ended.append("sleep")
    assert ended == []  # the wait was interrupted, not waited out


def test_the_escalation_waits_while_a_destructor_runs(monkeypatch):
    """Raised inside ``__del__`` it would only be reported ("Exception ignored") and lost."""
    import gc

    from skewpend.interrupts import Interrupts

    swallowed = []
    monkeypatch.setattr(sys, "unraisablehook", swallowed.append)

    sent, ended = _escalations(monkeypatch), []

    class Slow:
        def __del__(self):  # the escalation comes in here, is put off (a second one is sent), and waits
            assert _spin(NEVER, until=lambda: len(sent) >= 2)

    with pytest.raises(KeyboardInterrupt):
        with Interrupts(escalate_after=0.05):
            _signal_self_later(0.0)
            Slow()
            gc.collect()
            _spin(NEVER)  # raised in here, right after the destructor
            ended.append("spin")
    assert not swallowed and ended == []


def test_the_report_stops_inside_a_long_section(tmp_path, monkeypatch):
    """A section that draws for seconds (no check inside) no longer holds Ctrl-C until it ends."""

    import skewpend.views.report as R

    monkeypatch.setattr(R, "PARALLEL", False)
    monkeypatch.setattr(R, "chaos_jobs", lambda ctx: {})
    from skewpend.views.report import cache

    monkeypatch.setattr(cache, "load", lambda params: {"bodies": {}, "notes": {}, "timings": {}})
    ended = []
    monkeypatch.setattr(R, "section_simulation", lambda ctx: _spin(NEVER) or ended.append("section"))
    out = tmp_path / "r.html"
    with pytest.raises(KeyboardInterrupt):
        _signal_self_later(0.2)
        R.build_report(out=out)
    assert ended == []  # stopped inside the section, not after it
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
@pytest.mark.parametrize("signame", ["SIGINT", "SIGTERM"])
def test_ctrl_c_stops_the_report_within_a_second_or_so(tmp_path, monkeypatch, signame):
    """The report drew or ran SymPy for seconds between its checks (4-14 s to stop).  Nothing is left
    where it writes, nor in its temporary directory (TMPDIR: the second process's and the compiler's
    files too)."""
    import signal

    from helpers import signal_process

    scratch, work = tmp_path / "tmp", tmp_path / "work"
    scratch.mkdir()
    work.mkdir()
    monkeypatch.setenv("TMPDIR", str(scratch))
    ran, took = signal_process(["report", "--out", "r.html"], work, after=4.0, signum=getattr(signal, signame))
    assert ran.code == {"SIGINT": 130, "SIGTERM": 143}[signame], ran.report()
    assert ran.err.strip().splitlines() == ["skewpend: " + {"SIGINT": "interrupted", "SIGTERM": "terminated"}[signame]]
    # a hang guard, not a speed test: that the signal is raised inside the work, not after it, is shown in
    # process above (test_the_report_stops_inside_a_long_section and the escalation's tests)
    assert took < 20.0
    assert list(work.iterdir()) == [] and list(scratch.iterdir()) == []


# -- a full disk: one line, nothing left (item 10) ------------------------------------------------------
@pytest.fixture
def full_dir(tmp_path):
    """A directory on a 64 kB file system (tmpfs; needs root and mount)."""
    full = tmp_path / "full"
    full.mkdir()
    try:
        done = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(full)], capture_output=True)
    except OSError as exc:
        pytest.skip(f"cannot mount a small tmpfs to fill: {exc}")
    if done.returncode != 0:
        pytest.skip(f"cannot mount a small tmpfs to fill (root needed): {done.stderr.decode().strip()}")
    try:
        try:
            (full / "filler").write_bytes(b"x" * 60_000)  # nearly full: a few frames overflow it
        except OSError:
            pass
        yield full
    finally:
        subprocess.run(["umount", str(full)], capture_output=True)


@pytest.fixture(scope="module")
def short_run():
    import skewpend

    return skewpend.simulate(skewpend.reference_parameters(), (1.0, 0.5, 0.0, 0.0), 0.3, dt_out=1 / 30)


@pytest.mark.parametrize("name", ["a.mp4", "a.gif"])
def test_a_full_disk_while_animating_is_one_line_and_leaves_nothing(full_dir, short_run, capfd, name):
    from skewpend.views.animation import animate

    with pytest.raises(SkewpendError) as info:
        animate(short_run, full_dir / name, size=(160, 120))
    assert str(info.value) == f"cannot write {full_dir / name}: No space left on device"
    assert capfd.readouterr().err == ""  # ffmpeg's messages never reach the terminal
    assert [p.name for p in full_dir.iterdir()] == ["filler"]


def test_ffmpeg_failing_is_one_line_and_leaves_nothing(tmp_path, short_run, monkeypatch, capfd):
    """The old writer returned as if done when ffmpeg failed (a truncated video, exit status 0)."""
    from skewpend.views import animation

    class Broken:
        @staticmethod
        def get_ffmpeg_exe():
            return sys.executable  # "ffmpeg" that fails on its arguments

    monkeypatch.setattr(animation, "_ffmpeg", lambda: Broken)
    with pytest.raises(SkewpendError, match=r"^cannot write .*a\.mp4: ffmpeg failed \(exit status 2: .*\)$"):
        animation.animate(short_run, tmp_path / "a.mp4", size=(160, 120))
    assert capfd.readouterr().err == "" and list(tmp_path.iterdir()) == []
    assert animation._ffmpeg_reason("[out#0/mp4 @ 0x1] Error writing trailer: No space left on device\nmore", 1) \
        == "No space left on device"


# -- the views' entry points refuse wrong-typed arguments in one line (item 8) --------------------------
@pytest.mark.parametrize("bad", ["x", None, 3, [1.0, 2.0]])
def test_view_entry_points_refuse_what_they_cannot_draw(bad, tmp_path, short_run):
    from skewpend.views import animation, figures

    with pytest.raises(ParameterError, match=r"^tr must be a skewpend\.Trajectory"):
        animation.animate(bad, tmp_path / "a.gif")
    for name in ("angles_figure", "simulation_figure", "flipmap_figure", "lyapunov_figure", "poincare_figure",
                 "chaos_diagram_figure", "lyapunov_map_figure", "control_figure", "roa_figure", "plot_sweep",
                 "fep_figure", "alpha_family_figure"):
        with pytest.raises(ParameterError, match=r" must be (a|an) .*, got "):
            getattr(figures, name)(bad)
    assert list(tmp_path.iterdir()) == []


def test_a_figure_of_the_right_result_still_draws(short_run):
    from skewpend.views import figures

    assert figures.angles_figure(short_run).axes


def test_the_report_refuses_wrong_types_before_any_work(tmp_path):
    from skewpend.views.report import build_report

    (tmp_path / "d.html").mkdir()
    for kwargs, words in (({"params": "x"}, "params must be a skewpend.Parameters or a Chain, got str"),
                          ({"y0": "abc"}, "y0 must be 4 numbers"),
                          ({"out": 3}, "--out must be a file path, got int"),
                          ({"out": ""}, "--out must be a file path"),
                          ({"out": tmp_path / "d.html"}, "is a directory"),
                          ({"out": tmp_path / "r.txt"}, r"ending in \.html")):
        with pytest.raises(ParameterError, match=words):
            build_report(**kwargs)
    assert [p.name for p in tmp_path.iterdir()] == ["d.html"]


def test_a_compiler_s_temporary_files_go_to_a_directory_that_is_removed(tmp_path, monkeypatch):
    """Ctrl-C now stops a report during a kernel's compilation; a compiler killed mid-way cannot
    remove its own temporary files (gcc's ``ccXXXX.s`` in TMPDIR), so they go to a directory of ours."""
    from skewpend.numeric import kernels

    fake = tmp_path / "fakecc"
    fake.write_text('#!/bin/sh\necho half > "$TMPDIR/ccXXXX.s"\necho "fakecc: failed" >&2\nexit 1\n')
    fake.chmod(0o755)
    scratch, cache = tmp_path / "tmp", tmp_path / "kernels"
    scratch.mkdir()
    cache.mkdir()
    monkeypatch.setenv("CC", str(fake))
    monkeypatch.setenv("TMPDIR", str(scratch))
    with pytest.raises(kernels.CompilerError, match="fakecc: failed"):
        kernels._compile("int x;\n", cache / "k.so")
    assert list(scratch.iterdir()) == [] and list(cache.iterdir()) == []


def test_a_name_near_the_file_system_s_limit_is_still_written(tmp_path):
    """The temporary name adds some 30 characters: a 250-character name used to fail."""
    from skewpend.io import atomic_path

    out = tmp_path / ("a" * 245 + ".csv")
    with atomic_path(out) as tmp:
        tmp.write_text("x")
    site = tmp_path / ("s" * 250)
    frontend.export_explorer(site)
    assert out.read_text() == "x" and (site / "index.html").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([out.name, site.name])


def test_the_escalation_waits_while_a_gc_callback_runs(monkeypatch):
    """A garbage collector's callback (a profiler's, or a test plugin's) reports its exceptions only,
    like ``__del__``: the escalation waits until it has returned."""
    import gc

    from skewpend.interrupts import Interrupts

    swallowed = []
    monkeypatch.setattr(sys, "unraisablehook", swallowed.append)

    sent, ended = _escalations(monkeypatch), []

    def slow_callback(phase, info):
        if phase == "start":  # the escalation comes in here, is put off (a second one is sent), and waits
            assert _spin(NEVER, until=lambda: len(sent) >= 2)

    gc.callbacks.append(slow_callback)
    try:
        with pytest.raises(KeyboardInterrupt):
            with Interrupts(escalate_after=0.05):
                _signal_self_later(0.0)
                gc.collect()
                _spin(NEVER)  # raised in here, right after the callback
                ended.append("spin")
    finally:
        gc.callbacks.remove(slow_callback)
    assert not swallowed and ended == []


def test_the_escalation_waits_while_a_weakref_callback_runs(monkeypatch):
    """A weak reference's callback (a WeakKeyDictionary's ``remove`` under xdist swallowed it; here a
    ``weakref.finalize``, whose call is in weakref.py) reports its exceptions only: the escalation
    waits until it has returned."""
    import weakref

    from skewpend.interrupts import Interrupts

    swallowed = []
    monkeypatch.setattr(sys, "unraisablehook", swallowed.append)

    class Thing:
        pass

    sent, ended = _escalations(monkeypatch), []
    thing = Thing()
    # the escalation comes in the finalizer, is put off (a second one is sent), and waits
    weakref.finalize(thing, _spin, NEVER, until=lambda: len(sent) >= 2)
    with pytest.raises(KeyboardInterrupt):
        with Interrupts(escalate_after=0.05):
            _signal_self_later(0.0)
            del thing  # the finalizer runs here
            _spin(NEVER)  # raised in here, right after it
            ended.append("spin")
    assert not swallowed and ended == []
