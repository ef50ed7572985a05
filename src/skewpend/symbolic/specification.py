"""The specification's planar case (``alpha = 0``), typed once from its text, and its check.

The specification (a theoretical-mechanics course page; docs/theory/method.md sets it out) derives the equations of the double pendulum with
skewed hinges and, as its check, writes out the planar case ``alpha = 0`` by hand. This module
is the one transcription of those formulas in the project (the report shows them, the tests
and the report compare the derivation with them); nothing here is computed by the derivation.

From the specification's second half (its notation: ``e0 = cos(alpha) k + sin(alpha) i``,
``j`` down, thin rods of lengths ``a``, ``b`` and masses ``m1``, ``m2``):

* ``e`` -- the second hinge's axis: ``e = P1 . e0 = k`` at ``alpha = 0``;
* ``P`` -- the rotation of rod 2, ``P = P2(psi, e) . P1 = P(phi + psi, k)``;
* ``omega2`` -- its angular velocity ``(phi' + psi') k``;
* ``v2`` -- the squared speed of its centre of mass,
  ``b^2/4 (phi' + psi')^2 + a b cos(psi) (phi' + psi') phi' + a^2 phi'^2``;
* ``T`` -- the kinetic energy ``T1 + T2``;
* ``Pi`` -- the potential energy ``Pi1 + Pi2`` (its zero: rod 1 hanging, rod 2's centre at
  ``b/2`` above its lowest point, so it exceeds skewpend's -- zero with both rods hanging -- by
  the constant :func:`zero_level` ``= m2 g b / 2``);
* ``M0``, ``K0`` -- the linearised equations ``M0 q'' + K0 q = 0`` (no damping).

:func:`check_planar` compares the derivation at ``alpha = 0`` with each of these and returns
the differences simplified by SymPy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, List, Optional, Tuple

__all__ = ["planar_formulas", "planar_latex", "zero_level", "Comparison", "check_planar"]


def _symbols() -> Tuple[Any, ...]:
    from ..schema import LENGTH_NAMES, MASS_NAMES
    from .symbols import SYMBOLS as S

    return tuple(S[n] for n in LENGTH_NAMES + MASS_NAMES + ("g", "phi", "psi", "dphi", "dpsi"))


def planar_formulas() -> Dict[str, Any]:
    """The specification's planar formulas as SymPy expressions (keys ``e``, ``P``, ``omega2``,
    ``v2``, ``T``, ``Pi``, ``M0``, ``K0``), in the symbols of :data:`skewpend.SYMBOLS`."""
    import sympy as sp

    a, b, m1, m2, g, phi, psi, dphi, dpsi = _symbols()
    half = sp.Rational(1, 2)
    T1 = half * m1 * a**2 / 3 * dphi**2
    T2 = half * (m2 * b**2 / 3 * (dphi + dpsi) ** 2 + m2 * a * b * sp.cos(psi) * (dphi + dpsi) * dphi + m2 * a**2 * dphi**2)
    Pi1 = m1 * g * (a / 2 - a / 2 * sp.cos(phi))
    Pi2 = m2 * g * (a * (1 - sp.cos(phi)) + b / 2 * (2 + sp.sin(phi) * sp.sin(psi) - sp.cos(phi) * sp.cos(psi)))
    u = phi + psi
    return {
        "e": sp.Matrix([0, 0, 1]),
        "P": sp.Matrix([[sp.cos(u), -sp.sin(u), 0], [sp.sin(u), sp.cos(u), 0], [0, 0, 1]]),
        "omega2": sp.Matrix([0, 0, dphi + dpsi]),
        "v2": b**2 / 4 * (dphi + dpsi) ** 2 + a * b * sp.cos(psi) * (dphi + dpsi) * dphi + a**2 * dphi**2,
        "T": T1 + T2,
        "Pi": Pi1 + Pi2,
        "M0": sp.Matrix([
            [m1 * a**2 / 3 + m2 * b**2 / 3 + m2 * a * (a + b), m2 * b**2 / 3 + m2 * a * b / 2],
            [m2 * b**2 / 3 + m2 * a * b / 2, m2 * b**2 / 3],
        ]),
        "K0": sp.Matrix([
            [g / 2 * ((m1 + 2 * m2) * a + m2 * b), g / 2 * m2 * b],
            [g / 2 * m2 * b, g / 2 * m2 * b],
        ]),
    }


def planar_latex() -> Dict[str, str]:
    """The same formulas in the specification's own LaTeX (its Russian half; ``\\dot{}`` as
    there), keys as :func:`planar_formulas` with ``linear`` for the pair of linear equations."""
    return {
        "e": r"\underline{e}_0 = \cos(\alpha) \underline{k} + \sin(\alpha) \underline{i} = \underline{k}, \qquad "
             r"\underline{e} = \underline{\underline {P}}_1 \cdot \underline{e}_0 = \underline{k}",
        "P": r"\underline{\underline{P}}_2(\psi,\underline{e})= \underline{\underline{P}}_2(\psi,\underline{k}), \qquad "
             r"\underline{\underline{P}} = \underline{\underline{P}}_2 \cdot \underline{\underline{P}}_1"
             r" = \underline{\underline{P}}(\varphi + \psi, \underline{k})",
        "omega2": r"\underline{\omega}_2 = (\dot{\varphi}+\dot{\psi})\underline{k}",
        "v2": r"\upsilon^2_c = \frac{1}{4} b^2 (\dot{\varphi}+\dot{\psi})^2 + ab\cos\psi(\dot{\varphi}+\dot{\psi})\dot{\varphi} + a^2\dot{\varphi}^2",
        "T": r"T = \frac{1}{2}\frac{m_1 a^2}{3}\dot{\varphi}^2 + \frac{1}{2} \left( \frac{m_2 b^2}{3}(\dot{\varphi}+\dot{\psi})^2"
             r" + m_2 ab\cos\psi(\dot{\varphi}+\dot{\psi})\dot{\varphi} + m_2 a^2\dot{\varphi}^2 \right)",
        "Pi": r"\Pi = m_1 g \left( \frac{a}{2} - \frac{a}{2} \cos \varphi \right) + m_2 g \left[ a \left(1-\cos\varphi \right)"
              r" + \frac{b}{2}\left(2 + \sin\varphi\sin\psi - \cos\varphi\cos\psi \right) \right]",
        "linear": r"\begin{cases}"
                  r"\ddot{\varphi} \left( \frac{m_1 a^2}{3} + \frac{m_2 b^2}{3} + m_2 a (a+b) \right) + \ddot{\psi} \left( \frac{m_2 b^2}{3} + \frac{m_2 ab}{2} \right)"
                  r" + \varphi \frac{g}{2} \left((m_1+2m_2)a+m_2 b \right)+\psi \frac{g}{2}m_2 b = 0\\"
                  r"\ddot{\varphi} \left( \frac{m_2 b^2}{3} + \frac{m_2 ab}{2} \right) + \ddot{\psi} \frac{m_2 b^2}{3} + \varphi \frac{g}{2} m_2 b + \psi \frac{g}{2} m_2 b = 0"
                  r"\end{cases}",
    }


def zero_level():
    """``m2 g b / 2``: the specification's potential energy with both rods hanging (skewpend's is 0)."""
    a, b, m1, m2, g, *_ = _symbols()
    return m2 * g * b / 2


@dataclass(frozen=True)
class Comparison:
    """One quantity of the planar case: ``difference`` is skewpend's minus the specification's,
    simplified by SymPy; ``expected`` is what it must be (0, or the constant :func:`zero_level`
    with a minus sign for ``Pi``); ``identical`` says whether it is."""

    key: str
    title: str
    difference: Any
    expected: Any
    identical: bool


TITLES = {
    "e": "The second hinge's axis", "P": "Rotation of rod 2", "omega2": "Angular velocity of rod 2",
    "v2": "Speed of rod 2's centre of mass", "T": "Kinetic energy", "Pi": "Potential energy",
    "M0": "Mass matrix of the linearised equations", "K0": "Stiffness matrix of the linearised equations",
    "C0": "Damping matrix of the linearised equations",
}


def _simplified(expr):
    import sympy as sp

    return expr.applyfunc(sp.simplify) if isinstance(expr, sp.MatrixBase) else sp.simplify(expr)


def _is_zero(expr) -> bool:
    import sympy as sp

    return all(x == 0 for x in expr) if isinstance(expr, sp.MatrixBase) else expr == 0


def check_planar(eom=None) -> List[Comparison]:
    """The derivation at ``alpha = 0`` (``eom``, default ``derive(Parameters(alpha=0))``) against
    :func:`planar_formulas`, quantity by quantity, in the order of the specification; the
    linearisation's ``M0``, ``K0`` and ``C0`` (zero: the specification has no damping) last."""
    import sympy as sp

    from .derivation import derive
    from .model import Parameters

    if eom is None:
        eom = derive(Parameters(alpha=0.0))
    spec = planar_formulas()
    steps = eom.steps
    lin = eom.linearize()
    ours: Dict[str, Any] = {
        "e": steps["e"], "P": steps["P"], "omega2": steps["omega2"],
        "v2": sp.expand((steps["v_c"].T * steps["v_c"])[0, 0]),
        "T": eom.kinetic_energy, "Pi": eom.potential_energy, "M0": lin.M, "K0": lin.K, "C0": lin.C,
    }
    out = []
    for key in ("e", "P", "omega2", "v2", "T", "Pi", "M0", "K0", "C0"):
        theirs = spec.get(key, sp.zeros(2, 2))
        expected: Optional[Any] = -zero_level() if key == "Pi" else None
        difference = _simplified(ours[key] - theirs)
        identical = _is_zero(difference) if expected is None else sp.simplify(difference - expected) == 0
        out.append(Comparison(key=key, title=TITLES[key], difference=difference,
                              expected=expected if expected is not None else (0 * theirs), identical=bool(identical)))
    return out
