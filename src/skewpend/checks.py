"""The library's checks of its arguments, written once.

Every public function validates what it is given with these (and the CLI, config files and
the web API reach the same functions), so a rule -- what a tolerance may be, how many steps a
run may take, that ``progress`` is callable -- has one wording everywhere.  Messages name the
*parameter* (``max_steps``), never a command-line flag: the CLI maps names to flags.

The defaults that several computations share are here too: :data:`MAX_STEPS` and
:data:`DEFAULT_TOL`.
"""

from __future__ import annotations

import math
import numbers
from typing import Any, Callable, Optional, Tuple

from .errors import NotNumericError, ParameterError

__all__ = [
    "MAX_STEPS", "MAX_STEPS_LIMIT", "DEFAULT_TOL", "RTOL_MIN", "ATOL_MIN", "numeric_params", "tolerances", "max_steps", "whole", "positive",
    "progress_callable", "flag", "finite_seconds", "angle", "angles", "ANGLE_LIMIT", "real_sequence",
]

#: Default cap on the attempted steps (accepted + rejected) of one trajectory.
MAX_STEPS = 100_000_000
#: The largest cap a caller may ask for.
MAX_STEPS_LIMIT = 10**15
#: Default relative and absolute tolerance of the adaptive integrators.
DEFAULT_TOL = 1e-10
#: The smallest tolerances: rtol at machine precision, atol far below any state's scale.
RTOL_MIN, ATOL_MIN = 1e-15, 1e-300


def not_parameters(params, what: str) -> str:
    """The one line for a model that ``what`` cannot compute: it computes models of two links the double
    pendulum's parameters hold (the specification's derivation), and says what the model is instead."""
    if hasattr(params, "exact_model"):
        return (f"{what} computes the double pendulum's Parameters, not {params.title} (two links the double "
                "pendulum's parameters hold: hinge 2 on rod 1's end, one rotor for both joints)")
    return f"params must be a skewpend.Parameters, got {type(params).__name__}"


def numeric_params(params, what: str):
    """The double pendulum's :class:`~skewpend.Parameters` of ``params`` -- itself, or a chain of two that they
    hold (:meth:`exact_model`: the chain of two *is* the double pendulum) -- with every value numeric
    (``what`` needs them: "a flip time", ...), else a :class:`ParameterError`."""
    exact = params.exact_model() if hasattr(params, "exact_model") else None
    if exact is None:
        raise ParameterError(not_parameters(params, what))
    try:
        exact.require_numeric(what)
    except NotNumericError as exc:
        raise ParameterError(str(exc)) from None
    return exact


def numeric_model(params, what: str):
    """``params`` if it is a model -- a chain of links or the double pendulum's :class:`~skewpend.Parameters`
    (anything answering ``as_chain``) -- with every value numeric (``what`` needs them), else one
    :class:`ParameterError`."""
    if not hasattr(params, "as_chain") or not hasattr(params, "require_numeric"):
        raise ParameterError(f"params must be a skewpend.Parameters or a Chain, got {type(params).__name__}")
    try:
        return params.require_numeric(what)
    except NotNumericError as exc:
        raise ParameterError(str(exc)) from None


def positive(name: str, value: Any, *, cap: Optional[float] = None) -> float:
    """``value`` as a finite float > 0, not subnormal (at least 2.2e-308, which the compiled code
    may flush to 0), and at most ``cap``."""
    from .parsing import positive_number

    x = positive_number(name, value)
    assert x is not None  # None only with allow_none
    if cap is not None and x > cap:
        raise ParameterError(f"{name} must be at most {cap:g}, got {x:g}")
    return x


def tolerances(rtol, atol, *, default: float = DEFAULT_TOL) -> Tuple[float, float]:
    """``(rtol, atol)``: each a positive number (None: ``default``), rtol from 1e-15 (machine
    precision) to 1, atol from 1e-300 to 1."""
    rtol = default if rtol is None else positive("rtol", rtol)
    atol = default if atol is None else positive("atol", atol)
    if not (RTOL_MIN <= rtol <= 1.0 and ATOL_MIN <= atol <= 1.0):
        raise ParameterError(f"rtol must be from 1e-15 (machine precision) to 1 and atol from 1e-300 to 1, got "
                             f"rtol={rtol:g}, atol={atol:g}")
    return rtol, atol


def whole(name: str, value: Any, lo: int, hi: int, *, what: str = "") -> int:
    """``value`` as an int from ``lo`` to ``hi`` (a bool, a float or a string is refused)."""
    unit = f" ({what})" if what else ""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):  # NumPy's integers too
        raise ParameterError(f"{name} must be a whole number from {lo:g} to {hi:g}{unit}, got {value!r}")
    n = int(value)
    if not lo <= n <= hi:
        digits = str(n)
        shown = digits if len(digits) <= 20 else f"{digits[:12]}... ({len(digits.lstrip('-'))} digits)"
        raise ParameterError(f"{name} must be a whole number from {lo:g} to {hi:g}{unit}, got {shown}")
    return n


