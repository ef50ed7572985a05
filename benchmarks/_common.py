"""Helpers shared by the benchmark scripts (machine facts for their headers, heyoka.py compile times)."""

from __future__ import annotations

import importlib.metadata
import platform
import time
from pathlib import Path


def version(dist: str) -> str:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def compile_times(build):
    """(cold seconds, seconds from heyoka's on-disk cache, object) for ``build()`` (the JIT only).

    The in-memory cache is cleared before the caching build, else that build would be served from
    memory and store nothing on disk (on a first run the "cached" figure was then a second cold
    compile)."""
    import heyoka as hy

    L = hy.llvm_state
    was = L.get_diskcache_enabled()
    L.clear_memcache()
    L.set_diskcache_enabled(False)
    try:
        t0 = time.perf_counter()
        obj = build()
        cold = time.perf_counter() - t0
    finally:
        L.set_diskcache_enabled(was)
    # with heyoka's on-disk cache as the user has it: the in-memory cache cleared first, else this
    # build would be served from memory and store nothing on disk (stores the code if it is not there)
    L.clear_memcache()
    build()
    L.clear_memcache()
    t0 = time.perf_counter()
    build()
    return cold, time.perf_counter() - t0, obj


def heyoka_header(cores: int, *, sympy: bool = False):
    """Print the machine lines every heyoka.py comparison starts with; the module ``heyoka`` or None
    (not installed: only skewpend is measured)."""
    import os

    try:
        import heyoka as hy
    except ImportError:
        hy = None
    print("machine")
    print(f"  cpu        {cpu_model()}")
    print(f"  cores      {cores} usable (os.cpu_count {os.cpu_count()}); load average {os.getloadavg()[0]:.2f} at start")
    print(f"  python     {platform.python_version()}   numpy {version('numpy')}   "
          + (f"sympy {version('sympy')}   " if sympy else "") + f"skewpend {version('skewpend')}")
    print(f"  heyoka     {version('heyoka')}" + (f"   (recommended SIMD batch size {hy.recommended_simd_size()})" if hy else ""))
    return hy

