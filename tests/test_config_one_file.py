"""One run file for every command (issue 51, item 4) and the chain's inputs and messages (item 6).

A section a command does not use ([initial], [simulation]) is left aside with one note on stderr; keys of the
sections it uses are checked strictly; unknown sections and keys are refused with the name likely meant; a
chain's values never silently become the double pendulum's.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from skewpend.errors import ParameterError

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
TRIPLE = EXAMPLES / "skewed_triple.toml"

#: Which commands use the run's start and its integration -- written out here from the user's guide
#: (docs/howto/run-files.md), not read from the code under test.
USES_INITIAL = {"simulate", "animate", "report", "validate", "lyapunov", "orbit", "serve"}
USES_SIMULATION = {"simulate", "animate", "report", "validate", "lyapunov", "flipmap", "poincare", "chaos-diagram"}
COMMANDS = sorted(USES_INITIAL | USES_SIMULATION | {"export", "modes", "equilibria", "nnm", "control", "identify",
                                                     "derive"})


def _file(tmp_path, text: str, name: str = "run.toml") -> str:
    path = tmp_path / name
    path.write_text(text)
    return str(path)


def _notes(err: str):
    return [line for line in err.splitlines() if line.startswith("skewpend: note:")]


def _errors(err: str):
    return [line for line in err.splitlines() if line.startswith("skewpend: error:")]


# -- the rule, in the library ------------------------------------------------------------------------------------
@pytest.mark.parametrize("command", COMMANDS)
def test_unused_sections_are_left_aside_with_one_note(tmp_path, command):
    from skewpend.config import Run

    # t_end is what every user of [simulation] reads but poincare (its orbits run to --t-max): rtol there
    sim_key, sim_value = ("rtol", 1e-9) if command == "poincare" else ("t_end", 3.0)
    config = _file(tmp_path, f"[parameters]\na = 1.1\n\n[initial]\nphi0 = 0.3\n\n[simulation]\n{sim_key} = {sim_value}\n")
    run = Run(command, config, defaults=command != "derive")
    unused = [s for s, users in (("initial", USES_INITIAL), ("simulation", USES_SIMULATION)) if command not in users]
    if not unused:
        assert run.notes == []
    else:
        assert len(run.notes) == 1, run.notes
        note = run.notes[0]
        assert note.startswith(config) and f"skewpend {command}" in note and "ignored" in note
        assert all(f"[{s}]" in note for s in unused) and all(f"[{s}]" not in note for s in {"initial", "simulation"} - set(unused))
    # what is used takes effect, what is left aside does not
    assert run.raw("parameters", "a") == 1.1
    assert (run.raw("initial", "phi0") == 0.3) == (command in USES_INITIAL)
    assert (run.raw("simulation", sim_key) == sim_value) == (command in USES_SIMULATION)
    assert run.is_given("initial", "phi0") == (command in USES_INITIAL)


def test_a_used_sections_keys_of_other_commands_are_left_aside_with_a_note(tmp_path):
    """flipmap uses [simulation] (its horizon and tolerances): simulate's dt_out and out there are left aside,
    said in one note (examples/chaotic.toml serves simulate and flipmap alike); an unknown key is refused."""
    from skewpend.config import Run
    from skewpend.parsing import UsageError

    config = _file(tmp_path, "[initial]\nphi0 = 0.3\n\n[simulation]\nt_end = 7.0\ndt_out = 0.1\nout = 'x.csv'\n")
    run = Run("flipmap", config)
    assert run.raw("simulation", "t_end") == 7.0 and run.raw("simulation", "dt_out") is None
    assert run.raw("simulation", "out") is None
    assert len(run.notes) == 2 and "[initial] is not used by skewpend flipmap" in run.notes[0]
    assert "[simulation] dt_out, [simulation] out are settings of other commands, not used by skewpend flipmap; " \
        "ignored" in run.notes[1]
    animate = Run("animate", _file(tmp_path, "[simulation]\nout = 'x.csv'\n"))
    assert "the video is written to --out FILE.mp4|.gif" in animate.notes[0]  # why, where the command knows it
    with pytest.raises((UsageError, ParameterError), match="did you mean 'dt_out'"):
        Run("flipmap", _file(tmp_path, "[simulation]\ndt_ot = 0.1\n"))


@pytest.mark.parametrize("text, words", [
    ("[simulaton]\nt_end = 3\n", ["unknown section [simulaton]", "did you mean '[simulation]'"]),
    ("[link]\nmass = 1\n", ["unknown section [link]", "did you mean '[[links]]'"]),
    ("[[links]]\nlenght = 0.5\n", ["[[links]] 1", "'lenght'", "did you mean 'length'"]),
    ("[[links]]\nlength = 0.5\n[[links]]\nm = 0.5\n", ["[[links]] 2", "'m'", "did you mean 'mass'"]),
    ("[simulation]\nt_ned = 3\n", ["'t_ned'", "did you mean 't_end'"]),
    ("[initial]\nq = [1, 2]\n", ["'q'", "[initial]"]),
    ("[chain]\ngravity = 3\n[[links]]\nlength = 1\n", ["'gravity'", "did you mean 'g'"]),
])
def test_unknown_names_are_refused_with_the_name_likely_meant(tmp_path, text, words):
    """Even in a section the command leaves aside (modes does not use [simulation]): a typo is never ignored."""
    from helpers import run_cli

    config = _file(tmp_path, text)
    for command in ("simulate", "modes"):
        ran = run_cli([command, "--config", config, "-q"], cwd=tmp_path)
        errors = _errors(ran.err)
        assert ran.code == 2 and len(errors) == 1, ran.err
        assert all(w in errors[0] for w in words), errors[0]


# -- one file, every command, from the command line ---------------------------------------------------------------
@pytest.mark.parametrize("command", ["modes", "equilibria"])
def test_the_skewed_triple_serves_the_chain_commands(tmp_path, command):
    from helpers import run_cli

    ran = run_cli([command, "--config", TRIPLE, "-q"], cwd=tmp_path)
    assert ran.code == 0, ran.err
    notes = _notes(ran.err)
    assert len(notes) == 1 and "[initial] and [simulation]" in notes[0] and f"skewpend {command}" in notes[0], ran.err
    assert "q3" in ran.out or "down-down-down" in ran.out  # the chain of three, not the double pendulum


def test_the_skewed_triple_serves_the_explorer(tmp_path):
    """serve uses [initial] (q0: the start sliders; dq0 = 0: the page starts at rest) and leaves [simulation] aside."""
    from helpers import run_cli

    ran = run_cli(["serve", "--config", TRIPLE, "--export", "site", "-q"], cwd=tmp_path)
    assert ran.code == 0, ran.err
    notes = _notes(ran.err)
    assert len(notes) == 1 and "[simulation] is not used by skewpend serve" in notes[0], ran.err
    assert "q1_0=60.0" in ran.err  # the file's q0 = "60deg" reached the page's address
    speed = _file(tmp_path, TRIPLE.read_text().replace("dq0 = [0, 0, 0]", "dq0 = [0, 1, 0]"), "speed.toml")
    ran = run_cli(["serve", "--config", speed, "--export", "site2", "-q"], cwd=tmp_path)
    assert ran.code == 2 and "[initial] dq0" in _errors(ran.err)[0] and "at rest" in ran.err, ran.err


def test_a_page_runs_torques_friction_and_rotors_and_the_help_says_so(tmp_path):
    from helpers import run_cli

    config = _file(tmp_path, "[[links]]\nlength = 0.5\ntorque = 0.3\ncoulomb = 0.1\n\n[[links]]\nlength = 0.4\nrotor = 0.01\n")
    ran = run_cli(["serve", "--config", config, "--export", "site", "-q"], cwd=tmp_path)
    assert ran.code == 0, ran.err
    text = " ".join(run_cli(["serve", "--help"], cwd=tmp_path).out.split())
    assert "no joint torques" not in text and "refused" not in text.split("A chain of links")[0]
    assert "Constant joint torques (tau1, tau2), Coulomb friction (cf1, cf2, cfs) and rotor inertia (Ir, gr) are in the " \
           "page's physics as the file gives them" in text
    assert "torques, Coulomb friction and rotors are in its physics" in text
    # the double pendulum's too: the page is the recursive algorithms' (sliders g and the damping) with friction or
    # rotors, the derivation's with torques alone; a value the file leaves out is the reference case's
    for i, extra in enumerate(("cf1 = 0.05\nIr = 0.001\n", "tau1 = 0.3\n", "c1 = 0.01\ncf2 = 0.02\ngr = 2\n")):
        config = _file(tmp_path, f"[parameters]\na = 0.8\n{extra}", f"dp{i}.toml")
        ran = run_cli(["serve", "--config", config, "--export", f"dp{i}", "-q"], cwd=tmp_path)
        assert ran.code == 0, ran.err
        assert (tmp_path / f"dp{i}" / "index.html").is_file()
    config = _file(tmp_path, '[parameters]\ncf1 = 0.05\nm1 = "sym"\n', "sym.toml")
    ran = run_cli(["serve", "--config", config, "--export", "sym", "-q"], cwd=tmp_path)
    errors = _errors(ran.err)
    assert ran.code == 2 and len(errors) == 1 and "[parameters] m1" in errors[0] and "give a number" in errors[0], ran.err


# -- a chain's values are never the double pendulum's -----------------------------------------------------------
def test_a_chain_g_without_links_is_refused(tmp_path):
    from helpers import run_cli
    from skewpend.config import Run

    config = _file(tmp_path, "[chain]\ng = 1.0\n")
    ran = run_cli(["simulate", "--config", config, "--t-end", "0.1", "-q"], cwd=tmp_path)
    errors = _errors(ran.err)
    assert ran.code == 2 and len(errors) == 1 and "[chain] g" in errors[0] and "[parameters] g" in errors[0], ran.err
    assert ran.out == ""
    # with links (--links 2) the same g is the chain's: honoured
    chain = Run("simulate", config, {"parameters": {"links": 2}}).parameters()
    assert chain.n == 2 and chain.g == 1.0
    # a command of the double pendulum refuses [chain] as it refuses [[links]]
    ran = run_cli(["poincare", "--config", config, "--energy", "5", "-q"], cwd=tmp_path)
    assert ran.code == 2 and "[chain] (a chain of links) is not read by skewpend poincare" in ran.err, ran.err


@pytest.mark.parametrize("argv, words", [
    (["simulate", "--links", "33"], "--links: expected a whole number from 1 to 32, got '33'"),
    (["modes", "--links", "1000"], "--links: expected a whole number from 1 to 32, got '1000'"),
    (["simulate", "--links", "3", "--g", "-1"], "--g: g must be >= 0, got -1"),
    (["simulate", "--links", "3", "--g", "sym"], "--g: a chain's values must be numeric"),
    (["simulate", "--links", "3", "--cfs", "0"], "--cfs: cfs must be > 0"),
])
def test_chain_messages_name_their_subject(tmp_path, argv, words):
    from helpers import run_cli

    ran = run_cli([*argv, "-q"], cwd=tmp_path)
    errors = _errors(ran.err)
    assert ran.code == 2 and len(errors) == 1 and words in errors[0], ran.err
    assert "error: :" not in ran.err


def test_run_file_chain_limits_and_bounds_name_the_file(tmp_path):
    from helpers import run_cli

    many = _file(tmp_path, "[[links]]\nlength = 0.1\n" * 33, "many.toml")
    ran = run_cli(["simulate", "--config", many, "-q"], cwd=tmp_path)
    assert ran.code == 2 and "many.toml: [[links]]: a chain may have at most 32 links, got 33" in ran.err, ran.err
    low = _file(tmp_path, "[chain]\ng = -2\n[[links]]\nlength = 0.1\n", "low.toml")
    ran = run_cli(["simulate", "--config", low, "-q"], cwd=tmp_path)
    assert ran.code == 2 and "low.toml: [chain] g: g must be >= 0, got -2" in ran.err, ran.err


def test_the_documented_link_limit_is_the_one_enforced():
    """docs/guide/chains.md states the limit; the library, the options and the messages use the same one."""
    from skewpend.symbolic.chain import MAX_LINKS, Chain

    text = (Path(__file__).resolve().parent.parent / "docs" / "guide" / "chains.md").read_text()
    assert "at most 32" in text
    assert Chain.from_lists(32).n == 32
    with pytest.raises(ParameterError, match="at most 32 links, got 33"):
        Chain.from_mapping({"links": [{}] * 33})
    assert MAX_LINKS == 32


# -- derive: the exact symbolic form of a long chain ---------------------------------------------------------------
def test_derive_refuses_a_chain_too_long_for_symbolic_equations(tmp_path):
    from helpers import run_cli

    ran = run_cli(["derive", "--links", "10", "--format", "text", "-q"], cwd=tmp_path)
    errors = _errors(ran.err)
    assert ran.code == 2 and len(errors) == 1 and ran.out == "", ran.err
    assert errors[0].startswith("skewpend: error: --links:") and "hours" in errors[0] and "--format c|python|javascript" in errors[0]
    triple = _file(tmp_path, "".join("[[links]]\nlength = 0.2\n" for _ in range(8)), "eight.toml")
    ran = run_cli(["derive", "--config", triple, "-q"], cwd=tmp_path)
    assert ran.code == 2 and "eight.toml: [[links]]: the exact symbolic equations of a chain of 8 links" in ran.err, ran.err
    ran = run_cli(["derive", "--links", "10", "--format", "python", "-q"], cwd=tmp_path)  # the code: at once
    assert ran.code == 0 and "def rhs" in ran.out, ran.err


def test_derive_says_up_front_how_long_a_five_link_chain_takes(tmp_path, monkeypatch):
    """The note comes before the derivation begins (the derivation is replaced by a stand-in that stops)."""
    from helpers import run_cli
    from skewpend.symbolic import derivation

    class Began(ParameterError):
        pass

    def began(*args, **kwargs):
        raise Began("the derivation began")

    monkeypatch.setattr(derivation, "derive", began)
    ran = run_cli(["derive", "--links", "5", "-q"], cwd=tmp_path)
    lines = ran.err.strip().splitlines()
    assert ran.code == 2 and "the derivation began" in lines[-1], ran.err
    notes = _notes(ran.err)
    assert len(notes) == 1 and "chain of 5 links take about" in notes[0] and "--format c|python|javascript" in notes[0]
    ran = run_cli(["derive", "--links", "4", "-q"], cwd=tmp_path)
    assert ran.code == 2 and _notes(ran.err) == [], ran.err  # four links: a second or two, nothing to say


# -- the Python API's inputs -------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def models():
    pytest.importorskip("casadi")
    from skewpend import Parameters
    from skewpend.symbolic.chain import Chain

    return {"chain": Chain.from_lists(3), "double": Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)}


@pytest.mark.parametrize("kind", ["chain", "double"])
@pytest.mark.parametrize("bad, words", [
    ("complex", "complex number: (0.3+1j)"),
    ("complex-zero-imag", "complex number"),
    ("two-rows", "one row of real numbers, got an array of shape (2,"),
    ("boolean", "a boolean: True"),
    ("text", "text: '0.1'"),
])
def test_simulate_refuses_a_state_numpy_would_bend(models, kind, bad, words):
    from skewpend import simulate

    model = models[kind]
    n = 3 if kind == "chain" else 2
    y0 = {
        "complex": [0.1, 0.3 + 1j] + [0.0] * (2 * n - 2),
        "complex-zero-imag": np.zeros(2 * n, dtype=complex),
        "two-rows": np.zeros((2, n)),
        "boolean": (True,) + (0.0,) * (2 * n - 1),
        "text": ["0.1"] + [0.0] * (2 * n - 1),
    }[bad]
    with pytest.raises(ParameterError, match="y0 must be") as exc:
        simulate(model, y0, 0.1)
    assert words in str(exc.value)


@pytest.mark.parametrize("n", [True, False, 0, 33, 2.0, "3"])
def test_chain_from_lists_takes_a_whole_number_of_links(n):
    from skewpend.symbolic.chain import Chain

    with pytest.raises(ParameterError, match="n must be the number of links, a whole number from 1 to 32"):
        Chain.from_lists(n)
    assert Chain.from_lists(np.int64(3)).n == 3


def test_chain_mappings_suggest_the_key_meant():
    from skewpend.symbolic.chain import Chain

    with pytest.raises(ParameterError, match=r"link 1: unknown key 'lenght' \(did you mean 'length'\?\)"):
        Chain.from_mapping({"links": [{"lenght": 1.0}]})
    with pytest.raises(ParameterError, match=r"unknown per-link key 'masses' \(did you mean 'mass'\?\)"):
        Chain.from_lists(2, masses=[1.0, 2.0])
    with pytest.raises(ParameterError, match=r"unknown key 'gravity' \(did you mean 'g'\?\)"):
        Chain.from_mapping({"links": [{}], "gravity": 1.0})


@pytest.mark.parametrize("command, text, key, why", [
    ("lyapunov", '[simulation]\nout = "x.csv"\n', "out", None),
    ("flipmap", "[simulation]\ndt_out = 0.1\n", "dt_out", None),
    ("poincare", "[simulation]\nt_end = 5\n", "t_end", "each orbit runs until its crossings are recorded, or --t-max"),
    ("animate", '[simulation]\nout = "x.csv"\n', "out", "the video is written to --out FILE.mp4|.gif"),
    ("animate", "[simulation]\ndt_out = 0.1\n", "dt_out", "speed/fps"),
    ("report", '[simulation]\nplot = "p.png"\n', "plot", None),
    ("validate", '[simulation]\nmethod = "rk4"\n', "method", None),
])
def test_another_commands_setting_takes_no_effect_and_is_said(tmp_path, command, text, key, why):
    """Were refused until issue 51 (one run file for every command): left aside, never silently."""
    from skewpend.config import Run

    run = Run(command, _file(tmp_path, text))
    note = " ".join(run.notes)
    assert f"[simulation] {key} is a setting of other commands, not used by skewpend {command}; ignored" in note
    assert why is None or why in note
    assert not run.is_given("simulation", key)
