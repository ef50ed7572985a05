"""The SymPy symbols of every derived expression, by name (shared by the derivation and its renderers)."""

from __future__ import annotations

from typing import Dict

import sympy as sp

from ..schema import SCALAR_NAMES, field

#: SymPy's assumptions of each bound of the schema.
_ASSUMPTIONS = {"positive": dict(positive=True), "nonnegative": dict(nonnegative=True), "real": dict(real=True),
                "angle": dict(real=True)}

#: The symbols used in derived expressions, by name: the scalar parameters, the
#: coordinates ``phi, psi``, the speeds ``dphi, dpsi`` and the accelerations ``ddphi, ddpsi``.
SYMBOLS: Dict[str, sp.Symbol] = {n: sp.Symbol(n, **_ASSUMPTIONS[field(n).bound]) for n in SCALAR_NAMES}
SYMBOLS.update({n: sp.Symbol(n, real=True) for n in ("phi", "psi", "dphi", "dpsi", "ddphi", "ddpsi")})
