"""Coulomb friction in the linear analyses (no SymPy here: the analyses import it freely).

The model's Coulomb friction ``cf_i atan(cfs q_i')`` smooths ``cf_i sign(q_i')``.  A sign has no
derivative at rest: the smoothed slope ``cf_i cfs`` at ``q' = 0`` is an artefact of the smoothing
(with the DFKI lab's ``cfs = 100`` it is a viscous damping 100 x ``cf``, far above the joints' own
``c``).  So every linearisation -- normal modes, the equilibria's stability, the LQR's
``A``, ``derive --linear`` -- leaves it out by default (``coulomb="exclude"``) and says so;
``coulomb="smoothed"`` adds the slope as viscous damping ``C0 += diag(cf1 cfs, cf2 cfs)``.
"""

from __future__ import annotations

from typing import Tuple

__all__ = ["COULOMB", "DEFAULT_COULOMB", "check_coulomb", "friction_terms", "coulomb_note"]

#: How a linearisation treats Coulomb friction: left out (non-smooth at rest) or by its smoothed slope.
COULOMB = ("exclude", "smoothed")
DEFAULT_COULOMB = "exclude"


def check_coulomb(coulomb, name: str = "coulomb") -> str:
    """``coulomb`` if it is one of :data:`COULOMB`, else one :class:`~skewpend.errors.ParameterError`."""
    from ..errors import ParameterError

    if not isinstance(coulomb, str) or coulomb not in COULOMB:
        raise ParameterError(f"{name} must be 'exclude' (Coulomb friction left out of the linearisation: non-smooth at "
                             f"rest) or 'smoothed' (its smoothed slope cfs*cf as viscous damping), got {coulomb!r}",
                             parameter=name)
    return coulomb


def friction_terms(params) -> Tuple[str, ...]:
    """The Coulomb friction parameters that enter the model (``cf1``, ``cf2``: non-zero or symbolic; a
    chain's joints with friction, ``cf1`` ... ``cfn``)."""
    cf = [(f"cf{i}", _coulomb_value(params, f"cf{i}")) for i in range(1, params.n + 1)]
    return tuple(name for name, value in cf if value is None or value != 0)


def _coulomb_value(params, name: str):
    """Joint ``cfK``'s Coulomb friction amplitude (None: symbolic), by the model's own name for it."""
    return params.value(name)


def _slopes(params, names) -> str:
    """``cfs*cf`` of each term, numerically where the model is numeric."""
    cfs = params.cfs
    values = [None if (cfs is None or _coulomb_value(params, n) is None) else float(cfs) * float(_coulomb_value(params, n))
              for n in names]
    if any(v is None for v in values):
        return "cfs*" + ", cfs*".join(names)
    return "cfs*cf = " + ", ".join(f"{v:.4g}" for v in values) + " N m s"


def coulomb_note(params, coulomb: str = DEFAULT_COULOMB, option: str = "coulomb='smoothed' (--coulomb smoothed)") -> str:
    """One line saying how a linearisation treated the model's Coulomb friction ('' without any).

    ``option`` is how the other choice is spelled in the interface in use (the CLI: ``--coulomb
    smoothed``; it is named only with ``"exclude"``)."""
    names = friction_terms(params)
    if not names:
        return ""
    which = ", ".join(names)
    if coulomb == "smoothed":
        return (f"Coulomb friction {which} linearised by its smoothed slope: viscous damping {_slopes(params, names)} "
                "added to C (the slope of atan(cfs q') at rest)")
    return (f"Coulomb friction {which} excluded from the linearisation (non-smooth at rest; its smoothed slope would "
            f"act as viscous damping {_slopes(params, names)}; {option} includes it)")
