"""A disk cache of the report's symbolic sections (2, the derivation, and 3, the check at alpha = 0).

Two levels: whole sections under the report's parameters (:func:`load`, :func:`save`), and the parts
that depend on no value of theirs (:func:`memo`: the check at alpha = 0 with every parameter symbolic,
the thin rods' symbolic derivation under which terms are on), so that a report at another skew or other
masses reads those and computes only what its values change.

They are pure SymPy -- several seconds -- and depend only on the parameters and on skewpend's own
code, so, like the compiled kernels, they are kept in the cache directory
(:func:`skewpend.numeric.kernels.cache_dir`, ``$SKEWPEND_CACHE_DIR``) under a key that is the
SHA-256 of the parameters, skewpend's version and the text of every module that can change them
(``skewpend/symbolic``, ``skewpend/views/report``): any edit to that code, another version or
other parameters is another key.  A missing, unreadable or damaged entry is computed again; a
cache that cannot be written is skipped.  At most :data:`KEEP` entries are kept (the oldest go).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from contextlib import suppress
from functools import lru_cache
from pathlib import Path
from typing import Dict, Optional

__all__ = ["load", "save", "key", "memo", "KEEP"]

#: Entries kept in the cache (each some 100 kB of HTML).
KEEP = 64
_PACKAGE = Path(__file__).resolve().parents[2]


@lru_cache(maxsize=1)
def _code_digest() -> str:
    h = hashlib.sha256()
    for folder in ("symbolic", "views/report"):
        for path in sorted((_PACKAGE / folder).glob("*.py")):
            h.update(path.relative_to(_PACKAGE).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return h.hexdigest()


def key(params, part: str = "") -> str:
    """The entry's name: the SHA-256 of the version, the code and ``params`` (a model, or any JSON-able value
    for a ``part`` of a section)."""
    from ... import __version__

    what = params.to_dict() if hasattr(params, "to_dict") else params
    text = json.dumps({"skewpend": __version__, "code": _code_digest(), "params": what, **({"part": part} if part else {})},
                      sort_keys=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def memo(part: str, what, compute):
    """``compute()`` (a JSON-able value), kept under ``part`` and ``what`` (what it depends on, JSON-able):
    read back when an entry is there and whole, computed and stored otherwise."""
    path = _folder() / f"{key(what, part)}.json"
    with suppress(OSError, ValueError):
        data = json.loads(path.read_text(encoding="utf-8"))
        if isinstance(data, dict) and "value" in data:
            with suppress(OSError):
                os.utime(path)
            return data["value"]
    value = compute()
    _store(path, {"value": value})
    return value


def _folder() -> Path:
    from ...numeric.kernels import cache_dir

    return cache_dir() / "report-sections"


def load(params) -> Optional[Dict]:
    """The sections stored for ``params`` (``{"bodies", "notes", "timings"}``), or None."""
    path = _folder() / f"{key(params)}.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not (isinstance(data, dict) and isinstance(data.get("bodies"), dict)
            and all(isinstance(data["bodies"].get(k), str) for k in ("derivation", "check"))
            and isinstance(data.get("notes"), dict) and isinstance(data.get("timings"), dict)):
        return None
    with suppress(OSError):
        os.utime(path)  # recently used: kept longest
    return data


def save(params, sections: Dict) -> None:
    """Store ``sections`` for ``params`` (atomically); silently nothing if the cache is not writable."""
    _store(_folder() / f"{key(params)}.json", sections)


def _store(path: Path, data) -> None:
    folder = path.parent
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=".tmp")  # exclusive: never a planted link
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(json.dumps(data))
            os.replace(tmp, path)
        finally:
            if os.path.lexists(tmp):
                os.unlink(tmp)
        entries = sorted(folder.glob("*.json"), key=lambda p: p.stat().st_mtime)
        for old in entries[:-KEEP]:
            old.unlink(missing_ok=True)
    except OSError:
        return
