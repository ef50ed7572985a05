"""Every option's help says its default (issue 29: the model's options showed none, though the
reference case fills them in), and the default it shows is the one the command uses."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest

from helpers import run_cli

#: Options with no default to state: outputs (nothing is written), a cluster (this machine), flags.
NO_DEFAULT = {"out", "plot", "animate", "export", "scheduler", "config", "help"}


def _commands():
    from skewpend.cli import _group

    def walk(cmd, name):
        if hasattr(cmd, "commands"):
            for k, v in cmd.commands.items():
                yield from walk(v, f"{name} {k}".strip())
        else:
            yield name, cmd

    return list(walk(_group(), ""))


def test_every_option_states_its_default_or_that_it_is_required():
    missing = []
    for name, cmd in _commands():
        for p in cmd.params:
            if getattr(p, "is_flag", False) or p.name in NO_DEFAULT or p.param_type_name != "option":
                continue
            if not re.search(r"\b(default|required|instead of|with --)", p.help or "", re.IGNORECASE):
                missing.append(f"skewpend {name} {p.opts[0]}: {p.help!r}")
    assert not missing, "\n".join(missing)


@pytest.mark.parametrize("command,flag,shown", [("simulate", "--a", "(default 1)"), ("simulate", "--alpha", "(default 0.6)"),
                                                ("control", "--m2", "(default 0.7)"), ("derive", "--a", "(default symbolic)"),
                                                ("modes", "--b", "(default 0.8; symbolic with --format latex)")])
def test_model_defaults_shown_per_command(command, flag, shown):
    ran = run_cli([command, "--help"])
    assert ran.code == 0
    line = " ".join(ran.out.split())  # the help wraps its lines
    assert re.search(re.escape(flag) + r" \S+ [^-]*?" + re.escape(shown), line), line[:2000]


def test_the_shown_model_defaults_are_the_ones_used():
    """simulate with no model options and with every shown default typed out: the same run."""
    from skewpend.config import DEFAULT_RUN

    typed = [x for k, v in DEFAULT_RUN["parameters"].items() for x in (f"--{k}", str(v))]
    plain = run_cli(["simulate", "--t-end", "0.5"])
    explicit = run_cli(["simulate", "--t-end", "0.5", *typed])
    drop = lambda text: [line for line in text.splitlines() if not line.startswith("wall time")]
    assert plain.code == explicit.code == 0 and "final state" in plain.out
    assert drop(plain.out) == drop(explicit.out)


def test_the_command_table_is_the_modules_commands_in_the_helps_order():
    import importlib

    from skewpend import cli

    for module in set(cli._MODULES.values()):
        commands = importlib.import_module(f"skewpend.cli.{module}").COMMANDS
        assert {name for name, m in cli._MODULES.items() if m == module} == set(commands), module
    assert list(cli._group().commands) == list(cli.COMMAND_NAMES)


def test_a_run_builds_and_imports_only_the_command_it_names():
    """`skewpend simulate` parses one command's signature, not seventeen (the start of every run)."""
    code = ("import sys\nfrom skewpend import cli\ntry:\n    cli.main(['simulate', '--help'])\nexcept SystemExit:\n    pass\n"
            "print(sorted(m for m in sys.modules if m.startswith('skewpend.cli.')))\n"
            "print(sorted(cli._GROUPS['simulate'].commands))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.splitlines()
    assert out[-2] == "['skewpend.cli.options', 'skewpend.cli.simulate', 'skewpend.cli.types']"
    assert out[-1] == "['simulate']"
