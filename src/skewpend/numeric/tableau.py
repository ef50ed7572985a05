"""The DOP853 tableau as JavaScript, for the explorer's flip-map workers (no SymPy: the pages that
only replay a motion need it without the derivation)."""

from __future__ import annotations

import json

__all__ = ["dop853_js"]


def _coefficients():
    """SciPy's ``scipy/integrate/_ivp/dop853_coefficients.py`` (it imports only NumPy), loaded from its
    file: importing it by name would first import ``scipy.integrate`` (0.13 s) for a table of numbers."""
    import importlib.util
    from pathlib import Path

    import scipy

    path = Path(scipy.__file__).parent / "integrate" / "_ivp" / "dop853_coefficients.py"
    spec = importlib.util.spec_from_file_location("_skewpend_dop853_coefficients", path)
    if spec is None or spec.loader is None or not path.is_file():  # another layout: the import by name
        from scipy.integrate._ivp import dop853_coefficients

        return dop853_coefficients
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def dop853_js() -> str:
    """The DOP853 tableau (Hairer's Dormand-Prince 8(5,3), as tabulated in SciPy -- the same
    numbers as ``integrators.c``'s) as a classic script defining ``self.DOP853`` (A, C, E3, E5,
    D), for the flip-map workers of the explorer."""
    t = _coefficients()

    def arr(x):
        return json.dumps([float(v) for v in x]) if x.ndim == 1 else "[" + ", ".join(arr(r) for r in x) + "]"

    return ("self.DOP853 = {" + ", ".join(f"{k}: {arr(getattr(t, k))}" for k in ("A", "C", "E3", "E5", "D")) +
            ", NS: 12, NSTAGES: 16};\n")
