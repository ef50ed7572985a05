"""The SymPy symbols of every derived expression, by name (shared by the derivation and its renderers)."""

from __future__ import annotations

from typing import Dict

import sympy as sp

from .model import SCALAR_NAMES

__all__ = ["SYMBOLS"]

_ASSUMPTIONS = {
    "a": dict(positive=True),
    "b": dict(positive=True),
    "m1": dict(positive=True),
    "m2": dict(positive=True),
    "alpha": dict(real=True),
    "g": dict(nonnegative=True),
    "c1": dict(nonnegative=True),
    "c2": dict(nonnegative=True),
    "tau1": dict(real=True),
    "tau2": dict(real=True),
    "cf1": dict(nonnegative=True),
    "cf2": dict(nonnegative=True),
    "cfs": dict(positive=True),
    "Ir": dict(nonnegative=True),
    "gr": dict(real=True),
}

#: The symbols used in derived expressions, by name: the scalar parameters, the
#: coordinates ``phi, psi``, the speeds ``dphi, dpsi`` and the accelerations ``ddphi, ddpsi``.
SYMBOLS: Dict[str, sp.Symbol] = {n: sp.Symbol(n, **_ASSUMPTIONS[n]) for n in SCALAR_NAMES}
SYMBOLS.update({n: sp.Symbol(n, real=True) for n in ("phi", "psi", "dphi", "dpsi", "ddphi", "ddpsi")})
