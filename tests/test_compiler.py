"""No C compiler needed (issue 16): the order in which a compiler is found ($CC, the system's
cc/gcc/clang, the packaged zig cc of the ziglang wheel), the record of which one built each
cached library, and -- as a new user without a compiler runs them -- simulate, flipmap,
lyapunov and report with a PATH that holds no compiler, CC unset and an empty kernel cache.

Results of the packaged compiler are compared with the system compiler's to tolerances
derived from the runs (both are IEEE double without contraction or fast math; only the C
library's sin/cos may differ in the last bit, which a short, non-chaotic run amplifies by a
few orders of magnitude at most)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

from skewpend.numeric import kernels as K

from helpers import completed

ziglang = pytest.importorskip("ziglang")


def test_cc_wins_then_the_system_compiler_then_the_packaged_one(monkeypatch, tmp_path):
    monkeypatch.setenv("CC", "my-cc --flag 'a b'")
    assert K.find_compiler() == ["my-cc", "--flag", "a b"]
    monkeypatch.delenv("CC")
    monkeypatch.setenv("PATH", str(tmp_path))  # nothing on it
    assert K.find_compiler() == [sys.executable, "-m", "ziglang", "cc"]
    assert K.compiler_name(K.find_compiler()) == "zig cc (ziglang)"
    (tmp_path / "gcc").write_text("#!/bin/sh\n")
    (tmp_path / "gcc").chmod(0o755)
    assert K.find_compiler() == [str(tmp_path / "gcc")]


def test_without_any_compiler_the_message_says_what_to_install(monkeypatch, tmp_path):
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.setattr(K, "packaged_compiler", lambda: None)
    with pytest.raises(K.CompilerError, match="install gcc or clang .*'pip install ziglang'.*or set CC"):
        K.find_compiler()


def _no_compiler_env(tmp_path) -> dict:
    path = tmp_path / "bin"
    path.mkdir()
    env = {"PATH": str(path), "SKEWPEND_CACHE_DIR": str(tmp_path / "cache"), "HOME": os.environ.get("HOME", str(tmp_path))}
    assert not any(shutil.which(n, path=str(path)) for n in ("cc", "gcc", "clang"))
    return env


@pytest.mark.slow
def test_every_command_works_without_a_system_compiler(tmp_path):
    """The smoke set of issue 16 with no cc/gcc/clang on PATH, CC unset, an empty kernel cache:
    simulate, flipmap, lyapunov and simulate --method taylor build every kind of kernel (the model's,
    the flip map's, the chaos one -- all a report loads -- and a Taylor order's), each by zig cc, and say so.
    (The report itself ran here too until the suite was halved: 20 s of SymPy and figures that do not
    touch the compiler; a first report without a compiler is timed by benchmarks/bench_first_use.py.)"""
    env = _no_compiler_env(tmp_path)
    saved = os.environ.pop("CC", None)
    try:
        for argv in (["simulate", "--method", "dop853", "--t-end", "2", "--out", "run.csv"], ["flipmap", "--n", "16", "--t-end", "3"],
                     ["lyapunov", "--t-end", "20"], ["simulate", "--method", "taylor", "--t-end", "1"]):
            r = completed(argv, tmp_path, env=env, timeout=600)
            assert r.returncode == 0, (argv, r.stderr)
            assert "compiling the" in r.stderr  # the first-use notice (a build takes seconds)
    finally:
        if saved is not None:
            os.environ["CC"] = saved
    records = sorted((tmp_path / "cache" / "kernels").glob("*.compiler"))
    kinds = {re.sub(r"^skewpend_[0-9a-f]+", "", re.sub(r"\d+$", "", p.stem)) for p in records}
    assert kinds == {"", "_flip", "_chaos", "_taylor"}, kinds  # the simulation, flip, chaos and a Taylor order's
    assert {p.read_text().strip() for p in records} == {"zig cc (ziglang)"}
    assert (tmp_path / "run.csv").exists()


@pytest.mark.slow
def test_the_packaged_compiler_gives_the_system_compilers_results(tmp_path):
    system = next((shutil.which(n) for n in ("cc", "gcc", "clang") if shutil.which(n)), None)
    if system is None:
        pytest.skip("no system C compiler to compare with")
    code = (
        "import sys, numpy as np, skewpend as s, warnings\n"
        "warnings.simplefilter('ignore')\n"
        "p = s.reference_parameters()\n"
        "tr = s.simulate(p, (0.5, -0.3, 0.0, 0.0), 2.0, dt_out=0.1)\n"
        "fm = s.flip_map(p, 24, t_end=3.0)\n"
        "ly = s.lyapunov(p, (0.5, -0.3, 0.0, 0.0), t_end=50.0)\n"
        "np.savez(sys.argv[1], y=tr.y, flip=fm.flip_time, lam=ly.exponents, compiler=tr.stats['compiler'])\n"
    )
    out = {}
    for name in ("system", "zig"):
        (tmp_path / name).mkdir()
        env = {"CC": system} if name == "system" else _no_compiler_env(tmp_path / name)
        if name == "zig":  # a cache of its own; the system compiler's libraries are the test session's (built once)
            env["SKEWPEND_CACHE_DIR"] = str(tmp_path / name / "cache")
        full = {**{k: v for k, v in os.environ.items() if k != "CC"}, **env}
        proc = subprocess.run([sys.executable, "-c", code, str(tmp_path / f"{name}.npz")], env=full,
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr
        out[name] = np.load(tmp_path / f"{name}.npz")
    assert str(out["zig"]["compiler"]) == "zig cc (ziglang)" and str(out["system"]["compiler"]) == system
    # a regular 2 s run at rtol 1e-10: last-bit differences of sin/cos stay far below 1e-9
    np.testing.assert_allclose(out["zig"]["y"], out["system"]["y"], rtol=0, atol=1e-9)
    a, b = out["zig"]["flip"], out["system"]["flip"]
    assert np.array_equal(np.isnan(a), np.isnan(b))  # the same cells flip (3 s, far from the boundaries' scale)
    np.testing.assert_allclose(a[~np.isnan(a)], b[~np.isnan(b)], rtol=0, atol=1e-6)
    np.testing.assert_allclose(out["zig"]["lam"], out["system"]["lam"], rtol=0, atol=1e-6)


_HANDSHAKE_CC = """#!/bin/sh
# a compiler that waits (up to 60 s) until a second build has started, then compiles
d="{marks}"
touch "$d/start.$$"
i=0
while [ "$(ls "$d" | grep -c '^start[.]')" -lt 2 ] && [ $i -lt 600 ]; do sleep 0.1; i=$((i + 1)); done
[ $i -ge 600 ] && touch "$d/alone.$$"
exec {real} "$@"
"""


def test_two_libraries_build_side_by_side_and_one_library_once(tmp_path):
    """One lock per library (issue 28, the cold report): the model's kernel and the chaos kernel,
    asked for by two threads, compile at the same time -- each compiler run waits for the other
    to start, so builds one after the other would wait 60 s and leave a mark -- while a third
    thread asking for the model's kernel again waits for that build instead of starting its own."""
    import shlex

    marks = tmp_path / "marks"
    marks.mkdir()
    cc = tmp_path / "handshake-cc"
    cc.write_text(_HANDSHAKE_CC.format(marks=marks, real=" ".join(shlex.quote(x) for x in K.find_compiler())))
    cc.chmod(0o755)
    code = (
        "import threading, skewpend\n"
        "from skewpend.numeric.kernels import kernel_module\n"
        "p = skewpend.Parameters(a=1.0, b=0.8, m1=1.0, m2=0.5, alpha=0.7, g=9.81)\n"
        "got = {}\n"
        "jobs = {'model': lambda: kernel_module(p), 'chaos': lambda: kernel_module(p, chaos=True),\n"
        "        'model again': lambda: kernel_module(p)}\n"
        "threads = [threading.Thread(target=lambda k=k, f=f: got.__setitem__(k, f())) for k, f in jobs.items()]\n"
        "[t.start() for t in threads]; [t.join() for t in threads]\n"
        "assert got['model'] is got['model again'] and got['chaos'] is not got['model']\n"
        "print(got['model'].origin, got['chaos'].origin)\n"
    )
    env = {**os.environ, "CC": str(cc), "SKEWPEND_CACHE_DIR": str(tmp_path / "cache"), "SKEWPEND_QUIET": "1"}
    r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["compiled", "compiled"]
    names = sorted(x.name.split(".")[0] for x in marks.iterdir())
    assert names == ["start", "start"], names  # two builds, neither alone