def max_steps(value) -> int:
    """A cap on the attempted steps of one trajectory: a whole number from 1 to 1e15."""
    return whole("max_steps", value, 1, MAX_STEPS_LIMIT)


def progress_callable(progress, signature: str = "progress(done, total)") -> Optional[Callable]:
    """``progress`` if it is None or callable."""
    if progress is not None and not callable(progress):
        raise ParameterError(f"progress must be a callable {signature}")
    return progress


def flag(name: str) -> str:
    """The command-line flag of a parameter name: ``max_steps`` -> ``--max-steps``."""
    return "--" + name.replace("_", "-")


def finite_seconds(name: str, value: Any, *, zero: bool = True) -> float:
    """A duration [s]: a finite number >= 0 (> 0 unless ``zero``)."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number of seconds, got {value!r}") from None
    if isinstance(value, bool) or not math.isfinite(x) or x < 0 or (x == 0 and not zero):
        raise ParameterError(f"{name} must be a number of seconds {'>=' if zero else '>'} 0, got {value!r}")
    return x


#: The largest angle [rad] that is reduced modulo 2 pi: its double's spacing (1.2e-10 rad at 1e6)
#: keeps the reduced angle to better than 1e-9 rad; beyond it a reduction would invent digits
#: (the parsers' :data:`skewpend.parsing.MAX_ANGLE`, one bound).
from .parsing import MAX_ANGLE as ANGLE_LIMIT  # noqa: E402


def angle(name: str, value: Any) -> float:
    """An angle [rad] reduced modulo 2 pi into (-pi, pi] (to the double nearest the exact
    reduction): a finite real number (NumPy's scalars too) of magnitude at most
    :data:`ANGLE_LIMIT`, where the reduction keeps its meaning."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{name} must be an angle in radians (a real number), got {value!r}")
    x = float(value)
    if not math.isfinite(x) or abs(x) > ANGLE_LIMIT:
        raise ParameterError(f"{name} must be a finite angle of at most {ANGLE_LIMIT:g} rad in magnitude (it is "
                             f"reduced modulo 2 pi, which beyond that loses its digits), got {x:g}")
    if -math.pi < x <= math.pi:
        return x
    # reduced against 2 pi to 40 digits (the double 2*math.pi is 2.4e-16 short, which 1.6e5 turns
    # would make 4e-11 rad): the result is the double nearest the true reduction
    from decimal import Decimal, localcontext

    with localcontext() as ctx:
        ctx.prec = 60
        exact = Decimal(x)
        w = float(exact - round(exact / _TWO_PI) * _TWO_PI)
    return math.pi if w <= -math.pi else w


_TWO_PI = __import__("decimal").Decimal("6.283185307179586476925286766559005768394338798750211641949889")


def angles(name: str, values: Any, n: int) -> Tuple[float, ...]:
    """``n`` angles (a sequence or array of real numbers), each as :func:`angle` makes it."""
    try:
        items = [v.item() if hasattr(v, "item") else v for v in list(values)]
    except (TypeError, ValueError):  # not iterable, or an item an array of several numbers
        raise ParameterError(f"{name} must be {n} angles in radians, got {values!r}") from None
    if len(items) != n:
        raise ParameterError(f"{name} must be {n} angles in radians, got {len(items)} values")
    return tuple(angle(f"{name}[{i}]", v) for i, v in enumerate(items))


def real_sequence(name: str, value: Any) -> None:
    """Refuse what NumPy would convert with a loss or a reshape: a sequence of real numbers in one row
    (a state ``y0``), not complex numbers (their imaginary part would be dropped with a warning only),
    booleans or text, and not a 2-D array (flattened, its layout guessed).  The count and finiteness are
    the caller's to check."""
    import numpy as np

    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):  # ragged or not a sequence: the caller's conversion says so
        return
    if arr.ndim != 1:
        shape = "a single number" if arr.ndim == 0 else f"an array of shape {arr.shape}"
        raise ParameterError(f"{name} must be one row of real numbers, got {shape}", parameter=name)
    items = list(value) if isinstance(value, (list, tuple)) else []  # NumPy turns (True, 0.5) into floats
    if arr.dtype.kind in "fiu" and not any(isinstance(x, (bool, np.bool_)) for x in items):  # the common case
        return
    entries = arr.tolist() + items
    # the entry to name: one with an imaginary part, else the first that is no real number
    entries.sort(key=lambda x: not (isinstance(x, (complex, np.complexfloating)) and x.imag != 0))
    for x in entries:
        kind = ("a complex number" if isinstance(x, (complex, np.complexfloating)) else
                "a boolean" if isinstance(x, (bool, np.bool_)) else
                "text" if isinstance(x, (str, bytes)) else None)
        if kind:
            raise ParameterError(f"{name} must be real numbers, got {kind}: {x!r}", parameter=name)
