"""The checks of a model's values, shared by the chain of links (:mod:`.chain`) and the double pendulum's
facade (:mod:`.model`): real numbers within what the equations can square, three-vectors, inertia tensors
(symmetric, positive semi-definite, the triangle inequality of their principal moments) and the symbol
names the facade may keep symbolic.  Imports nothing heavy."""

from __future__ import annotations

import math
import numbers
from typing import Any, Optional, Tuple

from ..errors import ParameterError

__all__ = ["Scalar", "Vec3", "Mat3", "MAX_MAGNITUDE", "MAX_INERTIA", "RESERVED_NAMES", "as_real", "as_vector",
           "as_matrix", "as_entry", "check_inertia", "is_numeric", "symbol_names", "SYMBOLIC_WORDS"]

Scalar = Optional[float]
Vec3 = Tuple[float, float, float]
Mat3 = Tuple[Vec3, Vec3, Vec3]

def as_real(name: str, value: Any, limit: float = None) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be a real number or None (symbolic), got {value!r}")
    x = float(value)
    if not math.isfinite(x):
        raise ParameterError(f"{name} must be finite, got {x}")
    limit = MAX_MAGNITUDE if limit is None else limit
    if abs(x) > limit:
        raise ParameterError(
            f"{name} must be at most {limit:g} in magnitude (SI units; larger values overflow the equations), got {x:g}"
        )
    return x


#: Largest magnitude of a numeric scalar parameter, centre-of-mass or axis entry: squares and
#: products of a few of them must stay far from the float64 overflow at 1.8e308.  Inertia
#: entries (mass times length squared: a thin rod of the largest mass and length) go to 1e300.
MAX_MAGNITUDE = 1e100
MAX_INERTIA = 1e300


#: Names a symbolic geometry entry may not take (coordinates and internal stand-ins).
RESERVED_NAMES = frozenset({"alpha", "phi", "psi", "dphi", "dpsi", "ddphi", "ddpsi", "omega", "lam", "t",
                            "atan_dphi", "atan_dpsi"})
SYMBOLIC_WORDS = ("sym", "symbolic")


def as_entry(name: str, value: Any):
    """A geometry entry: a real number, or a symbol name (an identifier) left symbolic."""
    if isinstance(value, str):
        text = value.strip()
        if not text.isidentifier() or text in RESERVED_NAMES or text.startswith(("c_", "s_")):
            raise ParameterError(
                f"{name} must be a real number or a symbol name (an identifier, not one of "
                f"{sorted(RESERVED_NAMES)} and not starting with c_ or s_), got {value!r}"
            )
        return text
    return as_real(name, value, MAX_INERTIA if "inertia" in name else None)  # a link's "link 1 inertia[0][0]" too


def as_vector(name: str, value: Any, default_names: Optional[Tuple[str, str, str]] = None) -> Vec3:
    if isinstance(value, str) and value.strip().lower() in SYMBOLIC_WORDS and default_names:
        return default_names  # type: ignore[return-value]
    try:
        items = list(value)
    except TypeError:
        raise ParameterError(f"{name} must be a sequence of 3 real numbers or symbol names, got {value!r}") from None
    if len(items) != 3:
        raise ParameterError(f"{name} must have 3 components, got {len(items)}")
    return tuple(as_entry(f"{name}[{i}]", v) for i, v in enumerate(items))  # type: ignore[return-value]


def as_matrix(name: str, value: Any, prefix: str = "") -> Mat3:
    if isinstance(value, str) and value.strip().lower() in SYMBOLIC_WORDS:
        n = lambda i, j: f"{prefix}{'xyz'[min(i, j)]}{'xyz'[max(i, j)]}"  # noqa: E731
        return tuple(tuple(n(i, j) for j in range(3)) for i in range(3))  # type: ignore[return-value]
    try:
        rows = list(value)
    except TypeError:
        raise ParameterError(f"{name} must be a 3x3 matrix of real numbers or symbol names, got {value!r}") from None
    if len(rows) != 3:
        raise ParameterError(f"{name} must be a 3x3 matrix, got {len(rows)} rows")
    mat = tuple(as_vector(f"{name}[{i}]", r) for i, r in enumerate(rows))
    for i in range(3):
        for j in range(i):
            if isinstance(mat[i][j], str) or isinstance(mat[j][i], str):
                if mat[i][j] != mat[j][i]:
                    raise ParameterError(f"{name} must be symmetric, got {name}[{i}][{j}] = {mat[i][j]!r} "
                                         f"but {name}[{j}][{i}] = {mat[j][i]!r}")
    return mat  # type: ignore[return-value]


def is_numeric(entries) -> bool:
    flat = [x for row in entries for x in (row if isinstance(row, tuple) else (row,))]
    return not any(isinstance(x, str) for x in flat)


def symbol_names(entries) -> Tuple[str, ...]:
    flat = [x for row in entries for x in (row if isinstance(row, tuple) else (row,))]
    out: list = []
    for x in flat:
        if isinstance(x, str) and x not in out:
            out.append(x)
    return tuple(out)


def check_inertia(name: str, mat: Mat3) -> None:
    """An inertia tensor about the centre of mass: symmetric, PSD, triangle inequality."""
    import numpy as np

    m = np.array(mat, dtype=float)
    scale = max(float(np.abs(m).max()), 1e-300)
    tol = 1e-9 * scale
    if not np.allclose(m, m.T, rtol=0.0, atol=tol):
        raise ParameterError(f"{name} must be symmetric, got {mat}")
    lam = np.linalg.eigvalsh(0.5 * (m + m.T))
    if lam.min() < -tol:
        raise ParameterError(
            f"{name} must be positive semi-definite; its principal moments are [{', '.join(f'{x:.4g}' for x in lam)}]"
        )
    for i in range(3):
        if lam[i] > lam[(i + 1) % 3] + lam[(i + 2) % 3] + tol:
            raise ParameterError(
                f"{name} breaks the triangle inequality of principal moments "
                f"(each at most the sum of the other two): [{', '.join(f'{x:.4g}' for x in lam)}]"
            )
