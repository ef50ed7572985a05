"""Conventions shared by every generated numeric routine: the order of the state and of the
parameter array, and the split of a model into structure (what keys a compiled library) and
values (run-time inputs).

**Structure compiles, values are inputs** (:func:`structure_of`): the hinge axes, which entries of
each body's centre of mass and inertia tensor are zero, and whether the optional friction and
rotor terms exist at all key a compiled kernel; every scalar and every non-zero entry of the
bodies are read from the parameter array ``p`` (:data:`PARAMETER_ORDER`) at run time.  So a fit,
a sweep over a mass or an inertia, or a report of a new rig of the same structure compiles
nothing.  The specification's thin rods (no ``com``/``inertia`` given) keep their closed form
(``a/2``, ``m a^2/12``) in terms of the run-time ``a, b, m1, m2``.

The standalone exports and the explorer's JavaScript (:func:`geometry_of`) still carry a general
body's entries as numbers: their ``p`` is the scalars only (:data:`SCALAR_ORDER`)."""

from __future__ import annotations

from functools import lru_cache
from typing import Tuple

from ..schema import COM_NAMES, FRICTION_NAMES, GEOMETRY_NAMES, INERTIA_NAMES, ROTOR_NAMES, SCALAR_NAMES, sym_prefix
from ..symbolic.model import Parameters

__all__ = ["METHODS", "ADAPTIVE", "PARAMETER_ORDER", "SCALAR_ORDER", "BODY_ENTRIES", "TENSOR_ENTRIES", "TENSOR_INDICES", "STATE_ORDER", "GEOMETRY", "geometry_of",
           "structure_of", "optional_terms", "parameter_vector", "scalar_vector", "body_values"]

#: The integrators of ``simulate`` (here, where the command line's --help reads them without NumPy).
METHODS: Tuple[str, ...] = ("dop853", "rk4", "gauss", "taylor")
#: The methods that choose their own steps (rtol, atol); the others take a fixed step dt.
ADAPTIVE: Tuple[str, ...] = ("dop853", "taylor")
#: The entries of a symmetric tensor (the inertia) in the order of ``p``, and their (row, column).
TENSOR_ENTRIES: Tuple[str, ...] = ("xx", "xy", "xz", "yy", "yz", "zz")
TENSOR_INDICES: Tuple[Tuple[int, int], ...] = tuple(("xyz".index(e[0]), "xyz".index(e[1])) for e in TENSOR_ENTRIES)
#: The bodies' entries that compiled kernels read at run time: each body's centre of mass
#: (``r1x, r1y, r1z``, ...) and inertia tensor (``I1xx, I1xy, ...``), named as ``"sym"`` names them.
BODY_ENTRIES: Tuple[str, ...] = (tuple(f"{sym_prefix(n)}{x}" for n in COM_NAMES for x in "xyz")
                                 + tuple(f"{sym_prefix(n)}{ij}" for n in INERTIA_NAMES for ij in TENSOR_ENTRIES))
#: Order of the parameter array ``p`` of the compiled kernels: the scalars, then the bodies' entries.
PARAMETER_ORDER: Tuple[str, ...] = SCALAR_NAMES + BODY_ENTRIES
#: Order of the parameter array of the standalone exports and the explorer (bodies baked in).
SCALAR_ORDER: Tuple[str, ...] = SCALAR_NAMES
#: Order of the state ``y``.
STATE_ORDER: Tuple[str, ...] = ("phi", "psi", "dphi", "dpsi")
#: The bodies and axes: baked into generated code as numbers (or symbols).
GEOMETRY: Tuple[str, ...] = GEOMETRY_NAMES


def optional_terms(params: Parameters) -> Tuple[bool, bool]:
    """Which optional terms the compiled code of ``params`` holds: (Coulomb friction, rotor inertia)."""
    return params.has_friction, params.has_rotor


def _scalars_symbolic(params: Parameters, bodies: dict) -> Parameters:
    friction, rotor = optional_terms(params)
    off = {n: getattr(Parameters(), n) for n in FRICTION_NAMES * (not friction) + ROTOR_NAMES * (not rotor)}
    scalars = {k: None for k in SCALAR_NAMES if k not in off}
    geometry = {k: getattr(params, k) for k in GEOMETRY}
    geometry.update(bodies)
    return Parameters(**geometry, **scalars, **off)


def geometry_of(params: Parameters) -> Parameters:
    """The same bodies and axes with every scalar parameter symbolic (a runtime input): the
    model of the standalone exports and the explorer's JavaScript, which carry the bodies as numbers.

    The optional terms are structural: Coulomb friction (``cf1, cf2, cfs``) and the rotor inertia
    (``Ir, gr``) are runtime inputs when ``params`` has them (non-zero or symbolic), and are left
    out of the code otherwise -- so a model without them runs exactly today's code (bit for bit),
    and its ``p`` entries for them are not read.  Code for a model with friction reads any ``cf``,
    0 included."""
    return _scalars_symbolic(params, {})


