"""The views' and the command line's parameter lists and texts come from the schema (issue 37): a
model with Coulomb friction and rotors shows those terms in its texts (the figures' and
animations' titles, the report's table, the derivation's forces); a model with cf1 > 0 and nothing
else non-conservative is not called conservative (the report skips its energy-surface analyses and
says which terms); the explorer refuses the terms it cannot show instead of ignoring them; the
model's options are the schema's, in its order.  The expected texts are typed here from the
specification of each term (its unit, its meaning), not produced by the code under test."""

from __future__ import annotations

import html
import re
from types import SimpleNamespace


from skewpend import Parameters
from skewpend import schema

REFERENCE = dict(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
#: A model with both optional terms, every one of their parameters away from its default.
FRICTION_ROTOR = dict(REFERENCE, cf1=0.12, cf2=0.05, cfs=50.0, Ir=2e-4, gr=-30.0)
#: Coulomb friction in hinge 1 and nothing else non-conservative (no damping, no torques).
FRICTION_ONLY = dict(REFERENCE, cf1=0.1)


def _text(markup: str) -> str:
    return html.unescape(re.sub(r"<[^>]+>", "", markup))


def test_parameter_text_shows_friction_and_rotors():
    from skewpend.views.style import parameter_text

    text = parameter_text(Parameters(**FRICTION_ROTOR))
    for part in ("cf1 = 0.12 N m", "cf2 = 0.05 N m", "cfs = 50 s/rad", "Ir = 0.0002 kg m²", "gr = -30"):
        assert part in text, (part, text)
    titled = parameter_text(Parameters(**FRICTION_ROTOR), symbols=True)
    assert "cf₁ = 0.12 N m" in titled and "Iᵣ = 0.0002 kg m²" in titled and "gᵣ = -30" in titled
    plain = parameter_text(Parameters(**REFERENCE))
    assert plain == "a = 1 m, b = 0.8 m, m1 = 1 kg, m2 = 0.7 kg, alpha = 34.38°, g = 9.81 m/s²"


def test_parameter_text_shows_only_the_terms_away_from_their_defaults():
    from skewpend.views.style import parameter_text

    text = parameter_text(Parameters(**FRICTION_ONLY))
    assert text.endswith("g = 9.81 m/s², cf1 = 0.1 N m")  # cf2 = 0, cfs = 100, Ir = 0, gr = 1: the defaults


def _table(params):
    from skewpend.views.report.system import _parameter_rows  # noqa: PLC2701 (a test reads the table's rows)

    rows = _parameter_rows(params)
    return {re.sub(r"</?code>", "", r[1]): (_text(r[2]), _text(r[3]), _text(r[4])) for r in rows}


def test_report_table_has_friction_and_rotor_rows_when_the_model_has_them():
    rows = _table(Parameters(**FRICTION_ROTOR))
    assert rows["cf1"] == ("Coulomb friction in hinge 1", "0.12", "N m")
    assert rows["cf2"] == ("Coulomb friction in hinge 2", "0.05", "N m")
    assert rows["cfs"][1:] == ("50", "s/rad")
    assert rows["Ir"] == ("rotor inertia of each geared motor", "0.0002", "kg m²")
    assert rows["gr"] == ("gear ratio of the motors", "−30", "")  # a ratio: no unit
    # the core, damping and torques always; the geometry with its defaults
    for name in ("a", "b", "m1", "m2", "alpha", "g", "c1", "c2", "tau1", "tau2", "com1", "inertia2", "axis2"):
        assert name in rows, name
    assert rows["c1"] == ("viscous damping in hinge 1", "0", "N m s")


def test_report_table_leaves_out_terms_the_model_does_not_have():
    rows = _table(Parameters(**REFERENCE))
    assert not {"cf1", "cf2", "cfs", "Ir", "gr"} & set(rows)
    rows = _table(Parameters(**FRICTION_ONLY))
    assert {"cf1", "cf2", "cfs"} <= set(rows) and not {"Ir", "gr"} & set(rows)
    assert rows["cf2"][1] == "0" and rows["cfs"][1] == "100"  # the friction's whole law, at its defaults


def test_friction_alone_makes_the_report_call_the_model_not_conservative():
    from skewpend.views.report.system import conservation_text

    p = Parameters(**FRICTION_ONLY)
    assert not p.conservative and p.nonconservative_terms == ("cf1",)
    text = _text(conservation_text(p))
    assert "Not conservative" in text and "Coulomb friction in hinge 1" in text and "conserved" not in text
    assert "is conserved" in _text(conservation_text(Parameters(**REFERENCE)))
    rotor = Parameters(**dict(REFERENCE, Ir=1e-4, gr=3.0))  # the rotors store energy, lose none
    assert "is conserved" in _text(conservation_text(rotor))


def test_report_skips_the_energy_surface_analyses_for_friction():
    """Section 7's Poincare sections, map and diagram are not even started for a model with Coulomb
    friction (they were, before: only damping and torques were looked at)."""
    from skewpend.views import report as R

    assert R.chaos_jobs(SimpleNamespace(params=Parameters(**FRICTION_ONLY))) == {}
    assert R.chaos_jobs(SimpleNamespace(params=Parameters(**dict(REFERENCE, tau2=0.3)))) == {}


def test_derivation_shows_the_friction_in_the_generalised_forces():
    from skewpend.views.report.derivation import forces_text

    friction = forces_text(Parameters(**FRICTION_ONLY))
    assert r"\arctan(c_{fs}" in friction and "Coulomb friction" in friction and "c_i" not in friction
    both = forces_text(Parameters(**dict(REFERENCE, c2=0.1, tau1=0.2, cf2=0.1)))
    assert both.startswith(r"$Q_i = \tau_i - c_i\,\dot q_i - c_{fi}\arctan")
    assert forces_text(Parameters(**REFERENCE)).startswith("$Q_i = 0$")
    assert forces_text(Parameters(**dict(REFERENCE, Ir=1e-4))).startswith("$Q_i = 0$")  # rotors enter T, not Q


def test_model_options_are_the_schemas_in_its_order():
    from skewpend.cli import _group

    for command in ("simulate", "report", "derive", "flipmap"):
        params = [p for p in _group().commands[command].params if p.name in schema.NAMES]
        assert [p.name for p in params] == list(schema.SCALAR_NAMES + schema.GEOMETRY_NAMES), command
        assert all(p.opts == [f"--{p.name}"] for p in params), command
    helps = {p.name: p.help for p in _group().commands["simulate"].params}
    assert helps["cf2"] == "Coulomb friction in hinge 2 [N m]: torque -cf2 atan(cfs dpsi), at most cf2 pi/2 (default 0)"
    assert helps["a"] == "length of rod 1 [m] (default 1)"  # the reference case's value, added by show_defaults
    assert helps["inertia1"].startswith("inertia of body 1 about its centre of mass: 'Ixx,Iyy,Izz[,Ixy,Ixz,Iyz]' [kg m^2]")
    assert helps["com2"].endswith("(default the specification's thin rod)")
    modes = [p.name for p in _group().commands["modes"].params if p.name in schema.NAMES]
    assert not set(schema.TORQUE_NAMES) & set(modes) and set(schema.FRICTION_NAMES) <= set(modes)
