"""``skewpend control`` and ``skewpend serve`` read the rotary pendulum's ``[motor]`` (issue 54, item 4;
``examples/qube_servo2.toml``): control actuates the motor's joint within its torque limit kt Vmax / R, the
back-EMF kt km / R in the joint's damping -- one note saying it, explicit ``--actuated``/``--umax`` winning --;
the explorer takes the motor at 0 V (its damping), as simulate does."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from skewpend.config import Run

ROOT = Path(__file__).resolve().parents[1]
RUN_FILE = ROOT / "examples" / "qube_servo2.toml"
UMAX = 0.042 * 3.0 / 8.4  # kt Vmax / R [N m]
BACK_EMF = 0.042 * 0.042 / 8.4  # kt km / R [N m s]


def _closed_loop(stdout: str) -> np.ndarray:
    """The eigenvalues of the printed line ``closed loop -1, -8.3+3.4i, -8.3-3.4i, -1.4e4 [1/s]``."""
    line = next(ln for ln in stdout.splitlines() if ln.startswith("closed loop"))
    values = line[len("closed loop"):].replace("[1/s]", "").split(",")
    return np.sort_complex(np.array([complex(v.strip().replace("i", "j")) for v in values]))


def _notes(err: str):
    return [ln for ln in err.splitlines() if "[motor] on joint 1" in ln]


@pytest.mark.slow
def test_control_lqr_actuates_the_motors_joint_within_its_limit_with_its_back_emf_as_damping():
    """The gains and closed loop printed are those of the library's LQR on the chain with joint 1's damping Dr +
    kt km / R, joint 1 actuated, |u| <= kt Vmax / R -- and not those of the chain without the back-EMF."""
    from helpers import run_cli

    from skewpend.analysis.control import lqr

    ran = run_cli(["control", "lqr", "--config", RUN_FILE, "--target", "down-up"])
    assert ran.code == 0, ran.report()
    notes = _notes(ran.err)
    assert len(notes) == 1, ran.report()
    assert "(skewpend control: --actuated 1 (its joint), --umax 0.015 (kt Vmax/R); the back-EMF in the joint's damping)" \
        in notes[0]
    assert "actuated    joint 1;" in ran.out and f"|u| <= {UMAX:g} N m" in ran.out, ran.out
    chain = Run("simulate", str(RUN_FILE)).chain()
    assert chain.links[0].damping == pytest.approx(0.00027 + BACK_EMF, rel=1e-15)
    design = lqr(chain, "down-up", (1,), umax=UMAX)
    printed = _closed_loop(ran.out)
    expected = np.sort_complex(np.asarray(design.eigenvalues))
    np.testing.assert_allclose(printed, expected, rtol=1e-5)  # printed to 6 digits
    row = next(ln for ln in ran.out.splitlines() if ln.startswith("  joint 1"))
    gains = np.array([float(v) for v in row.split()[2:]])
    np.testing.assert_allclose(gains, design.K[0], rtol=5e-6)  # printed to 6 digits
    # without the back-EMF the arm's speed gain differs in the 4th digit: the printed gains are the damped model's
    bare = lqr(chain.replace_link(1, damping=0.00027), "down-up", (1,), umax=UMAX)
    assert abs(gains[2] - bare.K[0, 2]) > 1e-4 * abs(bare.K[0, 2])


@pytest.mark.slow
def test_explicit_actuated_and_umax_win_over_the_motor_and_the_note_says_so():
    from helpers import run_cli

    ran = run_cli(["control", "lqr", "--config", RUN_FILE, "--target", "down-up", "--umax", "0.02", "--actuated", "1"])
    assert ran.code == 0, ran.report()
    notes = _notes(ran.err)
    assert len(notes) == 1 and "(skewpend control: --actuated 1 as given, --umax 0.02 as given;" in notes[0], ran.report()
    assert "|u| <= 0.02 N m" in ran.out and f"|u| <= {UMAX:g} N m" not in ran.out, ran.out


@pytest.mark.slow
def test_the_default_target_is_the_rigs_highest_rest_said_in_a_note():
    """The arm turns about the vertical: the rig has no up-up rest, so control's default target (every link up)
    is its highest rest, down-up (the pendulum upright), said once; the same as --target down-up."""
    from helpers import run_cli

    ran = run_cli(["control", "lqr", "--config", RUN_FILE])
    assert ran.code == 0, ran.report()
    said = [ln for ln in ran.err.splitlines() if "no up-up rest" in ln]
    assert len(said) == 1 and "the target is its highest rest, down-up" in said[0], ran.report()
    assert "target      down-up: phi = 0 deg, psi = 180 deg" in ran.out, ran.out


@pytest.mark.slow
def test_the_mpc_swing_up_at_the_drivers_3_volts_runs_and_says_it_fails_exit_1():
    """``skewpend control swingup --controller mpc --config examples/qube_servo2.toml`` runs the MPC within the
    motor's 0.015 N m (3 V) and does not swing the pendulum up (docs/guide/rotary-pendulum.md: 10 V does): it says
    so in its result line and one error line, exit 1 as control's other failures; every input within the limit."""
    from helpers import run_cli

    ran = run_cli(["control", "swingup", "--controller", "mpc", "--config", RUN_FILE, "--t-end", "3"])
    assert ran.code == 1, ran.report()
    assert "swing-up    joint 1 to down-up, |u| <= 0.015 N m, 3 s" in ran.out, ran.out
    assert "result      not captured" in ran.out and "controller  model-predictive" in ran.out, ran.out
    largest = float(re.search(r"largest \|u\| ([0-9.e+-]+) N m", ran.out).group(1))
    assert UMAX * 0.9 < largest <= UMAX * (1 + 1e-9)
    errors = [ln for ln in ran.err.splitlines() if ln.startswith("skewpend: control:") or "error" in ln]
    assert len(errors) == 1 and "not captured" in errors[0], ran.report()


