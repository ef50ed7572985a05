"""`skewpend derive`: formats, the JSON contract, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
import sympy as sp

from skewpend import Parameters, derive
from skewpend.symbolic.derivation import SYMBOLS
from skewpend.symbolic.render import to_json
from helpers import completed


def run(*args, check=True):
    """Run the real command in a fresh process, as a user would."""
    return completed(args, timeout=120, check=check)


@pytest.fixture(scope="module")
def contract():
    return json.loads(run("derive", "--format", "json", "--linear").stdout)


def test_json_contract_keys_and_symbols(contract):
    assert contract["coordinates"] == ["phi", "psi"]
    assert contract["speeds"] == ["dphi", "dpsi"]
    assert contract["parameters"] == ["a", "b", "m1", "m2", "alpha", "g"]
    assert np.shape(contract["mass_matrix"]) == (2, 2)
    assert len(contract["forcing"]) == 2
    assert np.shape(contract["linearized"]["M"]) == (2, 2)
    assert np.shape(contract["linearized"]["K"]) == (2, 2)
    strings = (
        sum(contract["mass_matrix"], [])
        + contract["forcing"]
        + [contract["kinetic_energy"], contract["potential_energy"]]
        + sum(contract["linearized"]["M"], [])
        + sum(contract["linearized"]["K"], [])
    )
    names = set()
    for s in strings:
        names |= {x.name for x in sp.sympify(s).free_symbols}
    assert names == {"a", "b", "m1", "m2", "g", "alpha", "phi", "psi", "dphi", "dpsi"}


def test_json_round_trips_to_the_same_equations(contract):
    """Parsed strings equal the library's expressions (compared by value at random points)."""
    eom = derive()
    by_name = {s.name: s for s in SYMBOLS.values()}
    parse = lambda s: sp.sympify(s).xreplace({x: by_name[x.name] for x in sp.sympify(s).free_symbols})
    M = sp.Matrix([[parse(x) for x in row] for row in contract["mass_matrix"]])
    f = sp.Matrix([parse(x) for x in contract["forcing"]])
    diff = list(M - eom.mass_matrix) + list(f - eom.forcing)
    assert all(sp.expand(d) == 0 for d in diff)
    # mass_matrix . [phi'', psi''] = forcing has the meaning of Lagrange's equations: check
    # against T and Pi from the same JSON with the power balance at a random state
    T, Pi = parse(contract["kinetic_energy"]), parse(contract["potential_energy"])
    q = [SYMBOLS["phi"], SYMBOLS["psi"]]
    dq = [SYMBOLS["dphi"], SYMBOLS["dpsi"]]
    ddq = M.LUsolve(f)
    E = T + Pi
    power = sum(E.diff(x) * v for x, v in zip(q, dq)) + sum(E.diff(v) * w for v, w in zip(dq, ddq))
    rng = np.random.default_rng(1)
    vals = dict(zip(["a", "b", "m1", "m2", "alpha", "g", "phi", "psi", "dphi", "dpsi"], rng.uniform(0.2, 2, 10)))
    assert abs(float(power.subs({by_name[k]: v for k, v in vals.items()}))) < 1e-10


def test_numeric_values_are_reported_and_substituted():
    data = json.loads(run("derive", "-f", "json", "--a", "1", "--b", "0.8", "--alpha", "90deg").stdout)
    assert data["parameters"] == ["m1", "m2", "g"]
    assert data["values"]["a"] == 1.0 and data["values"]["alpha"] == pytest.approx(np.pi / 2)
    assert sp.sympify(data["mass_matrix"][0][1]) == 0  # alpha = 90 deg: no inertial coupling


def test_text_output_names_the_equations():
    out = run("derive", "--linear").stdout
    for label in ("M₁₁", "M₁₂ = M₂₁", "M₂₂", "f₁", "f₂", "T =", "Π =", "M₀", "K₀"):
        assert label in out


def test_steps_follow_the_specifications_order():
    out = run("derive", "--steps", "--alpha", "0").stdout
    positions = [out.index(k) for k in ("P₁ =", "e =", "P =", "ω₂ =", "ϑc =", "Θ₂ =", "T =", "Π =", "M₁₁")]
    assert positions == sorted(positions)
    data = json.loads(run("derive", "--steps", "-f", "json").stdout)
    assert list(data["steps"]) == ["P1", "e", "P", "omega2", "v_c", "Theta2", "T", "Pi", "M", "f"]


def test_latex_output():
    out = run("derive", "--format", "latex", "--linear").stdout
    assert out.startswith("\\[") and "\\begin{aligned}" in out and "\\ddot{\\varphi}" in out
    assert derive()._repr_latex_().startswith("$\\displaystyle")


def test_general_body_options():
    data = json.loads(
        run("derive", "-f", "json", "--a", "1", "--b", "1", "--m1", "1", "--m2", "1", "--g", "9.81",
            "--axis2", "1,0,1", "--com2", "0,0.5,0", "--inertia2", "0.1,0.01,0.1").stdout
    )
    assert data["parameters"] == []
    assert data["values"]["axis2"] == pytest.approx([2**-0.5, 0, 2**-0.5])


