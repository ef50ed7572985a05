"""No silence over 2 s on a terminal (issue 51, item 5): while work runs, the live line's text moves at
each of its sub-steps -- a continuation's Newton iterations and steps, the flip energy's searches, an
animation's frames, a report section's parts (:func:`skewpend.progress.detail`); off a terminal a line per
stage as before.  Nothing here is timed: the live line's moves (``Stages.moves``) are counted against the
work's own steps (flows, searches, frames), which each take well under a second."""

from __future__ import annotations

import io
import sys


from skewpend import progress as P


class _Streams:
    """stdout and stderr swapped for buffers (a terminal Stages wraps them)."""

    def __enter__(self):
        self.old = sys.stdout, sys.stderr
        self.out, self.err = io.StringIO(), io.StringIO()
        sys.stdout, sys.stderr = self.out, self.err
        return self

    def __exit__(self, *exc):
        sys.stdout, sys.stderr = self.old


def _terminal_stages(command: str) -> "tuple[P.Stages, io.StringIO]":
    from rich.console import Console

    screen = io.StringIO()
    console = Console(file=screen, force_terminal=True, width=160, color_system=None)
    return P.Stages(command, terminal=True, console=console), screen


# -- the reporter ----------------------------------------------------------------------------------------
def test_a_detail_is_drawn_on_the_live_line_after_its_stage():
    with _Streams() as streams:
        st, screen = _terminal_stages("demo")
        with st:
            P.stage("working")
            before = len(st.moves)
            P.detail("step 3 of 7")
            st._progress.refresh()
            drawn = screen.getvalue()
            P.detail("step 3 of 7")  # the same text again: no move
            assert len(st.moves) == before + 1
            P.stage("writing")  # a new stage forgets the last one's detail
            st._progress.refresh()
            assert st._live_text() == "writing"
    assert "skewpend demo: working: step 3 of 7" in drawn
    assert streams.err.getvalue() == ""  # the live line only, no line of its own


def test_off_a_terminal_a_detail_is_no_line():
    buf = io.StringIO()
    old, sys.stderr = sys.stderr, buf
    try:
        with P.Stages("demo", terminal=False) as st:
            P.stage("working")
            for k in range(5):
                P.detail(f"step {k}")
    finally:
        sys.stderr = old
    assert [line.split("... (")[0] for line in buf.getvalue().splitlines()] == ["skewpend demo: working"]
    assert st.moves == []
    P.detail("no command runs")  # nothing, nowhere


def test_a_detail_says_a_held_stage():
    """A held stage (said when its work begins) is said at its first detail: the work has begun."""
    with _Streams():
        st, _ = _terminal_stages("demo")
        with st:
            st.stage("computing", hold=True, within=600.0)
            assert st.lines == [] or st.lines[-1].startswith("skewpend demo: starting")
            P.detail("iteration 1")
            assert st.lines[-1].startswith("skewpend demo: computing... (")


# -- the continuation of a nonlinear normal mode (nnm on a 4-link chain: 105 s without a word) --------------
def _moves_between(monkeypatch, target, name, st):
    """Record len(st.moves) at each call of ``target.name``."""
    seen = []
    original = getattr(target, name)

    def counted(*args, **kw):
        seen.append(len(st.moves))
        return original(*args, **kw)

    monkeypatch.setattr(target, name, counted)
    return seen


def _longest_run_without_a_move(seen) -> int:
    """The most calls in a row with no move of the live line between them."""
    run = longest = 1 if seen else 0
    for a, b in zip(seen, seen[1:]):
        run = run + 1 if b == a else 1
        longest = max(longest, run)
    return longest


def test_nnm_on_a_chain_moves_the_line_at_every_newton_iteration(monkeypatch):
    """Every flow (one shooting: a Newton iteration, ~10-170 ms on a 4-link chain) and every search of the
    flip energy (an L-BFGS-B run, ~0.2 s) is followed by a move of the live line before the next but one."""
    import scipy.optimize

    from skewpend.analysis import orbits as O
    from skewpend.symbolic.chain import Chain

    monkeypatch.setattr(O, "FLIP_STARTS", 1)  # searches enough to see each move the line, not more
    chain = Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5], g=7.3)  # a chain no other test met
    O._FLIP_ENERGIES.pop(chain, None)
    with _Streams():
        st, _ = _terminal_stages("nnm")
        flows = _moves_between(monkeypatch, O._Model, "shoot", st)
        searches = _moves_between(monkeypatch, scipy.optimize, "minimize", st)
        texts = []
        said = st.detail
        monkeypatch.setattr(st, "detail", lambda text: (texts.append(text), said(text)))
        with st:
            with st.bar("continuing nonlinear normal mode 1", "J") as bar:
                family = O.nnm(chain, mode=1, energy_max=0.05, resolution=2, progress=bar)
    assert family.ok, family.message
    assert len(flows) >= 3 * len(family.energies) and len(searches) == 2 * 3 * O.FLIP_STARTS
    # a shooting's last flow (its converged orbit) and the next one's first may meet without a move between
    assert _longest_run_without_a_move(flows) <= 2, flows
    assert _longest_run_without_a_move(searches) == 1, searches
    # and the line said what it did: the search, the orbit, its energy, the iteration
    assert "the lowest flip energy: face 6 of 6, search 1 of 1" in texts
    assert any(t.startswith("orbit 3 near E = ") and t.endswith(": Newton iteration 1") for t in texts), texts
    assert O._FLIP_ENERGIES[chain] == O.flip_energy(chain)  # computed once per chain, then remembered


