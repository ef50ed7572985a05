"""The quadratic eigenvalue problem of the linear modes: ``(l^2 M + l C + K) x = 0`` for 2 x 2
matrices, solved robustly (the characteristic quartic's roots polished by Newton's method on
the scaled matrix, the null vectors from the polished roots) and the four eigenvalues given to
the two undamped modes by their shapes.  Used by :mod:`skewpend.analysis.modes`."""

from __future__ import annotations

import itertools
from typing import List, Tuple

import numpy as np

from ..errors import ParameterError

__all__ = ["quadratic_eigen", "pair_by_shape", "NotFinite"]


class NotFinite(ParameterError):
    """A result of the modes is not a finite number (``reason`` is a short phrase); the modes
    turn it into one message naming the parameters."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def quadratic_eigen(M: np.ndarray, C: np.ndarray, K: np.ndarray, *, stable: bool = True) -> Tuple[np.ndarray, np.ndarray]:
    """The four state-space eigenvalues ``l`` -- the roots of ``det(l^2 M + l C + K) = 0`` --
    and the displacement parts ``x`` (2, 4) of the state-space eigenvectors ``[x; l x]``
    (unit length), i.e. the null vectors of ``l^2 M + l C + K``.

    Starting values are the roots of the quartic and the reciprocals of the roots of the
    reversed quartic (accurate for the large and for the small roots); each is polished by
    Newton steps on ``det Q(l)`` evaluated from the 2x2 matrix (scaled by ``1/l^2`` for
    ``|l| > 1``, so nothing overflows).  Unlike the eigenvalues of the 4x4 state matrix this
    keeps full relative accuracy when the damping spans many orders of magnitude (the slow
    creep ``~ k/c`` and fast decay ``~ c/m`` of heavy damping, a lightly damped mode beside
    an almost locked hinge).  Near a double root (critical damping) Newton does not
    converge and the quartic's roots are used as they are.  ``stable``: ``K`` is positive
    definite (every coefficient of the quartic is then positive, and a zero one is an underflow);
    about an unstable equilibrium only ``det M > 0`` is required.
    """

    def det(A: np.ndarray) -> float:
        return A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]

    def mixed(A: np.ndarray, B: np.ndarray) -> float:  # det(A + B) - det(A) - det(B)
        return A[0, 0] * B[1, 1] + A[1, 1] * B[0, 0] - A[0, 1] * B[1, 0] - A[1, 0] * B[0, 1]

    coefficients = np.array([det(M), mixed(M, C), mixed(M, K) + det(C), mixed(C, K), det(K)], dtype=float)
    positive = coefficients > 0 if stable else coefficients[:1] > 0
    if not np.all(np.isfinite(coefficients)) or not np.all(positive) or coefficients[-1] == 0:
        raise NotFinite("the characteristic polynomial det(l^2 M0 + l C0 + K0) is not finite (overflow)")
    big = np.roots(coefficients).astype(complex)
    small = 1.0 / np.roots(coefficients[::-1]).astype(complex)
    roots: List[complex] = []
    for z0 in np.concatenate([big, small]):
        if not np.isfinite(z0) or z0 == 0:
            continue
        z, converged = _newton(z0, M, C, K)
        if not converged:
            continue
        if abs(z.imag) <= 1e-14 * abs(z):
            z = complex(z.real, 0.0)
        z = complex(z.real, abs(z.imag))
        if not any(abs(z - r) <= 1e-10 * abs(r) for r in roots):
            roots.append(z)
    lam = np.array(roots + [np.conj(z) for z in roots if z.imag != 0])
    if lam.size != 4:  # a (near) double root: Newton converges slowly there
        lam = big
    if lam.size != 4 or not np.all(np.isfinite(lam)):
        raise NotFinite("the state-space eigenvalues are not finite (overflow)")
    return lam, _null_vectors(lam, M, C, K)


def _scaled_q(z: complex, M: np.ndarray, C: np.ndarray, K: np.ndarray):
    """``Q(z) = z^2 M + z C + K`` and ``dQ/dz``, both divided by ``z^2`` when ``|z| > 1``;
    with the power of ``z`` taken out (0 or 2)."""
    if abs(z) > 1:
        w = 1.0 / z
        return M + w * C + (w * w) * K, -(w * w) * C - (2 * w**3) * K, 2
    return (z * z) * M + z * C + K, (2 * z) * M + C, 0


def _newton(z0: complex, M: np.ndarray, C: np.ndarray, K: np.ndarray) -> Tuple[complex, bool]:
    """Newton's method on ``det Q(z) = 0`` from ``z0`` (a real start stays real): the root
    and whether the steps converged to machine precision."""
    real = z0.imag == 0
    z = complex(z0.real, 0.0) if real else complex(z0)
    for _ in range(40):
        Q, dQ, p = _scaled_q(z, M, C, K)
        f = Q[0, 0] * Q[1, 1] - Q[0, 1] * Q[1, 0]
        df = dQ[0, 0] * Q[1, 1] + Q[0, 0] * dQ[1, 1] - dQ[0, 1] * Q[1, 0] - Q[0, 1] * dQ[1, 0]
        if f == 0:
            return z, True
        # det Q = z^(2p) det Qs  =>  det Q / (det Q)' = det Qs / ((det Qs)' + 2p det Qs / z)
        step = f / (df + 2 * p * f / z)
        if not np.isfinite(step):
            return z, False
        if real:
            step = complex(step.real, 0.0)
        z -= step
        if abs(step) <= 4 * np.finfo(float).eps * abs(z):
            return z, True
    return z, False


def _null_vectors(lam: np.ndarray, M: np.ndarray, C: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Unit null vectors of the (scaled) 2x2 ``Q(l)``, one column per eigenvalue; a zero
    column where ``Q(l) ~ 0`` (a double eigenvalue shared by two shapes: no shape)."""
    X = np.zeros((2, lam.size), complex)
    nM, nC, nK = (np.abs(A).max() for A in (M, C, K))
    for k, z in enumerate(lam):
        Q, _, p = _scaled_q(z, M, C, K)
        a, b = np.array([-Q[0, 1], Q[0, 0]]), np.array([Q[1, 1], -Q[1, 0]])
        x = a if np.linalg.norm(a) >= np.linalg.norm(b) else b
        n = np.linalg.norm(x)
        if not np.isfinite(n):
            raise NotFinite("the state-space eigenvectors are not finite (overflow)")
        scale = nM + nC / abs(z) + nK / abs(z) ** 2 if p else abs(z) ** 2 * nM + abs(z) * nC + nK
        if n > 1e-10 * scale:
            X[:, k] = x / n
    return X


