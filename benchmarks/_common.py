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


def heyoka_first_order(eom, s_dict, hv):
    """skewpend's equations of motion ``M(q) q'' = f`` as heyoka.py's first-order system over the
    variables ``hv`` = (phi, psi, phi', psi'), every symbol replaced through ``s_dict`` (SymPy
    symbol -> heyoka expression) by ``hy.from_sympy``; ``q'' = M^-1 f`` solved as skewpend does."""
    import heyoka as hy
    import sympy as sp

    def conv(e):
        e = sp.sympify(e)
        # constants heyoka cannot take as they are: functions of numbers (cos(3/5)) and rationals
        # whose denominator is not a power of 2 -> doubles
        e = e.xreplace({fn: sp.Float(float(fn), 53) for fn in e.atoms(sp.Function) if not fn.free_symbols})
        e = e.xreplace({r: sp.Float(float(r), 53) for r in e.atoms(sp.Rational) if not r.is_Integer})
        extra = e.free_symbols - set(s_dict)
        if extra:
            raise ValueError(f"equations still contain {sorted(map(str, extra))}")
        return hy.from_sympy(e, s_dict=s_dict)

    M, f = eom.mass_matrix, eom.forcing
    M11, M12, M22, f1, f2 = conv(M[0, 0]), conv(M[0, 1]), conv(M[1, 1]), conv(f[0]), conv(f[1])
    det = M11 * M22 - M12 * M12
    phi, psi, dphi, dpsi = hv
    return [(phi, dphi), (psi, dpsi), (dphi, (M22 * f1 - M12 * f2) / det), (dpsi, (M11 * f2 - M12 * f1) / det)]


def print_report_timings(tables: dict, width: int) -> None:
    """The report's own timings (its section 10) of each run kind, side by side: ``tables`` maps a kind
    to ``{part: seconds}``; a part missing in a kind prints as nan."""
    kinds = list(tables)
    print("\nthe report's own timings (section 10, the last run of each) [s]")
    print(f"{'part':<44}" + "".join(f"{k:>{width}}" for k in kinds))
    for part in dict.fromkeys(p for t in tables.values() for p in t):
        print(f"{part:<44}" + "".join(f"{tables[k].get(part, float('nan')):>{width}.2f}" for k in kinds))

