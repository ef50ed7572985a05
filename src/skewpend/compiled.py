"""Compiled kernels: the generated numba module for a model, cached on disk.

This module does not import SymPy: when the generated module for a model's bodies
and axes is already in the cache, a new process loads it (and numba's cached machine
code) without deriving anything.  On a miss, :mod:`skewpend.codegen` writes it.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys
import tempfile
import threading
from pathlib import Path
from typing import Dict, Tuple

from . import __version__
from .model import SCALAR_NAMES, Parameters

__all__ = ["PARAMETER_ORDER", "STATE_ORDER", "geometry_of", "parameter_vector", "kernel_module", "cache_dir"]

#: Order of the parameter array ``p`` of every generated routine.
PARAMETER_ORDER: Tuple[str, ...] = SCALAR_NAMES
#: Order of the state ``y``.
STATE_ORDER: Tuple[str, ...] = ("phi", "psi", "dphi", "dpsi")
_GEOMETRY = ("com1", "com2", "inertia1", "inertia2", "axis1", "axis2")
_SOURCES = ("codegen.py", "derivation.py", "kinematics.py", "_kernels.py", "compiled.py")


def geometry_of(params: Parameters) -> Parameters:
    """The same bodies and axes with every scalar parameter symbolic (a runtime input)."""
    return Parameters(**{k: getattr(params, k) for k in _GEOMETRY}, **{k: None for k in SCALAR_NAMES})


def parameter_vector(params: Parameters):
    """The float64 parameter array ``p`` in :data:`PARAMETER_ORDER` (``alpha`` = 0 when unused)."""
    import numpy as np

    params.require_numeric("numeric evaluation")
    return np.array(
        [0.0 if (n == "alpha" and not params.uses_alpha) else float(getattr(params, n)) for n in PARAMETER_ORDER]
    )


def _template_text() -> str:
    return (Path(__file__).with_name("_kernels.py")).read_text()


def cache_dir() -> Path:
    """Where generated kernels are kept: ``$SKEWPEND_CACHE_DIR`` or the user cache directory."""
    env = os.environ.get("SKEWPEND_CACHE_DIR")
    if env:
        return Path(env)
    import platformdirs

    return Path(platformdirs.user_cache_dir("skewpend"))


_LOCK = threading.Lock()
_LOADED: Dict[str, object] = {}


def _key(geometry: Parameters) -> str:
    h = hashlib.sha256()
    h.update(__version__.encode())
    h.update(repr(geometry.to_dict()).encode())
    for name in _SOURCES:
        h.update(Path(__file__).with_name(name).read_bytes())
    return h.hexdigest()[:20]


def kernel_module(params: Parameters):
    """The compiled kernel module for the bodies and axes of ``params``.

    Generated on first use (derivation + code generation, well under a second), written to
    :func:`cache_dir` atomically, and imported; numba caches its machine code next to it,
    so later processes start without deriving or compiling.  The module holds ``rhs``,
    ``jac``, ``energy``, ``momenta``, ``velocities``, ``ham_rhs`` and the integrators of
    :mod:`skewpend._kernels`.
    """
    geometry = geometry_of(params)
    key = _key(geometry)
    with _LOCK:
        if key in _LOADED:
            return _LOADED[key]
        directory = cache_dir() / "kernels"
        directory.mkdir(parents=True, exist_ok=True)
        path = directory / f"skewpend_model_{key}.py"
        if not path.exists():
            from .codegen import kernel_source

            source = kernel_source(geometry) + "\n" + _template_text()
            fd, tmp = tempfile.mkstemp(dir=directory, suffix=".tmp")
            with os.fdopen(fd, "w") as fh:
                fh.write(source)
            os.replace(tmp, path)
        name = f"skewpend_model_{key}"
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
        _LOADED[key] = module
        return module


