"""The parameter schema (issue 37): every parameter declared once, everything else derived from it.

* no module but ``schema.py`` lists two or more parameter names in a literal collection (the
  scan below reads every module's syntax tree);
* :class:`skewpend.Parameters`' fields, the kernels' parameter order, the run files' keys, the
  SymPy symbols' assumptions and the command line's model options are the schema's;
* an unknown or misspelled name is one line naming it, its nearest allowed name and the allowed
  names; a value out of bounds is one line with the bound; a run file of an older skewpend reads;
* one rule says whether a model is conservative: damping, Coulomb friction and torques count, the
  rotors' inertia does not -- and Poincare sections refuse a model with Coulomb friction (they
  ignored it before).
"""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import pytest

import skewpend
from skewpend import Parameters, schema
from skewpend.errors import ParameterError

PACKAGE = Path(skewpend.__file__).resolve().parent
ROOT = PACKAGE.parent.parent

#: Literal collections that hold parameter names by coincidence: another program's names.
FOREIGN = {
    ("analysis/measurements.py", "DFKI_KEYS"): "the DFKI lab's model-file keys (its own schema; some coincide with ours)",
    ("analysis/robustness.py", "LAB_VARIATIONS"): "the DFKI lab's robustness board's varied parameters (its names)",
}


def _assigned_name(tree: ast.Module, node: ast.AST):
    for stmt in tree.body:
        if isinstance(stmt, (ast.Assign, ast.AnnAssign)) and stmt.value is node:
            targets = stmt.targets if isinstance(stmt, ast.Assign) else [stmt.target]
            return next((t.id for t in targets if isinstance(t, ast.Name)), None)
    return None


def _listings():
    names = set(schema.NAMES)
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        if rel == "schema.py":
            continue
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
                items = node.elts
            elif isinstance(node, ast.Dict):
                items = [k for k in node.keys if k is not None]
            else:
                continue
            hits = [e.value for e in items if isinstance(e, ast.Constant) and isinstance(e.value, str) and e.value in names]
            if len(hits) >= 2 and (rel, _assigned_name(tree, node)) not in FOREIGN:
                yield f"{rel}:{node.lineno}: {hits}"


def test_no_module_but_the_schema_lists_parameter_names():
    found = list(_listings())
    assert not found, "parameter names listed outside skewpend/schema.py (derive them from the schema):\n" + "\n".join(found)


def test_the_scan_finds_a_listing():
    """The scan is not blind: a literal tuple of two names in a module's text is found."""
    tree = ast.parse('X = ("m1", "c2")\nY = ("phi", "psi")\n')
    node = tree.body[0].value
    hits = [e.value for e in node.elts if e.value in schema.NAMES]
    assert hits == ["m1", "c2"] and _assigned_name(tree, node) == "X"


# -- what derives from the schema -------------------------------------------------------------------
def test_parameters_fields_are_the_schema():
    fields = dataclasses.fields(Parameters)
    assert tuple(f.name for f in fields) == schema.NAMES
    for f in fields:
        assert f.default == schema.default(f.name), f.name


def test_kernel_parameter_order_is_the_schemas_scalars():
    from skewpend.numeric.conventions import BODY_ENTRIES, PARAMETER_ORDER, SCALAR_ORDER

    # the compiled kernels' p: the schema's scalars, then each body's centre of mass and inertia tensor
    # entries (run-time inputs, issue 37), named as the symbols name them
    assert SCALAR_ORDER == schema.SCALAR_NAMES and PARAMETER_ORDER == schema.SCALAR_NAMES + BODY_ENTRIES
    assert BODY_ENTRIES[:3] == ("r1x", "r1y", "r1z") and BODY_ENTRIES[6:12] == ("I1xx", "I1xy", "I1xz", "I1yy", "I1yz", "I1zz")
    assert len(BODY_ENTRIES) == 3 * len(schema.COM_NAMES) + 6 * len(schema.INERTIA_NAMES)
    # today's layout of p (the compiled kernels and every stored result depend on it)
    assert schema.SCALAR_NAMES[:6] == ("a", "b", "m1", "m2", "alpha", "g")
    assert len(schema.SCALAR_NAMES) == 15 and schema.GEOMETRY_NAMES[0] == "com1"


def test_symbols_take_the_schemas_bounds():
    from skewpend.symbolic.symbols import SYMBOLS

    for n in schema.SCALAR_NAMES:
        bound = schema.field(n).bound
        s = SYMBOLS[n]
        assert s.is_real, n
        assert bool(s.is_positive) == (bound == "positive"), n
        assert bool(s.is_nonnegative) == (bound in ("positive", "nonnegative")), n


def test_run_file_keys_and_cli_options_are_the_schemas():
    from skewpend.config import MODEL_KEYS
    from skewpend.io import CONFIG_SECTIONS

    assert MODEL_KEYS == frozenset(schema.NAMES) == frozenset(CONFIG_SECTIONS["parameters"])


def test_texts_exist_for_every_parameter():
    for n in schema.NAMES:
        assert schema.meaning(n) and schema.help_text(n) and schema.tex(n), n
        assert "{" not in schema.meaning(n) + schema.help_text(n), n
    assert schema.meaning("m2") == "mass of rod 2" and schema.unit("m2") == "kg"
    assert schema.symbol("tau1") == "τ₁" and schema.tex("tau1") == r"\tau_1"
    assert schema.default_text("com2") == "rod midpoint (0, b/2, 0)"


# -- bad input ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("given, near", [("mass1", "m1"), ("M2", "m2"), ("alfa", "alpha"), ("inertia_1", "inertia1"),
                                         ("length2", "b"), ("gravity", "g")])
