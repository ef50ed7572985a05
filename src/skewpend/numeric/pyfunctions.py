"""NumPy functions generated from the derivation by SymPy's ``lambdify``, kept on disk.

A few analyses evaluate small symbolic results numerically -- the linearised matrices of the
normal modes, the potential's gradient and Hessian of the equilibria -- through ``lambdify``.
Making one takes SymPy (a quarter of a second to import) and the derivation of the geometry;
the printed function does not.  So, like the compiled kernels
(:func:`skewpend.numeric.kernels.kernel_module`), the printed source is kept in the cache directory
(``$SKEWPEND_CACHE_DIR``, folder ``python``) under a key that is the SHA-256 of skewpend's and
SymPy's versions, the text of the modules that shape it (``skewpend/symbolic``, the caller's
module) and the geometry; the next process reads and compiles it without importing SymPy.  The
function is the same text either way, so it computes the same bits.  A missing or damaged entry
is made again; a cache that cannot be written is skipped.
"""

from __future__ import annotations

import hashlib
import json
from functools import lru_cache
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Callable, Sequence, Tuple

__all__ = ["cached_lambdify", "cached_object"]

_PACKAGE = Path(__file__).resolve().parent.parent
#: The namespace ``lambdify(..., "numpy")`` evaluates its printed source in.
_NUMPY_IMPORTS = "import numpy; from numpy import *; from numpy.linalg import *"


@lru_cache(maxsize=None)
def _code_digest(caller: str) -> str:
    from .. import __version__

    h = hashlib.sha256(__version__.encode())
    try:
        h.update(version("sympy").encode())
    except PackageNotFoundError:  # pragma: no cover - sympy is a dependency
        pass
    paths = sorted((_PACKAGE / "symbolic").glob("*.py")) + [_PACKAGE / caller, Path(__file__)]
    for path in paths:
        h.update(path.relative_to(_PACKAGE).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def _key(name: str, caller: str, geometry) -> str:
    described = geometry.to_dict() if hasattr(geometry, "to_dict") else geometry
    text = json.dumps({"name": name, "code": _code_digest(caller), "geometry": described}, sort_keys=True,
                      default=repr)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:24]


def _compile(source: str, filename: str) -> Callable:
    namespace: dict = {}
    exec(_NUMPY_IMPORTS, namespace)  # noqa: S102 - the namespace lambdify itself uses
    exec(compile(source, filename, "exec"), namespace)  # noqa: S102 - text printed by lambdify, see the module
    fn = namespace.get("_lambdifygenerated")
    if not callable(fn):
        raise ValueError("no _lambdifygenerated in the cached source")
    return fn


def cached_lambdify(name: str, caller: str, geometry, build: Callable[[], Tuple[Sequence, object]]) -> Callable:
    """``lambdify(args, exprs, "numpy")`` for ``(args, exprs) = build()``, read from the cache when
    there.  ``name``: what the function is (part of the key and the file name); ``caller``: the
    module that builds it, relative to the package (``"analysis/modes.py"``), whose text is part of
    the key; ``geometry``: the :class:`~skewpend.Parameters` it was derived for."""
    from .kernels import cache_dir, write_text_atomically

    folder = cache_dir() / "python"
    path = folder / f"{name}_{_key(name, caller, geometry)}.py"
    try:
        return _compile(path.read_text(encoding="utf-8"), str(path))
    except (OSError, UnicodeDecodeError, SyntaxError, ValueError, NameError, TypeError):
        pass  # not there, or damaged: made again below
    import inspect

    import sympy as sp

    args, exprs = build()
    fn = sp.lambdify(args, exprs, "numpy")
    source = inspect.getsource(fn)
    try:
        folder.mkdir(parents=True, exist_ok=True)
        write_text_atomically(path, source)  # a temporary file made exclusively (never a planted link), then renamed
    except OSError:
        pass  # an unwritable cache: this process keeps its function
    return fn


def cached_object(name: str, caller: str, key, build: Callable[[], object]) -> object:
    """``build()``'s result (symbolic objects: SymPy expressions and matrices, tuples, numbers),
    kept in the cache directory as a pickle under the same kind of key as :func:`cached_lambdify`
    (skewpend's and SymPy's versions, the text of ``skewpend/symbolic`` and of ``caller``, and
    ``key``: what the result was derived for, JSON-able or a :class:`~skewpend.Parameters`).  The
    cache is the user's own directory, written only by skewpend (atomically); a missing or damaged
    entry is built again, an unwritable cache skipped."""
    import pickle

    from .kernels import cache_dir, write_text_atomically

    folder = cache_dir() / "python"
    path = folder / f"{name}_{_key(name, caller, key)}.pickle"
    try:
        with open(path, "rb") as fh:
            return pickle.load(fh)
    except Exception:  # noqa: BLE001 - not there, or damaged (any unpickling error): built again below
        pass
    value = build()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        write_text_atomically(path, pickle.dumps(value, protocol=pickle.HIGHEST_PROTOCOL))
    except (OSError, pickle.PicklingError, TypeError, AttributeError):
        pass  # an unwritable cache, or a value that does not pickle: this process keeps its own
    return value

