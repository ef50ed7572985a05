"""First use as a whole process: `skewpend simulate` cold and warm against heyoka.py, side by side.

Case (issue 3): a=1, b=0.8, m1=1, m2=0.7, alpha=0.6, g=9.81, y0=(1.2, -0.8, 0, 0), 20 s,
skewpend's default method at rtol = atol = 1e-10 (the built-in defaults of `skewpend simulate`: method
auto, which picks taylor for this run since issue 36; dop853 before),
heyoka's Taylor integrator at tol = 1e-10. Every number is the wall time of a whole new
process (interpreter start-up, imports, compilation or cache loading, integration, output),
measured with time.perf_counter around subprocess.run, stdout and stderr captured.

* skewpend cold: `skewpend simulate` with an EMPTY kernel cache -- SKEWPEND_CACHE_DIR,
  NUMBA_CACHE_DIR and XDG_CACHE_HOME point to fresh temporary directories for every run, so
  the model code is generated (SymPy) and compiled (by whatever backend the installed skewpend
  uses); the benchmark prints how much each cache directory received.
* skewpend warm: the same with a cache populated by one prior (untimed) run.
* heyoka cold / warm: a Python script, written to a temporary file by this benchmark, that builds
  the same system with heyoka and integrates it over 20 s. heyoka JIT-compiles the Taylor
  integrator with LLVM; it keeps an in-memory cache per process and -- at least in heyoka.py
  7.13 (hy.llvm_state.get_diskcache_enabled/_path/_size) -- an on-disk cache of the compiled
  code, enabled by default, under $XDG_CACHE_HOME/heyoka (~/.cache/heyoka). So, as
  for skewpend: cold = XDG_CACHE_HOME points to a fresh temporary directory for
  every run; warm = the same directory, populated by one prior (untimed) run. The script reports
  heyoka's disk-cache path and size, so the benchmark can show which case actually happened.

The heyoka equations are not typed by hand: they come from skewpend's derivation
(skewpend.derive -> SymPy M(q) and f(q, q')), printed as text in THIS process (floats at full
double precision) and the 2x2 system M q'' = f solved explicitly in the generated script,
q'' = [M22 f1 - M12 f2, M11 f2 - M21 f1] / det M. So the timed heyoka process imports neither
SymPy nor skewpend -- only heyoka.

Neither cold case clears the operating system's file cache or Python's .pyc files; cold means
"no compiled code for this model in the tool's own caches".

The final states are compared (skewpend prints its final state with 12 significant digits).
The motion is chaotic: over 20 s each integrator's 1e-10 local error grows to 1e-6..1e-4, so the
two timed runs differ by about that much. To check that heyoka integrates the SAME equations,
two untimed runs follow: skewpend at rtol = atol = 1e-14 and heyoka at machine epsilon (its
default, used as the reference); these must agree to 1e-6. Each run's error against the
reference is printed.

Goals (first use): skewpend cold <= 2.5 s, skewpend warm <= 0.6 s.

Run:  python benchmarks/bench_first_use.py [--repeat-warm 5] [--repeat-cold 3]
      (--repeat N sets both). heyoka is optional: pip install heyoka

--no-compiler (issue 28, goal 5): a new user's first minute on a machine WITHOUT a system C compiler,
as tests/test_compiler.py hides it: PATH is one empty directory (no cc, gcc or clang; the commands
are started by their full path), CC is unset, and HOME, XDG_CACHE_HOME and SKEWPEND_CACHE_DIR are
fresh empty directories for every run (so the packaged zig cc's own cache, ~/.cache/zig, and
matplotlib's font cache start empty too, as on a new machine). Measured, --repeat-cold times each,
interleaved: the first `skewpend simulate` (goal <= 5 s) and the first `skewpend report -q`
(goal <= 30 s), each in its own fresh home; then, in the same home as that first simulate, a
`skewpend report` (the model's kernel already built: the report's other kernels and SymPy only).
Each run's stderr (a pipe here, as in a script or CI) is checked for the one-line notice
"compiling the model's kernels (first use only...)" (after a simulate: for any kind's notice);
every kind's notice, the compiler each kernel recorded and the report's own timings (section 10)
are printed.
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

A, B, M1, M2, ALPHA, G = 1.0, 0.8, 1.0, 0.7, 0.6, 9.81
Y0 = (1.2, -0.8, 0.0, 0.0)
T_END = 20.0
TOL = 1e-10
GOALS = {"skewpend cold": 2.5, "skewpend warm": 0.6}
NO_COMPILER_GOALS = {"first simulate": 5.0, "first report": 30.0}  # issue 28, goal 5
NOTICE = "compiling the model's kernels (first use only"
NOTICE_RE = re.compile(r"compiling the (.+?) kernels \(first use only")  # every kind's one-line notice
AGREEMENT = 1e-6
CHECK_RTOL = 1e-14  # skewpend's tight run for the agreement check (untimed)
REF_TOL = sys.float_info.epsilon  # heyoka's default tolerance: the reference (untimed)
TIMEOUT = 900.0
NAMES = ("phi", "psi", "dphi", "dpsi")
STATE_RE = re.compile(r"(?<![A-Za-z_])(phi|psi|dphi|dpsi)=([-+]?(?:[0-9.]+(?:[eE][-+]?[0-9]+)?|nan|inf))")


# ----------------------------------------------------------------------------- helpers


def skewpend_command() -> list[str]:
    exe = Path(sys.executable).parent / ("skewpend.exe" if os.name == "nt" else "skewpend")
    if exe.exists():
        return [str(exe), "simulate"]
    return [sys.executable, "-m", "skewpend", "simulate"]


from _common import cpu_model, print_report_timings, version  # noqa: E402  (benchmarks/ is on sys.path when run)


def base_env() -> dict[str, str]:
    env = dict(os.environ)
    for key in ("SKEWPEND_CACHE_DIR", "NUMBA_CACHE_DIR", "XDG_CACHE_HOME"):
        env.pop(key, None)
    return env


def cache_env(root: Path) -> dict[str, str]:
    """Environment whose every cache (skewpend kernels, numba, XDG/HOME caches, heyoka) is under root."""
    env = base_env()
    for sub in ("skewpend", "numba", "xdg"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    env["SKEWPEND_CACHE_DIR"] = str(root / "skewpend")
    env["NUMBA_CACHE_DIR"] = str(root / "numba")
    env["XDG_CACHE_HOME"] = str(root / "xdg")  # heyoka's disk cache: $XDG_CACHE_HOME/heyoka
    # HOME is left alone (a user-site install under ~/.local must stay visible); the heyoka
    # script prints its disk-cache path and the benchmark checks that it lies under root.
    return env


def run_timed(cmd: list[str], env: dict[str, str], what: str) -> tuple[float, subprocess.CompletedProcess]:
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=TIMEOUT)
    dt = time.perf_counter() - t0
    if proc.returncode != 0:
        raise RuntimeError(
            f"{what} failed (exit status {proc.returncode}): {' '.join(cmd)}\n"
            f"--- stdout ---\n{proc.stdout}\n--- stderr ---\n{proc.stderr}"
        )
    return dt, proc


def final_state(stdout: str) -> tuple[float, ...] | None:
    for line in stdout.splitlines():
        if line.lstrip().startswith("final state"):
            found = dict(STATE_RE.findall(line))
            if all(n in found for n in NAMES):
                return tuple(float(found[n]) for n in NAMES)
    return None


def wait_for_background(kernels: Path, limit: float = 300.0) -> float:
    """Seconds until no background build's marker (``.skewpend_*.building``) is left in ``kernels``."""
    start = time.perf_counter()
    while list(kernels.glob(".skewpend_*.building")) and time.perf_counter() - start < limit:
        time.sleep(0.05)
    return time.perf_counter() - start


