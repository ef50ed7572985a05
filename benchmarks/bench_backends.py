"""Numba or generated C? The same generated right-hand side in both, side by side.

Measures the cost of one evaluation of ``dy/dt`` for the thin-rod model:

* numba: the kernel's ``rhs`` called 10^6 times from a numba-compiled loop (how the
  integrators use it: inlined, no call overhead);
* C: ``skewpend derive --format c`` compiled with ``cc -O3 -march=native``, called 10^6
  times from a C loop (the best a generated-C backend can do);
* C through ctypes from Python, 10^4 calls (what calling compiled C per step from a
  Python-level integrator would cost).

Run:  python benchmarks/bench_backends.py
"""

from __future__ import annotations

import ctypes
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numba as nb
import numpy as np

from skewpend import Parameters
from skewpend.codegen import generate, kernel_module, parameter_vector

P = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
N = 1_000_000

HARNESS = r"""
void skewpend_rhs(const double y[4], const double p[10], double dydt[4]);
double loop(long n, const double *p) {
    double y[4] = {1.2, -0.8, 0.1, 0.2}, d[4], acc = 0.0;
    for (long i = 0; i < n; ++i) {
        y[0] = 1.2 + 1e-7 * (double)(i & 1023);
        skewpend_rhs(y, p, d);
        acc += d[2] + d[3];
    }
    return acc;
}
"""


def main():
    p = parameter_vector(P)
    k = kernel_module(P)
    rhs = k.rhs

    @nb.njit
    def loop(n, p):
        y = np.array([1.2, -0.8, 0.1, 0.2, 0.0])
        d = np.empty(5)
        acc = 0.0
        for i in range(n):
            y[0] = 1.2 + 1e-7 * (i & 1023)
            rhs(y, p, d)
            acc += d[2] + d[3]
        return acc

    loop(10, p)
    t0 = time.perf_counter()
    ref = loop(N, p)
    t_numba = (time.perf_counter() - t0) / N
    rows = [("numba rhs, compiled loop", t_numba)]

    cc = shutil.which("cc") or shutil.which("gcc")
    if cc:
        with tempfile.TemporaryDirectory() as d:
            d = Path(d)
            (d / "model.c").write_text(generate(P, "c"))
            (d / "harness.c").write_text(HARNESS)
            lib = d / "libm.so"
            subprocess.run([cc, "-O3", "-march=native", "-shared", "-fPIC", "-o", str(lib), str(d / "model.c"), str(d / "harness.c"), "-lm"], check=True)
            so = ctypes.CDLL(str(lib))
            so.loop.restype = ctypes.c_double
            so.loop.argtypes = [ctypes.c_long, ctypes.POINTER(ctypes.c_double)]
            pp = (ctypes.c_double * 10)(*p)
            so.loop(10, pp)
            t0 = time.perf_counter()
            val = so.loop(N, pp)
            rows.append(("generated C, C loop (-O3)", (time.perf_counter() - t0) / N))
            assert abs(val - ref) < 1e-6 * abs(ref), (val, ref)
            y4 = (ctypes.c_double * 4)(1.2, -0.8, 0.1, 0.2)
            out = (ctypes.c_double * 4)()
            n_py = 10_000
            t0 = time.perf_counter()
            for _ in range(n_py):
                so.skewpend_rhs(y4, pp, out)
            rows.append(("generated C via ctypes from Python", (time.perf_counter() - t0) / n_py))
    print(f"{'backend':40s} {'ns per rhs':>11s} {'x numba':>8s}")
    for name, t in rows:
        print(f"{name:40s} {t * 1e9:11.1f} {t / t_numba:8.2f}")


if __name__ == "__main__":
    main()