@pytest.mark.slow
def test_taylor_bits_are_the_same_with_or_without_fma_hardware_and_with_either_compiler(tmp_path, monkeypatch):
    """The Taylor kernels fuse each product with its addition by explicit ``fma`` calls (issue 28),
    never by contraction: ``fma`` is correctly rounded, so the processor's instruction (-mfma), the C
    library's routine (no flag: what a processor without the instruction runs) and the packaged zig cc
    give the same bits -- checked here on a chaotic run, where any difference in one rounding would
    grow to the last digits."""
    import ctypes

    from skewpend import Parameters
    from skewpend.numeric import simulation
    from skewpend.numeric.taylor_source import exact_system, taylor_c_source

    P = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
    order, step_l = K.taylor_rule(1e-9)
    source = taylor_c_source(exact_system(K.geometry_of(P)), order)
    p = K.parameter_vector(P)
    fused, fma = K.fused_multiply_add()
    system = K.find_compiler()
    variants = [("system, no flag", system, ()), ("zig cc, no flag", list(K.packaged_compiler()), ())]
    if fused and fma:
        variants += [("system, -mfma", system, fma), ("zig cc, -mfma", list(K.packaged_compiler()), fma)]
    results = {}
    for i, (name, cc, flags) in enumerate(variants):
        monkeypatch.setenv("CC", " ".join(cc))
        path = tmp_path / f"taylor{i}{K.LIB_SUFFIX}"
        K._compile(source, path, flags)
        fn = simulation._rows_fn(K.TaylorKernel(path, "compiled", 0.0, order))
        s, m, cap = K.TaylorState(), ctypes.c_int64(0), 4096
        cols, e, acc = np.empty(6 * cap), np.empty(cap), np.zeros(4)
        y0 = (ctypes.c_double * 4)(1.2, -0.8, 0.0, 0.0)
        rc = fn(ctypes.addressof(s), ctypes.addressof(y0), p.ctypes.data, 5.0, 1e-9, 1e-9, step_l, 10**6, 10**6,
                cols.ctypes.data, cap, e.ctypes.data, acc.ctypes.data, ctypes.byref(m))
        k = m.value
        assert rc == 0 and k > 50
        results[name] = np.concatenate([cols[:k], cols[cap:cap + 4 * k], e[:k]])
    first = next(iter(results.values()))
    for name, r in results.items():
        assert r.shape == first.shape and np.array_equal(r, first), name