def dir_bytes(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file()) if path.exists() else 0


# ----------------------------------------------------------------------------- heyoka script


def heyoka_script() -> str:
    """The heyoka program, its equations printed from skewpend's derivation (SymPy stays here)."""
    import sympy
    from sympy.printing.str import StrPrinter

    import skewpend
    from skewpend.symbolic.derivation import SYMBOLS

    params = skewpend.Parameters(
        a=A, b=B, m1=M1, m2=M2, alpha=ALPHA, g=G, c1=0.0, c2=0.0, tau1=0.0, tau2=0.0
    )
    eom = skewpend.derive(params)
    M, f = eom.mass_matrix, eom.forcing
    state = {SYMBOLS[n] for n in NAMES}
    allowed_functions = {sympy.sin, sympy.cos}

    class HeyokaPrinter(StrPrinter):
        def _print_Float(self, expr):  # full double precision (str() would keep 15 digits)
            return repr(float(expr))

        def _print_Rational(self, expr):  # exact p/q, evaluated by Python in double precision
            return f"({expr.p}/{expr.q})" if expr.q != 1 else str(expr.p)

    printer = HeyokaPrinter({"full_prec": True})

    def text(expr) -> str:
        expr = sympy.sympify(expr)
        extra = expr.free_symbols - state
        if extra:
            raise ValueError(f"equations still contain the symbols {sorted(map(str, extra))}")
        functions = {type(fn) for fn in expr.atoms(sympy.Function)}
        if not functions <= allowed_functions:
            raise ValueError(f"no heyoka translation for {sorted(map(str, functions - allowed_functions))}")
        return printer.doprint(expr)

    return f'''\
# Generated by benchmarks/bench_first_use.py from skewpend {skewpend.__version__}'s derivation
# (skewpend.derive: M(q) q'' = f(q, q')); a=1 b=0.8 m1=1 m2=0.7 alpha=0.6 g=9.81, no damping.
import sys

import heyoka as hy

TOL = float(sys.argv[1]) if len(sys.argv) > 1 else {TOL!r}
phi, psi, dphi, dpsi = hy.make_vars("phi", "psi", "dphi", "dpsi")
sin, cos = hy.sin, hy.cos

M11 = {text(M[0, 0])}
M12 = {text(M[0, 1])}
M21 = {text(M[1, 0])}
M22 = {text(M[1, 1])}
f1 = {text(f[0])}
f2 = {text(f[1])}

det = M11 * M22 - M12 * M21
ddphi = (M22 * f1 - M12 * f2) / det
ddpsi = (M11 * f2 - M21 * f1) / det

ta = hy.taylor_adaptive(
    [(phi, dphi), (psi, dpsi), (dphi, ddphi), (dpsi, ddpsi)],
    {list(Y0)!r},
    tol=TOL,
)
res = ta.propagate_until({T_END!r})
outcome, nsteps = res[0], res[3]
if outcome != hy.taylor_outcome.time_limit:
    raise SystemExit(f"heyoka: integration stopped early: {{outcome}} at t={{ta.time}}")
y = [float(v) for v in ta.state]
print(f"final state   t={{ta.time:g}} s  phi={{y[0]!r}}  psi={{y[1]!r}}  dphi={{y[2]!r}}  dpsi={{y[3]!r}}")
print(f"steps         {{nsteps}}  (Taylor order {{ta.order}}, tol {{ta.tol:g}})")
try:
    s = hy.llvm_state
    print(f"diskcache     enabled={{s.get_diskcache_enabled()}} path={{s.get_diskcache_path()}} bytes={{s.get_diskcache_size()}}")
except AttributeError:
    print("diskcache     none (this heyoka has only the in-memory cache)")
'''