def _pattern(name: str, value):
    """A numeric centre of mass or inertia tensor as its structure: each non-zero entry the symbol
    of :data:`BODY_ENTRIES` (read from ``p``), each zero entry 0; None (a thin rod) and symbolic
    entries stay as they are."""
    if value is None:
        return None
    prefix = sym_prefix(name)
    if name in COM_NAMES:
        return tuple(f"{prefix}{x}" if isinstance(v, str) or v != 0 else 0.0 for x, v in zip("xyz", value))
    return tuple(tuple(value[i][j] if isinstance(value[i][j], str) else
                       (f"{prefix}{'xyz'[min(i, j)]}{'xyz'[max(i, j)]}" if value[i][j] != 0 else 0.0)
                       for j in range(3)) for i in range(3))


def structure_of(params: Parameters, *, full: bool = False) -> Parameters:
    """What keys a compiled kernel: the hinge axes, which entries of each body are zero, whether the
    optional friction and rotor terms exist; every scalar and every non-zero body entry symbolic (read
    from ``p`` at run time, :data:`PARAMETER_ORDER`).  Two rigs of the same structure share one library.

    >>> import skewpend
    >>> from skewpend.numeric.conventions import structure_of
    >>> rig = skewpend.Parameters(a=0.3, b=0.2, m1=0.5, m2=0.6, alpha=0.0, g=9.81, com1=(0, 0.15, 0))
    >>> structure_of(rig).com1, structure_of(rig.replace(com1=(0, 0.12, 0))) == structure_of(rig)
    ((0.0, 'r1y', 0.0), True)

    ``full=True``: every entry of both bodies read from ``p`` whatever ``params`` holds (the
    library of identification, whose fits may move any entry; thin rods are then general bodies
    with the rods' values in ``p``)."""
    if full:  # every entry of every body read from p (identification: any body the fit may reach)
        bodies = {n: _pattern(n, ((1.0,) * 3 if n in COM_NAMES else ((1.0,) * 3,) * 3)) for n in COM_NAMES + INERTIA_NAMES}
    else:
        bodies = {n: _pattern(n, getattr(params, n)) for n in COM_NAMES + INERTIA_NAMES}
    return _scalars_symbolic(params, bodies)


def body_values(params: Parameters):
    """The bodies' entries of :data:`BODY_ENTRIES` (centres of mass, inertia tensors) as numbers:
    the given ones, or the thin rods' (``(0, l/2, 0)``, ``m l^2/12 (E - j j)``) where none is given."""
    from ..schema import LENGTH_NAMES, MASS_NAMES

    out = []
    for name, length, mass in zip(COM_NAMES, LENGTH_NAMES, MASS_NAMES):
        com = getattr(params, name)
        out += [float(x) for x in com] if com is not None else [0.0, 0.5 * float(getattr(params, length)), 0.0]
    for name, length, mass in zip(INERTIA_NAMES, LENGTH_NAMES, MASS_NAMES):
        J = getattr(params, name)
        if J is None:
            rod = float(getattr(params, mass)) * float(getattr(params, length)) ** 2 / 12.0
            J = ((rod, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, rod))
        out += [float(J[i][j]) for i, j in TENSOR_INDICES]
    return out


def scalar_vector(params: Parameters):
    """The scalars of :func:`parameter_vector` (:data:`SCALAR_ORDER`): ``p`` of the exports and the explorer."""
    import numpy as np

    params.require_numeric("numeric evaluation")
    return np.array([0.0 if (n == "alpha" and not params.uses_alpha) else float(getattr(params, n)) for n in SCALAR_NAMES])


def parameter_vector(params: Parameters):
    """The float64 parameter array ``p`` of the compiled kernels, in :data:`PARAMETER_ORDER`: the
    scalars (``alpha`` = 0 when unused), then the bodies' entries (:func:`body_values`)."""

    try:
        return _vector(params).copy()
    except TypeError:  # a model with an unhashable field: computed each time
        return _vector.__wrapped__(params)


@lru_cache(maxsize=256)
def _vector(params: Parameters):
    """:func:`parameter_vector`, kept for the models last used (callers get a copy): a simulation's
    Python path reads it at every call (about 1 us from here against 12 us to build it, a tenth of
    a short Taylor run's whole call)."""
    import numpy as np

    return np.concatenate([scalar_vector(params), body_values(params)])


#: Chains of up to this many links take the Taylor series with ``simulate``'s ``method="auto"``: their model as
#: polynomials (:mod:`skewpend.numeric.polynomial`) is small enough (three general links: 81.5 series products
#: an order, 0.24-0.28x heyoka.py's time at equal error, docs/benchmarks.md); each further link multiplies its terms.
SERIES_MAX_LINKS = 3