def test_misspelled_names_get_the_nearest(given, near):
    with pytest.raises(ParameterError) as info:
        Parameters(**{given: 1.0})
    text = str(info.value)
    assert "\n" not in text
    assert f"unknown parameter {given!r} (did you mean {near!r}?)" in text
    assert "allowed: a, b, m1, m2, alpha, g" in text


def test_replace_and_mapping_refuse_unknown_names_the_same_way():
    p = skewpend.reference_parameters()
    for call in (lambda: p.replace(masss1=2.0), lambda: Parameters.from_mapping({"masss1": 2.0})):
        with pytest.raises(ParameterError, match=r"unknown parameter 'masss1' \(did you mean 'm1'\?\)"):
            call()


def test_run_file_with_an_unknown_name(tmp_path):
    from skewpend.io import read_config

    path = tmp_path / "run.toml"
    path.write_text("[parameters]\na = 1.0\ndampng1 = 0.1\n")
    with pytest.raises(ParameterError) as info:
        read_config(path)
    assert str(info.value).startswith(f"{path}: [parameters]: unknown parameter 'dampng1'")
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("name, value, bound", [("m1", -1.0, "m1 must be > 0"), ("c2", -0.1, "c2 must be >= 0"),
                                                ("cfs", 0.0, "cfs must be > 0"), ("g", -9.81, "g must be >= 0")])
def test_out_of_bounds_is_one_line_with_the_bound(name, value, bound):
    with pytest.raises(ParameterError) as info:
        Parameters(**{name: value})
    assert str(info.value).startswith(bound) and "\n" not in str(info.value)


def test_a_run_file_of_an_older_skewpend_reads(tmp_path):
    """The fitted model written by the previous version (keys in its order, c1/c2 always spelled,
    full 3x3 tensors) reads, and written again by today's writer it reads back the same."""
    from skewpend.config import parameters_toml
    from skewpend.io import read_config
    from skewpend.config import build_parameters

    old = ROOT / "examples" / "fitted_kaheman.toml"
    values = read_config(old)["parameters"]
    p = build_parameters(values)
    assert p.is_numeric and p.m1 > 0
    path = tmp_path / "again.toml"
    path.write_text("[parameters]\n" + "\n".join(parameters_toml(p)) + "\n")
    assert build_parameters(read_config(path)["parameters"]) == p


# -- one rule for "conservative" ---------------------------------------------------------------------
BASE = dict(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)


@pytest.mark.parametrize("term", schema.NONCONSERVATIVE_NAMES)
def test_each_loss_or_torque_makes_a_model_nonconservative(term):
    p = Parameters(**BASE, **{term: 0.1})
    assert not p.conservative and p.nonconservative_terms == (term,)
    assert p.dissipative == (schema.field(term).role != "torque")


def test_rotor_inertia_and_symbolic_terms():
    assert Parameters(**BASE, Ir=1e-4, gr=-6.0).conservative  # stores energy, loses none
    assert not Parameters(**BASE, c1=None).conservative  # symbolic: not known to vanish
    assert Parameters(**BASE).conservative


def test_poincare_refuses_coulomb_friction():
    """The section needs E = T + Pi constant; before the schema the check ignored cf1, cf2."""
    with pytest.raises(ParameterError, match=r"needs a conservative model .* cf1 = 0.05; set cf1 to 0"):
        skewpend.poincare(Parameters(**BASE, cf1=0.05), energy=-5.0)


# -- the facade's names are aliases of the links' fields (issue 52) ----------------------------------------------
def test_every_facade_name_is_a_link_field_or_the_chains():
    """Each of the double pendulum's names (``a``, ``m1``, ``alpha``, ``com2``, ``Ir``, ...) names one field of the
    chain's links (and the link: 1 or 2, or every link's for the one rotor and gear), or a field of the chain
    itself (``g``, ``cfs``): the facade adds no quantity of its own, and the link fields keep their names."""
    from skewpend.schema import CHAIN_NAMES, LINK_KEYS, NAMES, link_field_of

    assert LINK_KEYS == ("axis", "offset", "length", "mass", "com", "inertia", "damping", "coulomb", "torque",
                         "rotor", "gear")
    for name in NAMES:
        alias = link_field_of(name)
        if name in CHAIN_NAMES:
            assert alias is None, name
            continue
        assert alias is not None, f"{name} is neither a link field nor the chain's"
        key, i = alias
        assert key in LINK_KEYS and i in (1, 2, None), (name, alias)
    assert [link_field_of(n) for n in ("a", "b", "m2", "alpha", "axis1", "c1", "tau2", "cf1", "com2", "inertia1", "Ir", "gr")] == [
        ("length", 1), ("length", 2), ("mass", 2), ("axis", 2), ("axis", 1), ("damping", 1), ("torque", 2),
        ("coulomb", 1), ("com", 2), ("inertia", 1), ("rotor", None), ("gear", None)]


def test_a_facade_name_beside_a_chain_names_the_link_field(tmp_path):
    """``--m1`` beside ``--links 3`` is one line naming the link field to use (exit 2, nothing written)."""
    import subprocess
    import sys

    for flag, want in (("--m1=2", "give link 1's mass as --link-mass"), ("--alpha=10deg", "give link 2's axis"),
                       ("--Ir=1e-4", "give each link's rotor as --link-rotor")):
        proc = subprocess.run([sys.executable, "-m", "skewpend", "simulate", "--links", "3", flag, "--t-end", "1",
                               "--out", str(tmp_path / "t.csv")], capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2, proc.stderr
        last = proc.stderr.strip().splitlines()[-1]
        assert last.startswith(f"skewpend: error: {flag.split('=')[0]}:") and want in last, last
        assert "Traceback" not in proc.stderr
    assert list(tmp_path.iterdir()) == []