def test_serve_reads_the_motor_at_0_volts_as_simulate_does():
    """The explorer's model is the chain with the back-EMF in joint 1's damping (the motor at 0 V), the note as
    simulate's."""
    run = Run("serve", str(RUN_FILE))
    assert run.chain().links[0].damping == pytest.approx(0.00027 + BACK_EMF, rel=1e-15)
    assert [n for n in run.notes if "[motor]" in n] == [n.replace("skewpend simulate", "skewpend serve") for n in
                                                        Run("simulate", str(RUN_FILE)).notes if "[motor]" in n]
    assert any("skewpend serve applies 0 V" in n for n in run.notes)


@pytest.mark.parametrize("actuated, umax, expected, words", [
    (None, None, ((1,), UMAX), ["--actuated 1 (its joint)", "--umax 0.015 (kt Vmax/R)"]),
    ((1,), 0.02, ((1,), 0.02), ["--actuated 1 as given", "--umax 0.02 as given"]),
    (None, 0.02, ((1,), 0.02), ["--actuated 1 (its joint)", "--umax 0.02 as given"]),
    ((1, 2), None, ((1, 2), None), ["--actuated 1,2 as given", "no --umax from it (it drives one joint of those actuated)"]),
    ("both", None, ("both", None), ["--actuated both as given", "no --umax from it (it drives one joint of those actuated)"]),
])
def test_what_control_takes_of_the_motor(actuated, umax, expected, words):
    """Its joint and limit where not given; a given --actuated/--umax wins; its limit only for its joint alone."""
    motor = Run("simulate", str(RUN_FILE)).motor
    got_actuated, got_umax, said = motor.control_actuators(actuated, umax)
    assert (got_actuated, got_umax) == expected and said == words
    note = motor.control_note(said)
    assert note.startswith("[motor] on joint 1: back-EMF kt km/R = 0.00021 N m s added to joint 1's damping")
    assert note.endswith(f"(skewpend control: {', '.join(words)}; the back-EMF in the joint's damping)")