def test_backbones_name_each_family_on_the_live_line_and_add_no_line_off_it(monkeypatch):
    """A chain's families take up to a minute each: the live line names the family it follows; off a
    terminal they are the command's one stage (a report's section stays one line)."""
    from skewpend.analysis import orbits as O
    from skewpend.symbolic.chain import Chain

    chain = Chain.from_lists(3, length=[0.5, 0.4, 0.3], mass=[1.0, 0.8, 0.5])
    O.flip_energy(chain)  # (seconds; remembered for the chain: the families below do not search again)
    with _Streams():
        st, _ = _terminal_stages("nnm")
        texts = []
        said = st.detail
        monkeypatch.setattr(st, "detail", lambda text: (texts.append(text), said(text)))
        with st:
            result = O.backbones(chain, energy_max=0.05, resolution=3)
    assert len(result.families) == 3
    for m in (1, 2, 3):
        assert any(t.startswith(f"mode {m} of 3: orbit ") for t in texts), (m, texts)
    buf = io.StringIO()
    old, sys.stderr = sys.stderr, buf
    try:
        with P.Stages("nnm", terminal=False):
            P.stage("continuing the nonlinear normal modes")
            O.backbones(chain, energy_max=0.05, resolution=3)
    finally:
        sys.stderr = old
    said = [line.split("... (")[0] for line in buf.getvalue().splitlines()]
    assert said == ["skewpend nnm: continuing the nonlinear normal modes"], said


# -- an animation's frames (a GIF: 15 s of rendering said as one stage) --------------------------------------
def test_an_animation_moves_the_line_at_every_frame(monkeypatch, tmp_path):
    import skewpend
    from skewpend.config import reference_parameters
    from skewpend.views.animation import FrameRenderer, animate

    clip = skewpend.simulate(reference_parameters(), (1.2, -0.8, 0.0, 0.0), 1.0, dt_out=1.0 / 12)
    with _Streams():
        st, _ = _terminal_stages("animate")
        draws = _moves_between(monkeypatch, FrameRenderer, "draw", st)
        texts = []
        said = st.detail
        monkeypatch.setattr(st, "detail", lambda text: (texts.append(text), said(text)))
        with st:
            with st.bar("rendering", "frames") as bar:
                animate(clip, tmp_path / "a.gif", fps=12, size=(160, 120), progress=bar)
    frames = clip.t.size
    assert len(draws) == frames + 4  # every frame, and the four that choose the GIF's palette
    assert _longest_run_without_a_move(draws) == 1, draws
    assert texts[0] == "setting up the scene (Matplotlib)" and texts[-1] == "finishing the GIF file"
    assert [t for t in texts if t.startswith("frame ")] == [f"frame {k} of {frames}" for k in range(1, frames + 1)]
    assert (tmp_path / "a.gif").stat().st_size > 0


# -- a chain report's sections (up to 45 s each said as one stage) ---------------------------------------------
def test_a_chain_reports_sections_say_their_sub_steps(monkeypatch):
    """Sections 2, 3, 4 and 6 of a chain's report: the live line names each typeset row, each random state of
    the check, each hinge's sweep and the flip map's cells as they finish (each well under a second here)."""
    from skewpend.symbolic.chain import Chain
    from skewpend.views import report as R
    from skewpend.views.report import analyses, derivation
    from skewpend.views.report.common import Context

    monkeypatch.setattr(analyses, "FLIPMAP_N", 8)  # the sub-steps, not the pictures' resolution, are checked
    chain = Chain.from_lists(2, length=[0.5, 0.4], mass=[1.0, 0.8], axis=[(0, 0, 1), (0.5, 0, 1)])
    ctx = Context(chain, (0.5, -0.3, 0.0, 0.0), 1.0, "dop853", None, None, None, None, 0.5, 10.0, (160, 120), 5,
                  False, None)
    with _Streams():
        st, _ = _terminal_stages("report")
        texts, moves = [], []
        said = st.detail

        def record(text):
            texts.append(text)
            said(text)
            moves.append(len(st.moves))

        monkeypatch.setattr(st, "detail", record)
        with st:
            for key in ("derivation", "check", "modes", "flipmap"):
                P.stage(key)
                getattr(R, f"section_{key}")(ctx)
    assert "deriving the equations of 2 links (SymPy)" in texts
    assert [t for t in texts if t.startswith("typesetting row")] == ["typesetting row 1 of 2 of M and f",
                                                                     "typesetting row 2 of 2 of M and f"]
    assert [t for t in texts if t.startswith("random state")] == [f"random state {k} of {derivation.CHECK_STATES}"
                                                                   for k in range(1, derivation.CHECK_STATES + 1)]
    assert "hinge 2's tilt: 5 values (sweep 1 of 1)" in texts
    cells = [t for t in texts if t.startswith("8×8 starts: ")]
    assert cells and cells[-1] == "8×8 starts: 64 of 64 cells", texts
    for k in range(1, len(texts)):  # each new text moved the line
        assert (moves[k] > moves[k - 1]) == (texts[k] != texts[k - 1]), (texts[k - 1], texts[k])
