"""Resumable result stores: a Zarr group over a grid, written chunk by chunk.

The template-then-region-writes pattern: :meth:`RowStore.create` writes the whole layout
first -- the arrays (filled with their fill values, so nothing is stored yet), the
coordinates, the attributes -- in a temporary directory beside the target and renames it
into place, so a store either exists complete with its metadata or not at all.  Results
then arrive one *chunk* (a block of whole rows, one Zarr chunk of every array) at a time:
:meth:`RowStore.write_chunk` writes the chunk's region of every array, then its row of
per-chunk statistics, and only then sets the chunk's ``done`` flag.  A run stopped at any
point -- Ctrl-C, ``kill -9``, a power cut -- leaves a store whose ``done`` flags name exactly
the chunks that are complete (Zarr writes every chunk file to a temporary name and renames
it; a flag that cannot be read counts as not done), so a later run computes only the
others.  No two chunks share a Zarr chunk of any array, so no region write touches another
chunk's data.

A run holds the store's lock file (``.skewpend.lock``: host and process id) while it writes;
a second run on the same store is refused while the first is alive, and the lock of a
killed run is taken over.

Zarr (the ``cluster`` extra) is imported only here and only when a store is used; without
it the error says ``pip install "skewpend[cluster]"``.  Zarr 2 (format 2) and Zarr 3 (format
3) are both supported; either way the store opens with ``xarray.open_zarr``.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import socket
import time
from pathlib import Path
from typing import Any, Dict, Mapping, Optional, Sequence, Tuple

import numpy as np

from ..errors import ParameterError, SkewpendError

__all__ = ["RowStore", "require_zarr", "store_target", "settings_diff", "digest", "CLUSTER_EXTRA", "STORE_SUFFIX"]

#: How to install what stores and clusters need.
CLUSTER_EXTRA = 'pip install "skewpend[cluster]"'
#: Stores are directories named ``*.zarr``.
STORE_SUFFIX = ".zarr"
#: Marks a store written by this module (attribute ``skewpend_store``).
FORMAT = "skewpend-rowstore/1"
LOCK_NAME = ".skewpend.lock"


def require_zarr(what: str = "a Zarr store"):
    """The ``zarr`` module, or a :class:`SkewpendError` naming the extra to install."""
    from ..errors import require

    return require("zarr", what)


def _zarr3(zarr) -> bool:
    return int(zarr.__version__.split(".")[0]) >= 3


def _create_array(zarr, group, name: str, *, shape, chunks, dtype, fill_value, dims: Sequence[str],
                  attrs: Optional[Mapping[str, Any]] = None, data: Optional[np.ndarray] = None):
    attrs = dict(attrs or {})
    if _zarr3(zarr):
        arr = group.create_array(name, shape=shape, chunks=chunks, dtype=dtype, fill_value=fill_value,
                                 dimension_names=tuple(dims), attributes=attrs)
    else:  # pragma: no cover - zarr 2
        arr = group.create_dataset(name, shape=shape, chunks=chunks, dtype=dtype, fill_value=fill_value)
        arr.attrs.update({"_ARRAY_DIMENSIONS": list(dims), **attrs})
    if data is not None:
        arr[...] = data
    return arr


def _tmp_dir(path: Path) -> Path:
    """A new directory beside ``path``, made exclusively under a random name (never an existing
    path or a planted link), holding the template at ``store`` until it is renamed into place."""
    import tempfile

    parent = path.parent if str(path.parent) else Path(".")
    return Path(tempfile.mkdtemp(prefix=f".{path.name}.skewpend-{os.getpid()}-", suffix=".tmp", dir=parent))


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: alive
        return True
    return True


def _remove_stale_templates(path: Path) -> None:
    """Temporary store directories beside ``path`` left by killed processes."""
    pattern = re.compile(rf"^\.{re.escape(path.name)}\.skewpend-(\d+)-[A-Za-z0-9_]+\.tmp$")
    parent = path.parent if str(path.parent) else Path(".")
    try:
        entries = list(parent.iterdir())
    except OSError:
        return
    for entry in entries:
        m = pattern.match(entry.name)
        if m and int(m.group(1)) != os.getpid() and not _alive(int(m.group(1))) and not entry.is_symlink():
            shutil.rmtree(entry, ignore_errors=True)


def check_store_path(path, *, option: str = "store") -> Path:
    """A store path: ending in ``.zarr``, in an existing directory.  (Whether it may exist is
    the caller's decision.)"""
    try:
        path = Path(os.fspath(path))
    except TypeError:
        raise ParameterError(f"{option} must be a path ending in {STORE_SUFFIX}, got {path!r}") from None
    if path.suffix.lower() != STORE_SUFFIX:
        raise ParameterError(f"{option}: expected a directory name ending in {STORE_SUFFIX}, got {str(path)!r}")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise ParameterError(f"{option}: cannot write {path}: directory {parent} does not exist")
    return path


def settings_diff(stored: Dict[str, Any], wanted: Dict[str, Any]) -> str:
    """What differs between a store's recorded settings and a run's, for the message."""

    def flat(d, top=None):
        """Nested settings (the parameters) by their own names, prefixed only where a name is
        also a top-level setting (``params.alpha`` beside a diagram's ``alpha`` axis)."""
        top = set(d) if top is None else top
        out = {}
        for k, v in d.items():
            if isinstance(v, dict):
                out.update({(f"{k}.{kk}" if kk in top else kk): vv for kk, vv in flat(v, top).items()})
            else:
                out[k] = v
        return out

    a, b = flat(stored), flat(wanted)
    diffs = [f"{k} {b.get(k)!r} (store: {a.get(k)!r})" for k in list(b) + [k for k in a if k not in b] if a.get(k) != b.get(k)]
    if not diffs:
        return "settings recorded differently"
    return ", ".join(diffs[:6]) + (f", and {len(diffs) - 6} more" if len(diffs) > 6 else "")


def store_target(store, *, resume: bool, what: str) -> Tuple[Path, bool]:
    """The path of a run's store (checked, Zarr importable) and whether it exists already; an
    existing store without ``resume`` is refused (never overwritten)."""
    path = check_store_path(store)
    require_zarr(what)
    exists = os.path.lexists(path)
    if exists and not resume:
        raise ParameterError(f"{path} exists; resume it (--resume) or choose another path")
    return path, exists


class RowStore:
    """A Zarr group of arrays over an ``(rows, cols)`` grid (optionally with one more trailing
    dimension), in chunks of ``chunk_rows`` whole rows, with a ``done`` flag and a row of
    statistics per chunk.

    Use :meth:`create` (a new store, locked) or :meth:`open` (an existing one; locked when
    ``writable``) as a context manager; leaving the block releases the lock.  Arrays:

    * each data array, shape ``(rows, cols)``, Zarr chunks ``(chunk_rows, cols)``;
    * the two coordinate arrays, named by ``dims``;
    * ``done`` (bool, one per chunk) and ``chunk_stats`` (float64, ``(chunks, len(stats))``).
    """

    def __init__(self, path: Path, group, zarr, *, lock: bool):
        self.path, self._g, self._zarr = path, group, zarr
        a = dict(group.attrs)
        self.shape: Tuple[int, int] = tuple(a["shape"])  # type: ignore[assignment]
        self.chunk_rows: int = int(a["chunk_rows"])
        self.n_chunks: int = self.shape[0] // self.chunk_rows
        self.arrays: Tuple[str, ...] = tuple(a["arrays"])
        self.stat_names: Tuple[str, ...] = tuple(a["stats"])
        names = (*self.arrays, "done", "chunk_stats") + (("chunk_digest",) if a.get("digests", False) else ())
        try:
            self._arrays = {name: group[name] for name in names}  # handles, read once
        except Exception as exc:  # noqa: BLE001 - a deleted array, corrupt array metadata
            raise ParameterError(_damaged(path, f"an array cannot be opened ({_reason(exc)})")) from None
        self._lock: Optional[Path] = None
        if lock:
            self._acquire()

    # -- life cycle ---------------------------------------------------------------------------------
    @classmethod
    def create(cls, path, *, kind: str, shape: Tuple[int, int], chunk_rows: int,
               arrays: Mapping[str, Tuple[Any, Any, Mapping[str, Any]]], dims: Tuple[str, str],
               coords: Mapping[str, Tuple[np.ndarray, Mapping[str, Any]]], stats: Sequence[str],
               attrs: Mapping[str, Any], extra: Optional[Tuple[str, np.ndarray, Mapping[str, Any]]] = None) -> "RowStore":
        """Write the template of a new store at ``path`` (refused if anything is there).

        ``arrays``: name -> (dtype, fill value, attributes), or (dtype, fill value, attributes,
        True) for an array with the trailing dimension ``extra`` = (name, coordinate values,
        attributes) -- shape ``(rows, cols, len(values))``; ``coords``: for each name in ``dims``,
        (values, attributes); ``kind`` is recorded and checked by :meth:`open`.
        """
        zarr = require_zarr()
        path = Path(path)
        rows, cols = (int(s) for s in shape)
        if chunk_rows < 1 or rows % chunk_rows:
            raise ValueError(f"chunk_rows must divide the rows: {chunk_rows} does not divide {rows}")
        if os.path.lexists(path):
            raise ParameterError(f"{path} exists; resume it or choose another path")
        _remove_stale_templates(path)
        try:
            holder = _tmp_dir(path)
        except OSError as exc:
            raise ParameterError(f"cannot create {path}: {exc.strerror or exc}") from None
        tmp = holder / "store"
        n_chunks = rows // chunk_rows
        try:
            group = zarr.open_group(str(tmp), mode="w-")
            for name, (dtype, fill, a, *has_extra) in arrays.items():
                more: Tuple[int, ...] = ()
                if has_extra and has_extra[0]:
                    if extra is None:
                        raise ValueError(f"array {name} has the extra dimension, but none is given")
                    more = (len(extra[1]),)
                _create_array(zarr, group, name, shape=(rows, cols, *more), chunks=(chunk_rows, cols, *more),
                              dtype=dtype, fill_value=fill, dims=(*dims, extra[0]) if more else dims, attrs=a)
            if extra is not None:
                values = np.asarray(extra[1], dtype=np.float64)
                _create_array(zarr, group, extra[0], shape=values.shape, chunks=values.shape, dtype="float64",
                              fill_value=np.nan, dims=(extra[0],), attrs=extra[2], data=values)
            for dim, size in zip(dims, (rows, cols)):
                values, a = coords[dim]
                values = np.asarray(values, dtype=np.float64)
                if values.shape != (size,):
                    raise ValueError(f"coordinate {dim} must have {size} values")
                _create_array(zarr, group, dim, shape=(size,), chunks=(size,), dtype="float64", fill_value=np.nan,
                              dims=(dim,), attrs=a, data=values)
            _create_array(zarr, group, "done", shape=(n_chunks,), chunks=(1,), dtype="bool", fill_value=False,
                          dims=("chunk",), attrs={"long_name": "chunk complete (its rows and statistics written)"})
            _create_array(zarr, group, "chunk_stats", shape=(n_chunks, len(stats)), chunks=(1, len(stats)),
                          dtype="float64", fill_value=np.nan, dims=("chunk", "stat"),
                          attrs={"long_name": "statistics of each chunk", "columns": list(stats)})
            _create_array(zarr, group, "chunk_digest", shape=(n_chunks, len(arrays)), chunks=(1, len(arrays)),
                          dtype="uint64", fill_value=0, dims=("chunk", "array"),
                          attrs={"long_name": "BLAKE2b-64 digest of each chunk of each array (written before 'done')",
                                 "columns": list(arrays)})
            _update_attrs(group, {
                **dict(attrs), "skewpend_store": FORMAT, "kind": kind, "shape": [rows, cols], "chunk_rows": int(chunk_rows),
                "n_chunks": n_chunks, "arrays": list(arrays), "stats": list(stats), "complete": False, "digests": True,
            })
            _write_lock(tmp / LOCK_NAME)
            try:
                os.rename(tmp, path)  # atomic: the store appears with its whole template, or not at all
            except OSError as exc:
                if os.path.lexists(path):
                    raise ParameterError(f"{path} exists; resume it or choose another path") from None
                raise ParameterError(f"cannot create {path}: {exc.strerror or exc}") from None
        except OSError as exc:
            raise ParameterError(f"cannot create {path}: {exc.strerror or exc}") from None
        finally:
            shutil.rmtree(holder, ignore_errors=True)  # the holder only: the store has left it, or failed
        store = cls(path, zarr.open_group(str(path), mode="r+"), zarr, lock=False)
        store._lock = path / LOCK_NAME
        return store

    @classmethod
    def open(cls, path, *, kind: str, writable: bool = False) -> "RowStore":
        """An existing store made by :meth:`create` with the same ``kind``; ``writable`` takes
        its lock (refused while another live process holds it)."""
        zarr = require_zarr()
        path = Path(path)
        if not path.exists():
            raise ParameterError(f"{path} does not exist")
        if not path.is_dir():
            raise ParameterError(f"{path} is not a {kind} store (not a directory)")
        try:
            group = zarr.open_group(str(path), mode="r+" if writable else "r")
            attrs = dict(group.attrs)
        except Exception:  # noqa: BLE001 - whatever Zarr raises for a directory that is not a group
            if (path / "zarr.json").exists() or (path / ".zgroup").exists():
                raise ParameterError(_damaged(path, "its group metadata cannot be read")) from None
            raise ParameterError(f"{path} is not a {kind} store (no Zarr group there)") from None
        if attrs.get("skewpend_store") != FORMAT or attrs.get("kind") != kind:
            raise ParameterError(f"{path} is not a {kind} store made by skewpend")
        try:
            shape = [int(x) for x in attrs["shape"]]
            rows_per_chunk = int(attrs["chunk_rows"])
            ok = len(shape) == 2 and rows_per_chunk >= 1 and shape[0] % rows_per_chunk == 0
        except (KeyError, TypeError, ValueError):
            ok = False
        if not ok:
            raise ParameterError(_damaged(path, "its layout attributes are missing or inconsistent"))
        return cls(path, group, zarr, lock=writable)

    @classmethod
    def open_matching(cls, path, *, kind: str, fingerprint: str, settings: Mapping[str, Any],
                      writable: bool = False) -> "RowStore":
        """:meth:`open`, refused (naming what differs) unless the store was made with the same
        settings (their recorded fingerprint): the check before a run resumes a store."""
        st = cls.open(path, kind=kind, writable=writable)
        if st.attrs.get("fingerprint") != fingerprint:
            try:
                stored = json.loads(st.attrs.get("settings", "{}"))
            except ValueError:
                stored = {}
            st.close()
            raise ParameterError(f"{path} was made with other settings: {settings_diff(stored, dict(settings))}; "
                                 "resume with the same settings, or choose another path")
        return st

    def close(self) -> None:
        """Release the lock (if held)."""
        if self._lock is not None:
            with contextlib.suppress(OSError):
                self._lock.unlink()
            self._lock = None

    def __enter__(self) -> "RowStore":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _acquire(self) -> None:
        lock = self.path / LOCK_NAME
        for _ in range(2):
            try:
                _write_lock(lock, exclusive=True)
                self._lock = lock
                return
            except FileExistsError:
                host, pid = _read_lock(lock)
                stale = host == socket.gethostname() and pid is not None and pid != os.getpid() and not _alive(pid)
                if pid is None:  # unreadable: cut short by a kill while being written, unless just being written
                    with contextlib.suppress(OSError):
                        stale = time.time() - lock.stat().st_mtime > 10.0
                if stale:
                    with contextlib.suppress(OSError):
                        lock.unlink()  # its run was killed: take over
                    continue
                who = f"process {pid} on {host}" if pid is not None else "another run"
                raise ParameterError(
                    f"{self.path} is in use by {who}; wait for it to finish (if that run was killed on another "
                    f"machine, delete {lock})"
                ) from None
        raise ParameterError(f"cannot lock {self.path}: {lock} keeps reappearing")  # pragma: no cover

    # -- contents -----------------------------------------------------------------------------------
    @property
    def attrs(self) -> Dict[str, Any]:
        return dict(self._g.attrs)

    def set_attrs(self, **values: Any) -> None:
        _update_attrs(self._g, values)

    def chunk_rows_of(self, k: int) -> slice:
        return slice(k * self.chunk_rows, (k + 1) * self.chunk_rows)

    def done(self) -> np.ndarray:
        """The ``done`` flags (a flag that cannot be read -- a file cut short -- is not done)."""
        arr = self._arrays["done"]
        try:
            return np.asarray(arr[:], dtype=bool)
        except Exception:  # noqa: BLE001 - a damaged chunk file: read flag by flag
            out = np.zeros(self.n_chunks, dtype=bool)
            for k in range(self.n_chunks):
                with contextlib.suppress(Exception):
                    out[k] = bool(np.asarray(arr[k:k + 1])[0])
            return out

    def write_chunk(self, k: int, data: Mapping[str, np.ndarray], stats: np.ndarray) -> None:
        """Chunk ``k``: the region of every array, its statistics, then its ``done`` flag."""
        if set(data) != set(self.arrays):
            raise ValueError(f"write_chunk needs exactly the arrays {self.arrays}")
        rows = self.chunk_rows_of(k)
        try:
            for name in self.arrays:
                self._arrays[name][rows] = data[name]
            self._arrays["chunk_stats"][k:k + 1, :] = np.asarray(stats, dtype=np.float64)[None, :]
            if "chunk_digest" in self._arrays:
                digests = [digest(np.asarray(data[name], dtype=self._arrays[name].dtype)) for name in self.arrays]
                self._arrays["chunk_digest"][k:k + 1, :] = np.asarray(digests, dtype=np.uint64)[None, :]
            self._arrays["done"][k:k + 1] = np.ones(1, dtype=bool)  # the whole chunk: never read first
        except OSError as exc:  # a full disk, a store deleted under us, ...
            raise SkewpendError(f"cannot write to {self.path}: {exc.strerror or exc} (what was written is kept: "
                                "resume once the problem is fixed)") from None

    def damaged(self, done: Optional[np.ndarray] = None) -> np.ndarray:
        """Indices of the chunks flagged done whose data cannot be read or no longer match the
        digests written with them (a chunk file deleted, emptied or overwritten).  A missing
        chunk file of an array is read as its fill value, which is right only if that is what
        was written: the digest tells.  Stores made before digests existed: readability only."""
        done = self.done() if done is None else done
        digests = None
        if "chunk_digest" in self._arrays:
            try:
                digests = np.asarray(self._arrays["chunk_digest"][...], dtype=np.uint64)
            except Exception:  # noqa: BLE001 - unreadable digests: every chunk is suspect
                return np.flatnonzero(done)
        bad = []
        for k in np.flatnonzero(done).tolist():
            rows = self.chunk_rows_of(k)
            try:
                blocks = [np.asarray(self._arrays[name][rows]) for name in self.arrays]
                np.asarray(self._arrays["chunk_stats"][k:k + 1])
            except Exception:  # noqa: BLE001 - whatever Zarr raises for a damaged chunk file
                bad.append(k)
                continue
            if digests is not None and any(int(digests[k, i]) != digest(b) for i, b in enumerate(blocks)):
                bad.append(k)
        return np.asarray(bad, dtype=np.int64)

    def read(self, name: str) -> np.ndarray:
        arr = self._arrays[name] if name in self._arrays else self._g[name]
        try:
            return np.asarray(arr[...])
        except Exception as exc:  # noqa: BLE001 - a damaged chunk file
            raise ParameterError(_damaged(self.path, f"{name} cannot be read ({_reason(exc)}); resume it to "
                                                     "recompute the damaged chunks")) from None

    def names(self) -> Tuple[str, ...]:
        """Every array of the store (data, coordinates, bookkeeping)."""
        return tuple(self._g.array_keys())

    def chunk_stats(self) -> np.ndarray:
        return self.read("chunk_stats")


def digest(block: np.ndarray) -> int:
    """BLAKE2b-64 of an array block's bytes (C order): what :meth:`RowStore.damaged` checks."""
    import hashlib

    return int.from_bytes(hashlib.blake2b(np.ascontiguousarray(block).tobytes(), digest_size=8).digest(), "little")


def _reason(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    reason = text[0] if text else type(exc).__name__
    return reason if len(reason) <= 120 else reason[:117] + "..."


def _damaged(path: Path, what: str) -> str:
    return (f"{path} is damaged: {what}; it cannot be repaired -- delete it and run again, or choose another path"
            if "resume" not in what else f"{path} is damaged: {what}")


def _update_attrs(group, values: Mapping[str, Any]) -> None:
    """One write of the group's metadata (Zarr 3's ``attrs.update`` rewrites it once per key).
    The whole mapping is given: Zarr 3.0.0-3.0.4's ``update_attributes`` replaced, not merged."""
    if hasattr(group, "update_attributes"):
        group.update_attributes({**dict(group.attrs), **dict(values)})
    else:  # pragma: no cover - zarr 2
        group.attrs.update(dict(values))


def _write_lock(lock: Path, *, exclusive: bool = False) -> None:
    flags = os.O_WRONLY | os.O_CREAT | (os.O_EXCL if exclusive else os.O_TRUNC)
    fd = os.open(lock, flags, 0o644)
    with os.fdopen(fd, "w") as fh:
        fh.write(json.dumps({"host": socket.gethostname(), "pid": os.getpid()}))


def _read_lock(lock: Path) -> Tuple[Optional[str], Optional[int]]:
    try:
        data = json.loads(lock.read_text())
        return str(data["host"]), int(data["pid"])
    except (OSError, ValueError, KeyError, TypeError):
        return None, None