# ----------------------------------------------------------------------------- no system compiler


def no_compiler_env(root: Path) -> dict[str, str]:
    """A new user's environment without a system compiler: PATH one empty directory, CC unset, and a
    fresh HOME, XDG_CACHE_HOME and SKEWPEND_CACHE_DIR under root (as tests/test_compiler.py)."""
    env = {k: v for k, v in base_env().items() if k not in ("CC", "HOME", "MPLCONFIGDIR")}
    for sub in ("bin", "home", "home/.cache"):
        (root / sub).mkdir(parents=True, exist_ok=True)
    if any(shutil.which(n, path=str(root / "bin")) for n in ("cc", "gcc", "clang")):
        raise SystemExit("the empty PATH directory has a C compiler in it")
    env.update(PATH=str(root / "bin"), HOME=str(root / "home"), XDG_CACHE_HOME=str(root / "home" / ".cache"),
               SKEWPEND_CACHE_DIR=str(root / "skewpend"))
    return env


def no_compiler(repeat: int, keep: bool) -> int:
    from bench_report import timings  # section 10's table of a report

    sk = skewpend_command()[:-1]  # the executable (started by its full path: PATH has nothing)
    print("machine")
    print(f"  cpu        {cpu_model()}")
    print(f"  nproc      {len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else os.cpu_count()}")
    print(f"  platform   {platform.platform()}")
    print(f"  python     {platform.python_version()}   skewpend {version('skewpend')}   ziglang {version('ziglang')}   "
          f"sympy {version('sympy')}   matplotlib {version('matplotlib')}")
    print(f"  command    {' '.join(sk)}")
    print(f"  load       {' '.join(f'{x:.2f}' for x in os.getloadavg())} at the start (1, 5, 15 min; the machine "
          "may be shared)")
    print(f"no system compiler: PATH = an empty directory, CC unset, fresh HOME and caches for every run; "
          f"{repeat} runs each, interleaved (median reported)\n", flush=True)
    work = Path(tempfile.mkdtemp(prefix="skewpend-bench-no-compiler-"))
    times: dict[str, list[float]] = {}
    notices: dict[str, list[bool]] = {}
    tables: dict[str, dict[str, float]] = {}
    compilers: set[str] = set()
    builds: list[str] = []

    def once(case: str, root: Path, args: list[str]) -> None:
        dt, proc = run_timed(sk + args, no_compiler_env(root), case)
        times.setdefault(case, []).append(dt)
        kinds = NOTICE_RE.findall(proc.stderr)
        notices.setdefault(case, []).append(NOTICE in proc.stderr or (bool(kinds) and "after" in case))
        for line in (proc.stdout + proc.stderr).splitlines():
            if line.startswith("kernel") and "compiled" in line:
                builds.append(f"{case}: {line.split(None, 1)[1]}")
        for rec in (root / "skewpend").rglob("*.compiler"):
            compilers.add(rec.read_text().strip())
        other = [ln for ln in proc.stderr.splitlines() if ln.strip() and not NOTICE_RE.search(ln)]
        print(f"  {case:<28} {dt:7.2f} s   notices on stderr (a pipe): {', '.join(kinds) or 'NONE'}"
              + (f"   other stderr: {' | '.join(other)[:200]}" if other else ""), flush=True)

    try:
        for i in range(repeat):
            once("first simulate", work / f"sim-{i}", ["simulate"])
            once("report after that simulate", work / f"sim-{i}", ["report", "-q", "-o", str(work / "after.html")])
            tables["report after simulate"] = timings(work / "after.html")
            once("first report", work / f"rep-{i}", ["report", "-q", "-o", str(work / "first.html")])
            tables["first report"] = timings(work / "first.html")
    finally:
        if keep:
            print(f"\n(temporary directories kept in {work})")
        else:
            shutil.rmtree(work, ignore_errors=True)
    print(f"\n{'case':<30} {'n':>2} {'median s':>9} {'min s':>7} {'max s':>7}  notice  goal")
    failed = False
    for case, v in times.items():
        med = statistics.median(v)
        goal = ""
        if case in NO_COMPILER_GOALS:
            ok = med <= NO_COMPILER_GOALS[case]
            failed |= not ok
            goal = f"<= {NO_COMPILER_GOALS[case]:g} s  {'met' if ok else 'NOT met'}"
        seen = f"{sum(notices[case])}/{len(v)}"
        print(f"{case:<30} {len(v):>2} {med:>9.2f} {min(v):>7.2f} {max(v):>7.2f}  {seen:>6}  {goal}")
    print(f"\ncompilers recorded by the kernels: {', '.join(sorted(compilers)) or 'none'}")
    for line in dict.fromkeys(builds):
        print(f"  {line}")
    if tables:
        print_report_timings(tables, 24)
    print(f"\nload average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"goals: {'all met' if not failed else 'NOT all met'}")
    return 0


# ----------------------------------------------------------------------------- main


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=None, help="repetitions for both cold and warm")
    ap.add_argument("--repeat-warm", type=int, default=5, help="warm repetitions (default 5)")
    ap.add_argument("--repeat-cold", type=int, default=3, help="cold repetitions (default 3)")
    ap.add_argument("--keep", action="store_true", help="keep the temporary directories")
    ap.add_argument("--no-compiler", action="store_true",
                    help="a new user's first simulate and report with no system C compiler (issue 28, goal 5)")
    args = ap.parse_args()
    if args.no_compiler:
        return no_compiler(args.repeat if args.repeat is not None else args.repeat_cold, args.keep)
    n_warm = args.repeat if args.repeat is not None else args.repeat_warm
    n_cold = args.repeat if args.repeat is not None else args.repeat_cold
    if n_warm < 1 or n_cold < 1:
        ap.error("repetitions must be >= 1")

    try:
        import heyoka  # noqa: F401  (only to know whether it is there; never timed here)

        have_heyoka = True
    except ImportError:
        have_heyoka = False

    print("machine")
    print(f"  cpu        {cpu_model()}")
    affinity = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    print(f"  nproc      {affinity} (os.cpu_count {os.cpu_count()})")
    print(f"  platform   {platform.platform()}")
    print(f"  python     {platform.python_version()} ({sys.executable})")
    print(f"  skewpend   {version('skewpend')}   numba {version('numba')}   sympy {version('sympy')}")
    print(f"  heyoka     {version('heyoka')}")
    sk_cmd = skewpend_command()
    print(f"  command    {' '.join(sk_cmd)}")
    print(f"case: a={A} b={B} m1={M1} m2={M2} alpha={ALPHA} g={G}, y0={Y0}, t_end={T_END} s, tol {TOL:g}")
    print(f"repetitions: cold {n_cold}, warm {n_warm} (median reported)\n")

    work = Path(tempfile.mkdtemp(prefix="skewpend-bench-first-use-"))
    times: dict[str, list[float]] = {}
    states: dict[str, tuple[float, ...]] = {}
    notes: list[str] = []
    errors: dict[str, str] = {}  # tool -> first failure; a failed tool is not run again

    def measure(tool: str, case: str | None, cmd: list[str], env: dict[str, str]):
        """Run once (timed into times[case] unless case is None); None if the tool failed."""
        if tool in errors:
            return None
        try:
            dt, proc = run_timed(cmd, env, case or tool)
        except (RuntimeError, subprocess.TimeoutExpired, OSError) as exc:
            errors[tool] = str(exc)
            print(f"  {tool}: FAILED ({str(exc).splitlines()[0]})", flush=True)
            return None
        if case is not None:
            times.setdefault(case, []).append(dt)
        return dt, proc

    try:
        hy_cmd = None
        if have_heyoka:
            t0 = time.perf_counter()
            script = work / "heyoka_case.py"
            try:
                script.write_text(heyoka_script())
                hy_cmd = [sys.executable, str(script)]
                print(f"heyoka script generated from skewpend.derive in {time.perf_counter() - t0:.2f} s "
                      f"(not timed): {script}")
            except Exception as exc:  # skewpend.derive itself failing must not hide the timings
                errors["heyoka"] = f"could not generate the heyoka script from skewpend.derive: {exc!r}"
                print(errors["heyoka"])
        else:
            print("heyoka is not installed: measuring skewpend only.")
            print("  install it with:  pip install heyoka   (or: conda install -c conda-forge heyoka.py)")
        print(flush=True)

        # --- cold: a fresh cache root for every run, skewpend and heyoka interleaved
        for i in range(n_cold):
            root = work / f"cold-skewpend-{i}"
            r = measure("skewpend", "skewpend cold", sk_cmd, cache_env(root))
            if r:
                states.setdefault("skewpend", final_state(r[1].stdout))
                if dir_bytes(root / "skewpend") == 0:
                    notes.append("skewpend cold run left SKEWPEND_CACHE_DIR empty (no kernel cache written?)")
                print(f"  skewpend cold #{i + 1}: {r[0]:6.2f} s   caches written: SKEWPEND_CACHE_DIR "
                      f"{dir_bytes(root / 'skewpend')} B, NUMBA_CACHE_DIR {dir_bytes(root / 'numba')} B, "
                      f"XDG_CACHE_HOME {dir_bytes(root / 'xdg')} B", flush=True)
                # since issue 51 the first run takes dop853 and a detached process builds the Taylor library:
                # wait for it (it would load the next run's machine) and say when it was ready
                ready = wait_for_background(root / "skewpend" / "kernels")
                method = "taylor" if "method        taylor" in r[1].stdout else "dop853"
                print(f"      (this run: {method}; the Taylor library built in the background, ready "
                      f"{ready:.1f} s after the run ended)", flush=True)
            if hy_cmd:
                root = work / f"cold-heyoka-{i}"
                r = measure("heyoka", "heyoka cold", hy_cmd, cache_env(root))
                if r:
                    states.setdefault("heyoka", final_state(r[1].stdout))
                    disk = [ln for ln in r[1].stdout.splitlines() if ln.startswith("diskcache")]
                    if disk and "path=" in disk[0] and f"path={root}" not in disk[0]:
                        notes.append("heyoka's disk cache is NOT under the fresh XDG_CACHE_HOME: 'cold' may be warm")
                    print(f"  heyoka cold   #{i + 1}: {r[0]:6.2f} s   {disk[0].split(None, 1)[1] if disk else ''}",
                          flush=True)

        # --- warm: one cache root each, populated by one untimed run
        sk_env = cache_env(work / "warm-skewpend")
        measure("skewpend", None, sk_cmd, sk_env)
        hy_env = cache_env(work / "warm-heyoka")
        if hy_cmd:
            measure("heyoka", None, hy_cmd, hy_env)
        hy_out = ""
        for i in range(n_warm):
            r = measure("skewpend", "skewpend warm", sk_cmd, sk_env)
            if r:
                warm, cold = final_state(r[1].stdout), states.get("skewpend")
                if warm is None or cold is None or max(abs(a - b) for a, b in zip(warm, cold)) > 1e-3:
                    # cold: dop853 (the Taylor library builds in the background), warm: taylor, both at 1e-10;
                    # over 20 s of chaos their difference grows to 1e-6..1e-4
                    notes.append("skewpend warm final state differs from the cold one by more than 1e-3")
                print(f"  skewpend warm #{i + 1}: {r[0]:6.2f} s", flush=True)
            if hy_cmd:
                r = measure("heyoka", "heyoka warm", hy_cmd, hy_env)
                if r:
                    hy_out = r[1].stdout
                    disk = [ln for ln in hy_out.splitlines() if ln.startswith("diskcache")]
                    print(f"  heyoka warm   #{i + 1}: {r[0]:6.2f} s   {disk[0].split(None, 1)[1] if disk else ''}",
                          flush=True)
        if hy_out:
            print("\nheyoka output (last warm run):")
            print("  " + hy_out.strip().replace("\n", "\n  "))

        # --- reference rows: interpreter start-up and bare imports (warm file cache)
        imports = [("python -c pass", "pass")]
        if hy_cmd:
            imports.append(("import heyoka", "import heyoka"))
        for label, code in imports:
            for _ in range(n_warm):
                measure(label, label, [sys.executable, "-c", code], base_env())

        # --- accuracy (untimed): skewpend at a tight tolerance, heyoka at machine epsilon
        tight = [f"--rtol={CHECK_RTOL:g}", f"--atol={CHECK_RTOL:g}"]
        r = measure("skewpend", None, sk_cmd + tight, sk_env)
        if r:
            states["skewpend tight"] = final_state(r[1].stdout)
        if hy_cmd:
            r = measure("heyoka", None, hy_cmd + [repr(REF_TOL)], hy_env)
            if r:
                states["heyoka reference"] = final_state(r[1].stdout)
    finally:
        if args.keep:
            print(f"\n(temporary directories kept in {work})")
        else:
            shutil.rmtree(work, ignore_errors=True)

    # --- table
    med = {k: statistics.median(v) for k, v in times.items()}
    ref = med.get("heyoka warm")
    order = ["skewpend cold", "skewpend warm", "heyoka cold", "heyoka warm", "python -c pass", "import heyoka"]
    reference_rows = {"python -c pass", "import heyoka"}
    print()
    print(f"{'case':<16} {'n':>2} {'median s':>9} {'min s':>7} {'max s':>7} {'x heyoka warm':>14}  goal")
    print("-" * 72)
    failed = False
    for case in order:
        if case not in med:
            if case in GOALS:
                failed = True
                print(f"{case:<16} {0:>2} {'-':>9} {'-':>7} {'-':>7} {'-':>14}  <= {GOALS[case]} s  FAIL (not measured)")
            continue
        ratio = f"{med[case] / ref:.2f}" if ref else "-"
        goal = ""
        if case in GOALS:
            ok = med[case] <= GOALS[case]
            failed |= not ok
            goal = f"<= {GOALS[case]} s  {'PASS' if ok else 'FAIL'}"
        label = case + ("*" if case in reference_rows else "")
        v = times[case]
        print(f"{label:<16} {len(v):>2} {med[case]:>9.3f} {min(v):>7.3f} {max(v):>7.3f} {ratio:>14}  {goal}")
    print("* for reference: interpreter start-up alone, and `python -c \"import heyoka\"`")

    # --- final states and their agreement
    rows = [
        ("skewpend default 1e-10 (timed)", states.get("skewpend")),
        ("heyoka taylor 1e-10 (timed)", states.get("heyoka")),
        (f"skewpend default {CHECK_RTOL:g} (check)", states.get("skewpend tight")),
        (f"heyoka taylor {REF_TOL:.2g} (reference)", states.get("heyoka reference")),
    ]
    ref_state = states.get("heyoka reference")
    print()
    print(f"final state at t = {T_END:g} s" + (f"; error = max |state - heyoka at {REF_TOL:.2g}|" if ref_state else ""))
    print(f"{'':<36}" + "".join(f"{n:>18}" for n in NAMES) + ("     error" if ref_state else ""))
    for label, st in rows:
        if label.startswith("heyoka") and not have_heyoka:
            continue
        if st is None:
            tool = label.split()[0]
            why = "failed, see ERROR below" if tool in errors else "no 'final state' line in its output"
            print(f"{label:<36}  ({why})")
            continue
        err = f"  {max(abs(a - b) for a, b in zip(st, ref_state)):8.1e}" if ref_state else ""
        print(f"{label:<36}" + "".join(f"{x:>18.12g}" for x in st) + err)

    def compare(label, s1, s2):
        if s1 is None or s2 is None:
            return None
        diff = [b - a for a, b in zip(s1, s2)]
        worst = max(abs(d) for d in diff)
        print(f"{label}: " + "  ".join(f"{n} {d:+.1e}" for n, d in zip(NAMES, diff)) + f"   max {worst:.1e}")
        return worst

    if have_heyoka:
        print()
        compare("heyoka 1e-10 - skewpend 1e-10 (the timed runs)", states.get("skewpend"), states.get("heyoka"))
        worst = compare(
            f"heyoka {REF_TOL:.2g} - skewpend {CHECK_RTOL:g} (same equations?)",
            states.get("skewpend tight"), states.get("heyoka reference"),
        )
        if worst is not None:
            ok = math.isfinite(worst) and worst <= AGREEMENT
            print(f"  -> the two agree to {AGREEMENT:g}: {'yes' if ok else 'NO'}"
                  "  (the motion is chaotic: at 1e-10 each run's own error is amplified to the size above)")
    for note in dict.fromkeys(notes):
        print("note:", note)
    for tool, message in errors.items():
        print(f"\nERROR: {tool} failed, its rows are missing or incomplete:\n{message}")
    print(f"\ngoals: {'all met' if not failed else 'NOT all met'}")
    return 1 if errors else 0  # a missed goal is a result, not an error of the benchmark


if __name__ == "__main__":
    sys.exit(main())
