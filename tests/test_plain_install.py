"""What the README's plain install (``pip install .``) gives is what the README tours (issue 51, item 3):
CasADi (chains, the leaderboard's optimal swing-ups) is a default dependency, the shipped run files
travel with the package, and a tutorial that needs an extra says which, with the install line.

A plain install is imitated in a subprocess whose imports of every optional dependency fail (a
``sitecustomize`` on ``PYTHONPATH`` that refuses them), so the test holds on a machine that has them."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import skewpend
from skewpend.errors import EXTRAS

ROOT = Path(__file__).resolve().parents[1]

try:
    import tomllib
except ImportError:  # Python 3.10
    import tomli as tomllib

PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))


def _name(requirement: str) -> str:
    return re.split(r"[<>=!~;\[ ]", requirement, maxsplit=1)[0].strip().lower()


DEFAULT = {_name(r) for r in PYPROJECT["project"]["dependencies"]}
#: Importable optional modules: those of the extras (errors.EXTRAS) and xarray, none a default dependency.
OPTIONAL = sorted(m for m in EXTRAS if m.lower() not in DEFAULT and m != "casadi")

BLOCKER = """
import importlib.abc, sys
BLOCKED = set({blocked!r})
class _Plain(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {{name!r}} (a plain install)", name=name)
        return None
sys.meta_path.insert(0, _Plain())
"""


@pytest.fixture(scope="module")
def plain_env(tmp_path_factory):
    site = tmp_path_factory.mktemp("plain-site")
    (site / "sitecustomize.py").write_text(BLOCKER.format(blocked=OPTIONAL), encoding="utf-8")
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


def _run(argv, env, cwd, timeout=300):
    return subprocess.run(argv, env=env, cwd=cwd, capture_output=True, text=True, timeout=timeout)


def test_casadi_is_a_default_dependency():
    """The README's tour runs chains and the leaderboard, which need CasADi: it comes with ``pip install .``."""
    assert "casadi" in DEFAULT
    assert EXTRAS["casadi"] is None  # a missing CasADi is a broken install, not a missing extra
    assert set(OPTIONAL) >= {"mujoco", "zarr", "netCDF4", "fastapi", "xarray"}


def test_the_blocker_imitates_a_plain_install(plain_env, tmp_path):
    """The imitation itself can fail: an optional module is refused, a default one imports."""
    ran = _run([sys.executable, "-c", "import casadi, numpy, scipy, sympy\nimport mujoco"], plain_env, tmp_path)
    assert ran.returncode == 1 and "No module named 'mujoco' (a plain install)" in ran.stderr, ran.stderr


def test_the_tours_chain_line_runs_on_a_plain_install(plain_env, tmp_path):
    """``skewpend simulate --config examples/skewed_triple.toml`` (the README's last tour line) exited 2
    with 'needs casadi' after ``pip install .``; here from another folder through the shipped file."""
    path = skewpend.example_run_file("skewed_triple")
    ran = _run([sys.executable, "-m", "skewpend", "simulate", "--config", str(path), "--t-end", "0.5"], plain_env, tmp_path)
    assert ran.returncode == 0, ran.stderr
    assert "reached t_end" in ran.stdout
    assert "needs" not in ran.stderr


def test_the_leaderboards_optimiser_builds_on_a_plain_install(plain_env, tmp_path):
    """``skewpend control leaderboard`` exited 2 asking for ``skewpend[chains]``: its transcription's
    dynamics (CasADi) build for the acrobot with nothing but the default dependencies."""
    code = ("from skewpend.analysis import leaderboard, trajopt\n"
            "chain = trajopt._as_chain(leaderboard.dfki_model())\n"
            "f = trajopt.casadi_dynamics(chain, (1,))\n"
            "print('built', chain.n)\n")
    ran = _run([sys.executable, "-c", code], plain_env, tmp_path)
    assert ran.returncode == 0 and "built 2" in ran.stdout, ran.stderr


def test_the_run_files_are_package_data():
    """The repository's ``examples/`` is a link to the package's folder: one copy, installed with the code."""
    files = skewpend.datasets.example_run_files()
    assert {"skewed_triple", "chaotic", "general_body"} <= set(files)
    for stem, path in files.items():
        assert (ROOT / "examples" / path.name).resolve() == path.resolve()
    with pytest.raises(skewpend.ParameterError, match="available: .*skewed_triple"):
        skewpend.example_run_file("nowhere")
    assert skewpend.example_run_file("skewed_triple.toml") == files["skewed_triple"]


#: What in a tutorial's code needs an optional module: the module, by the text that shows it.
USES = {
    "mujoco": [r"^\s*import mujoco", r"compare_with_mujoco\(", r"mujoco_trajectory\("],
    "zarr": [r"\.zarr[\"']"],
    "distributed": [r"scheduler="],
    "netCDF4": [r"to_netcdf\("],
    "xarray": [r"to_xarray\(\)"],
    "anywidget": [r"widget\("],
}


def _code(page: str) -> str:
    return "\n".join(re.findall(r"```\{code-cell\}[^\n]*\n(.*?)```", page, flags=re.S))


@pytest.mark.parametrize("path", sorted((ROOT / "docs" / "tutorials").glob("*.md")), ids=lambda p: p.name)
def test_a_tutorial_names_the_install_of_each_extra_it_needs(path):
    """After a plain install every tutorial runs, or says up front what to install for the parts that
    need more (the chains tutorial needed MuJoCo unmentioned)."""
    page = path.read_text(encoding="utf-8")
    code = _code(page)
    missing = []
    for module, patterns in USES.items():
        if any(re.search(p, code, flags=re.M) for p in patterns):
            extra = EXTRAS[module]
            line = 'pip install "skewpend[' if extra else f"pip install {module.lower()}"
            named = re.search(re.escape(line) + (rf"[a-z,]*{extra}" if extra else ""), page)
            if not named:
                missing.append(f"{module} ({line}{extra + ']' if extra else ''})")
    assert not missing, f"{path.name} uses {missing} without naming the install"