@pytest.mark.parametrize(
    "args, message",
    [
        (["derive", "--m1", "-1"], "m1 must be > 0"),
        (["derive", "--alpha", "abc"], "--alpha: expected a number"),
        (["derive", "--a", "nan"], "--a: expected a finite number"),
        (["derive", "--unknown"], "No such option"),
        (["derive", "--format", "xml"], "--format"),
        (["derive", "--inertia2", "1,2"], "--inertia2: expected 3 or 6 or 9"),
        (["derive", "--inertia2", "1,1,3"], "triangle inequality"),
        (["derive", "--axis1", "0,0,0"], "axis1 must be a non-zero vector"),
        (["derive", "--tau1", "1", "--linear"], "not an equilibrium"),
        (["frobnicate"], "No such command"),
    ],
)
def test_bad_input_gives_one_line_and_status_2(args, message):
    proc = run(*args, check=False)
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("skewpend: error:"), proc.stderr
    assert message in lines[0]


def test_help_and_version():
    assert "derive" in run("--help").stdout
    assert run("--version").stdout.startswith("skewpend ")


def test_to_json_is_the_library_form_of_the_contract():
    data = to_json(derive(Parameters(alpha=0)), linear=derive(Parameters(alpha=0)).linearize())
    assert set(data) >= {"coordinates", "speeds", "parameters", "mass_matrix", "forcing", "kinetic_energy", "potential_energy", "linearized"}


# -- a chain of links ----------------------------------------------------------------------------------------
CHAIN_TOML = """[chain]
g = 9.81

[[links]]
length = 0.5
mass = 1.0

[[links]]
length = 0.4
mass = 0.8
axis = [0.6, 0, 0.8]

[[links]]
length = 0.3
mass = 0.5
axis = [1, 0, 0]
damping = 0.01
"""


@pytest.fixture(scope="module")
def chain_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("chain") / "triple.toml"
    path.write_text(CHAIN_TOML)
    return path


def test_a_chains_json_parses_back_to_its_derivation(chain_file):
    """`derive --config` with [[links]]: the JSON contract for n coordinates; every entry sympifies back
    to the library's derivation of the same chain (differences simplify to 0)."""
    from skewpend.symbolic.chain import Chain
    from skewpend.symbolic.derivation import coordinate_symbol

    data = json.loads(run("derive", "--config", str(chain_file), "--format", "json", "--linear").stdout)
    assert data["coordinates"] == ["q1", "q2", "q3"] and data["speeds"] == ["dq1", "dq2", "dq3"]
    assert len(data["mass_matrix"]) == 3 and len(data["values"]["links"]) == 3
    chain = Chain.from_mapping(data["values"])
    eom = derive(chain)
    names = {n: coordinate_symbol(n) for c in eom.coordinates for n in (c, "d" + c)}
    state = list(names.values())
    rng = np.random.default_rng(5)
    points = rng.uniform(-3, 3, (5, len(state)))

    def same(text, expr):  # the printed floats are the derivation's to their 17 digits: equal to 1e-12
        a = sp.lambdify(state, sp.sympify(text, locals=names))
        b = sp.lambdify(state, expr)
        return all(abs(float(a(*x)) - float(b(*x))) <= 1e-12 * max(1.0, abs(float(b(*x)))) for x in points)

    for i in range(3):
        assert all(same(data["mass_matrix"][i][j], eom.mass_matrix[i, j]) for j in range(3))
        assert same(data["forcing"][i], eom.forcing[i])
    lin = eom.linearize()
    assert all(same(data["linearized"]["K"][i][j], lin.K[i, j]) for i in range(3) for j in range(3))


def test_a_chains_text_latex_and_code(chain_file):
    text = run("derive", "--config", str(chain_file), "--steps").stdout
    assert text.startswith("Chain of 3 links") and "M₁₃ = M₃₁" in text and "f₃" in text
    assert "rotation tensor of link 3, P3 = P2 . P(q3, e30)" in text
    latex = run("derive", "--config", str(chain_file), "--format", "latex").stdout
    assert r"\ddot{q}_{3}" in latex and r"\begin{aligned}" in latex
    c = run("derive", "--config", str(chain_file), "--format", "c").stdout
    assert "from a chain's recursive algorithms" in c and "#define SP_NQ 3" in c
    py = run("derive", "--config", str(chain_file), "--format", "python").stdout
    assert "def rhs(t, y, p=P):" in py and "N = 3" in py
    js = run("derive", "--config", str(chain_file), "--format", "javascript").stdout
    assert "export function rhs(y, p = P) {" in js and "export const N = 3;" in js
    bad = run("derive", "--config", str(chain_file), "--format", "python", "--steps", check=False)
    assert bad.returncode == 2 and "--steps go with --format text" in bad.stderr and "Traceback" not in bad.stderr