def pair_by_shape(lam: np.ndarray, X: np.ndarray, M: np.ndarray, V: np.ndarray) -> np.ndarray:
    """Split the four eigenvalues into a pair per undamped mode (rows), by shape similarity."""
    norm = np.sqrt(np.abs(np.einsum("ij,ik,kj->j", X.conj(), M, X).real))
    # S[k, j]: similarity of eigenvector j to undamped mode k (V is M0-normalised); neutral 1/2
    # for an eigenvalue whose shape is undetermined (x = 0, see _null_vectors)
    S = np.where(norm > 0, np.abs(V.T @ M @ X) / np.where(norm > 0, norm, 1.0), 0.5)

    def is_pair(i: int, j: int) -> bool:
        if lam[i].imag == 0 and lam[j].imag == 0:
            return True
        return lam[i].imag != 0 and abs(lam[i] - np.conj(lam[j])) <= 1e-12 * abs(lam[i])

    best, best_score = None, -np.inf
    for g1 in itertools.combinations(range(4), 2):
        g2 = tuple(j for j in range(4) if j not in g1)
        if not (is_pair(*g1) and is_pair(*g2)):
            continue
        score = S[0, list(g1)].sum() + S[1, list(g2)].sum()
        if score > best_score:
            best, best_score = (g1, g2), score
    if best is None:
        raise NotFinite("the state-space eigenvalues do not form conjugate or real pairs (numerical failure)")
    pairs = np.empty((2, 2), complex)
    for k, g in enumerate(best):
        z = lam[list(g)]
        if z[0].imag != 0:
            z = np.array([z[0].real + 1j * abs(z[0].imag), z[0].real - 1j * abs(z[0].imag)])
        else:
            z = z[np.argsort(np.abs(z))]
        pairs[k] = z
    return pairs