@pytest.mark.slow
def test_taylor_without_fused_multiply_add_agrees_to_rounding(tmp_path):
    """A processor without fused multiply-add gets Taylor kernels that round each product and sum
    (``taylor_c_source(..., fused=False)``): the same steps' values to rounding on a regular swing
    (non-chaotic: rounding differences stay near 1e-14 over 2 s; 1e-11 allowed), other bits."""
    import ctypes

    from skewpend import Parameters
    from skewpend.numeric import simulation
    from skewpend.numeric.taylor_source import exact_system, taylor_c_source

    P = Parameters(a=1.0, b=0.8, m1=1.0, m2=0.7, alpha=0.6, g=9.81)
    order, step_l = K.taylor_rule(1e-9)
    p = K.parameter_vector(P)
    out = []
    for fused in (True, False):
        source = taylor_c_source(exact_system(K.geometry_of(P)), order, fused=fused)
        assert f"#define SP_FUSED {int(fused)}" in source
        path = tmp_path / f"taylor_fused{int(fused)}{K.LIB_SUFFIX}"
        K._compile(source, path, K.fused_multiply_add()[1] if fused else ())
        fn = simulation._rows_fn(K.TaylorKernel(path, "compiled", 0.0, order))
        s, m, cap = K.TaylorState(), ctypes.c_int64(0), 4096
        cols, e, acc = np.empty(6 * cap), np.empty(cap), np.zeros(4)
        y0 = (ctypes.c_double * 4)(0.7, -0.4, 0.3, -0.2)
        rc = fn(ctypes.addressof(s), ctypes.addressof(y0), p.ctypes.data, 2.0, 1e-9, 1e-9, step_l, 10**6, 10**6,
                cols.ctypes.data, cap, e.ctypes.data, acc.ctypes.data, ctypes.byref(m))
        k = m.value
        assert rc == 0
        out.append(np.column_stack([cols[:k], cols[cap:cap + 4 * k].reshape(k, 4)]))
    a, b = out
    assert a.shape == b.shape
    np.testing.assert_allclose(b, a, rtol=0, atol=1e-11)
    assert not np.array_equal(a, b)  # a code path of its own
