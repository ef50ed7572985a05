"""Compiled kernels: the generated C for a model, compiled once and cached on disk.

This module does not import SymPy: when the shared library for a model's bodies and axes
is in the cache, a new process loads it with :mod:`ctypes` in about a millisecond.  On a
miss, :mod:`skewpend.numeric.kernel_source` prints the model's C from the derivation, the integrator
template ``integrators.c`` is appended, and a C compiler builds it: ``$CC``, else the system's
``cc``, ``gcc`` or ``clang`` (a fraction of a second), else the packaged ``zig cc`` of the
``ziglang`` wheel (a dependency: no system compiler needed; about 2 s per kernel, 6 s the very
first time).  Each cached library records which compiler built it (``.compiler`` beside it).

The cache repairs itself: a library whose recorded SHA-256 does not match, or that does
not load, is rebuilt; an unwritable cache directory falls back to a private temporary
one (with a warning).  ``$SKEWPEND_CACHE_DIR`` overrides the user cache directory.
"""

from __future__ import annotations

import ctypes
import hashlib
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import warnings
from functools import lru_cache
from pathlib import Path
from typing import Dict, Optional, Tuple

from .. import __version__
from ..errors import SkewpendError
from ..symbolic.model import Parameters
from .conventions import GEOMETRY, PARAMETER_ORDER, STATE_ORDER, geometry_of, optional_terms, parameter_vector, structure_of

__all__ = ["ControlStruct", "control_struct_type",
    "PARAMETER_ORDER",
    "STATE_ORDER",
    "geometry_of",
    "parameter_vector",
    "kernel_module",
    "cache_dir",
    "Kernel",
    "State",
    "LyapState",
    "lyap_state_type",
    "TaylorState",
    "TaylorKernel",
    "taylor_kernel",
    "taylor_order",
    "taylor_rule",
    "fused_multiply_add",
    "TAYLOR_L_BANDS",
    "CompilerError",
    "find_compiler",
    "LIB_SUFFIX",
    "packaged_compiler",
    "compiler_name",
    "built_by",
]

#: Files whose text determines the generated library (part of the cache key).
_SOURCES = (
    "numeric/kernel_source.py", "numeric/codegen.py", "numeric/conventions.py", "numeric/integrators.c", "numeric/chaos.c",
    "numeric/dop853_core.h", "numeric/rows.h", "numeric/shooting.c", "numeric/kernels.py", "status.py", "symbolic/derivation.py", "symbolic/kinematics.py",
    "symbolic/symbols.py", "numeric/recursive.py", "symbolic/chain.py",
)
_PACKAGE = Path(__file__).resolve().parent.parent
#: Compiler flags: no floating-point contraction, so results do not depend on FMA availability.
CFLAGS = ("-O2", "-fPIC", "-shared", "-ffp-contract=off", "-fno-fast-math")
SP_NMAX = 8
#: Shared libraries are named as the platform expects (``.dylib`` on macOS, ``.so`` elsewhere).
LIB_SUFFIX = ".dylib" if sys.platform == "darwin" else ".so"


class CompilerError(SkewpendError, RuntimeError):
    """No working C compiler, or the generated kernel did not compile."""


def cache_dir() -> Path:
    """Where compiled kernels are kept: ``$SKEWPEND_CACHE_DIR`` or the user cache directory."""
    env = os.environ.get("SKEWPEND_CACHE_DIR")
    if env:
        return Path(env)
    import platformdirs

    return Path(platformdirs.user_cache_dir("skewpend"))


def _state_at(cls, t0: float, y0):
    """A resumable state of ``cls`` (an integrator's mirror) at time ``t0`` and state ``y0``."""
    s = cls()
    s.t = float(t0)
    for i, v in enumerate(y0):
        s.y[i] = float(v)
    return s


@lru_cache(maxsize=None)
def state_type(nmax: int):
    """The mirror of ``sp_state`` (``integrators.c``) for states of at most ``nmax`` components
    (``SP_NMAX``: 8 for the double pendulum, ``2 n + 2`` for a chain of ``n`` links)."""

    class _State(ctypes.Structure):
        """Mirror of ``sp_state`` in ``integrators.c``: everything an integrator needs to resume."""

        _fields_ = [
            ("t", ctypes.c_double),
            ("h", ctypes.c_double),
            ("y", ctypes.c_double * nmax),
            ("f", ctypes.c_double * nmax),
            ("g", ctypes.c_double * nmax),
            ("comp", ctypes.c_double * nmax),
            ("told", ctypes.c_double),
            ("hseg", ctypes.c_double),
            ("yold", ctypes.c_double * nmax),
            ("F", ctypes.c_double * (7 * nmax)),
            ("nfev", ctypes.c_int64),
            ("naccept", ctypes.c_int64),
            ("nreject", ctypes.c_int64),
            ("step", ctypes.c_int64),
            ("started", ctypes.c_int32),
            ("have_f", ctypes.c_int32),
            ("dense_ok", ctypes.c_int32),
            ("aux", ctypes.c_int32),
        ]

        at = classmethod(_state_at)

    _State.__name__ = _State.__qualname__ = "State" if nmax == SP_NMAX else f"State{nmax}"
    return _State


State = state_type(SP_NMAX)


#: Mirror of ``SP_TN`` and ``SP_TPMAX`` in the Taylor kernel (:mod:`skewpend.numeric.taylor_source`).
SP_TN, SP_TPMAX = 5, 32


#: The step factor's exponent L of the Taylor rule by tolerance band (:func:`taylor_rule`): (the
#: smallest rtol of the band, L).  Jorba & Zou's (and heyoka's) L = 2 is the optimum when a step's cost
#: grows as p^2 (the series products); skewpend's generated series cost nearly linearly in p up to order
#: 16 (the fixed parts of a step -- sincos, the step rule, the polynomial, the row -- weigh as much as
#: the products), where larger steps at a higher order cost less for the same error: measured over
#: five motions (chaotic, regular, skewed, spinning; benchmarks/bench_taylor_rule.py), L = 1.5 down to
#: 1e-9 (orders <= 15) and 1.75 down to 1e-11 (orders 13-16) take 0.65x heyoka's time at equal error
#: (median; max 0.77x), against 0.70x (max 0.85x) with L = 2 throughout and the same series.
TAYLOR_L_BANDS = ((1e-9, 1.5), (1e-11, 1.75), (0.0, 2.0))


def taylor_rule(rtol: float) -> Tuple[int, float]:
    """The Taylor method's order p and step exponent L for a relative tolerance: L from
    :data:`TAYLOR_L_BANDS`, ``p = ceil(-ln(rtol) / L) + 1`` (at least 2, at most ``SP_TPMAX``); the
    step is ``rho exp(-L) exp(-0.7 / (p - 1))`` (``taylor.c``), so that the series' last terms
    estimate a local error of ``exp(-L (p - 1)) <= rtol`` (relative to max(1, |y|)).  Here, not in
    :mod:`~skewpend.numeric.taylor_source`, so that a run from cached kernels does not import SymPy."""
    for lowest, L in TAYLOR_L_BANDS:
        if rtol >= lowest:
            break
    return min(max(int(math.ceil(-math.log(rtol) / L)) + 1, 2), SP_TPMAX), L


def taylor_order(rtol: float) -> int:
    """The Taylor order for a relative tolerance (:func:`taylor_rule`'s p)."""
    return taylor_rule(rtol)[0]


def _taylor_fields(tn: int) -> list:
    """``sp_taylor_state``'s fields for a state of ``tn`` components (taylor.c's ``SP_TN``)."""
    return [
        ("t", ctypes.c_double),
        ("y", ctypes.c_double * tn),
        ("told", ctypes.c_double),
        ("hold", ctypes.c_double),
        ("jet", ctypes.c_double * (tn * (SP_TPMAX + 2))),
        ("nfev", ctypes.c_int64),
        ("naccept", ctypes.c_int64),
        ("nreject", ctypes.c_int64),
        ("order", ctypes.c_int64),
        ("started", ctypes.c_int32),
        ("dense_ok", ctypes.c_int32),
        ("work", ctypes.c_int32),
        ("pad", ctypes.c_int32),
    ]


@lru_cache(maxsize=None)
def taylor_state_type(tn: int):
    """The ctypes mirror of ``sp_taylor_state`` (``taylor.c``: a resumable Taylor run) for ``SP_TN = tn``
    (the double pendulum's 5, a chain of n links: 2 n + 1)."""
    name = "TaylorState" if tn == SP_TN else f"TaylorState{tn}"
    return type(name, (ctypes.Structure,), {"_fields_": _taylor_fields(tn), "at": classmethod(_state_at)})


TaylorState = taylor_state_type(SP_TN)


@lru_cache(maxsize=None)
def control_struct_type(nq: int):
    """The mirror of ``sp_control`` (``integrators.c``) for a model of ``nq`` coordinates (2 for the
    double pendulum, ``n`` for a chain of ``n`` links): the inputs applied inside the integrators
    (:mod:`skewpend.numeric.control` fills it)."""
    nx = 2 * nq

    class _Control(ctypes.Structure):
        """Mirror of ``sp_control`` in ``integrators.c``."""

        _fields_ = [
            ("kind", ctypes.c_int32),
            ("actuated", ctypes.c_int32),
            ("umax", ctypes.c_double * nq),
            ("K", ctypes.c_double * (nq * nx)),
            ("xs", ctypes.c_double * nx),
            ("us", ctypes.c_double * nq),
            ("ke", ctypes.c_double),
            ("kp", ctypes.c_double),
            ("kd", ctypes.c_double),
            ("E_target", ctypes.c_double),
            ("P", ctypes.c_double * (nx * nx)),
            ("rho", ctypes.c_double),
            ("n_table", ctypes.c_int64),
            ("table", ctypes.POINTER(ctypes.c_double)),
            ("callback", ctypes.c_void_p),
            ("dt_table", ctypes.c_double),
            ("hold", ctypes.c_double),
        ]

    _Control.__name__ = _Control.__qualname__ = "ControlStruct" if nq == 2 else f"ControlStruct{nq}"
    return _Control


#: The double pendulum's ``sp_control``.
ControlStruct = control_struct_type(2)


@lru_cache(maxsize=None)
def lyap_state_type(n2: int):
    """The mirror of ``sp_lyap_state`` (``chaos.c``) for states of ``n2`` components (4 for the double
    pendulum, ``2 n`` for a chain of ``n`` links): the state and up to ``n2`` tangent vectors."""
    vmax = n2 * (n2 + 1)

    class _LyapState(ctypes.Structure):
        """Mirror of ``sp_lyap_state`` in ``chaos.c``: a resumable Benettin run."""

        _fields_ = [
            ("t", ctypes.c_double),
            ("h", ctypes.c_double),
            ("t0", ctypes.c_double),
            ("every", ctypes.c_double),
            ("y", ctypes.c_double * vmax),
            ("f", ctypes.c_double * vmax),
            ("nfev", ctypes.c_int64),
            ("naccept", ctypes.c_int64),
            ("nreject", ctypes.c_int64),
            ("nrenorm", ctypes.c_int64),
            ("k", ctypes.c_int32),
            ("have_f", ctypes.c_int32),
            ("pad0", ctypes.c_int32),
            ("pad1", ctypes.c_int32),
        ]

    return _LyapState


#: The double pendulum's resumable Benettin run (``sp_lyap_state`` with 4 state components).
LyapState = lyap_state_type(4)


# -- the compiler -----------------------------------------------------------------------------------
#: The packaged compiler: the ``ziglang`` wheel's ``zig cc`` (clang with its own libc and linker),
#: a dependency of skewpend, used when no system compiler is found.
PACKAGED_COMPILER = ("-m", "ziglang", "cc")


def packaged_compiler() -> Optional[list]:
    """``[python, -m, ziglang, cc]`` if the ``ziglang`` wheel is installed, else None."""
    import importlib.util

    if importlib.util.find_spec("ziglang") is None:
        return None
    return [sys.executable, *PACKAGED_COMPILER]


def find_compiler() -> list:
    """The C compiler as a command (a list): ``$CC`` if set, else the first of ``cc``, ``gcc``,
    ``clang`` on PATH, else the packaged ``zig cc`` (:func:`packaged_compiler`)."""
    import shlex

    env = os.environ.get("CC")
    if env:
        return shlex.split(env)
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return [path]
    packaged = packaged_compiler()
    if packaged is not None:
        return packaged
    raise CompilerError(
        "skewpend compiles its simulation kernels with a C compiler and none was found: install gcc or clang "
        "(e.g. 'apt-get install gcc'), or the packaged one ('pip install ziglang'), or set CC"
    )


def compiler_name(cc: list) -> str:
    """How a compiler command reads in messages and in the cache's records: ``/usr/bin/cc``, or
    ``zig cc (ziglang)`` for the packaged one."""
    if tuple(cc[1:]) == PACKAGED_COMPILER:
        return "zig cc (ziglang)"
    return " ".join(cc)


@lru_cache(maxsize=None)
def fused_multiply_add() -> Tuple[bool, Tuple[str, ...]]:
    """Whether this processor has fused multiply-add instructions, and the compiler flags that use
    them: ``(True, ("-mfma",))`` on x86-64 with them (Linux: the ``fma`` flag of /proc/cpuinfo),
    ``(True, ())`` on aarch64 (always there; compilers use it for ``fma`` unasked), else
    ``(False, ())``.  The Taylor kernels fuse every product of their series with the addition that
    follows (``fma``, about 10 % less time a step) where it is there; ``fma`` is correctly rounded, so
    their bits are the same on every such processor and with either compiler.  Where it is not, the C
    library's exact ``fma`` would take ~100x the time, so those kernels round each product and sum
    separately (other bits, the same accuracy).  Part of the Taylor kernels' cache key: a library
    built for one is never loaded on the other."""
    machine = platform.machine().lower()
    if machine in ("aarch64", "arm64"):
        return True, ()
    if machine in ("x86_64", "amd64"):
        try:
            text = Path("/proc/cpuinfo").read_text(errors="replace")
        except OSError:
            text = ""
        for line in text.splitlines():
            if line.startswith("flags"):
                return (True, ("-mfma",)) if "fma" in line.split(":", 1)[-1].split() else (False, ())
    return False, ()


def _compile(source: str, target: Path, flags: Tuple[str, ...] = (), archives: Tuple[str, ...] = ()) -> str:
    """Compile ``source`` into the shared library ``target`` (written atomically, with the
    records ``.sha256`` and ``.compiler`` beside it), ``flags`` added to :data:`CFLAGS`, linked with the static
    ``archives``; returns the compiler's name."""
    cc = find_compiler()
    name = compiler_name(cc)
    directory = target.parent
    fd, c_tmp = tempfile.mkstemp(dir=directory, prefix=f".{target.stem}.", suffix=".c.tmp")
    with os.fdopen(fd, "w") as fh:
        fh.write(source)
    so_tmp = c_tmp[: -len(".c.tmp")] + LIB_SUFFIX + ".tmp"
    try:
        # -I: the integrators include the DOP853 core (dop853_core.h) from the package
        # the packaged zig cc builds its compiler runtime (compiler_rt) on its first use, 4-7 s, for
        # builtins no kernel calls (double and 64-bit integer arithmetic are instructions; only libm is used)
        extra = ["-rtlib=none"] if tuple(cc[1:]) == PACKAGED_COMPILER else []
        cmd = [*cc, *CFLAGS, *flags, *extra, "-I", str(_PACKAGE / "numeric"), "-o", so_tmp, "-x", "c", c_tmp,
               *(("-x", "none", *archives) if archives else ()), "-lm"]
        # the compiler's own temporary files (gcc's .s) go to a directory of ours, removed even when
        # Ctrl-C kills the compiler mid-way (it could not clean up after itself)
        scratch = tempfile.mkdtemp(dir=directory, prefix=f".{target.stem}.", suffix=".cc-tmp")
        try:
            proc = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "TMPDIR": scratch})
        except OSError as exc:
            raise CompilerError(f"cannot run the C compiler {name!r}: {exc.strerror}; install gcc or clang, or set CC") from None
        finally:
            shutil.rmtree(scratch, ignore_errors=True)
        if proc.returncode != 0:
            first = (proc.stderr.strip().splitlines() or ["(no message)"])[0]
            raise CompilerError(f"the C compiler {name!r} failed on the generated kernel: {first}")
        if not os.path.isfile(so_tmp) or os.path.getsize(so_tmp) == 0:
            raise CompilerError(f"the C compiler {name!r} reported success but produced no shared library; set CC to a "
                                "working C compiler (gcc or clang)")
        digest = hashlib.sha256(Path(so_tmp).read_bytes()).hexdigest()
        os.replace(so_tmp, target)
        write_text_atomically(target.with_suffix(".sha256"), digest + "\n")
        write_text_atomically(target.with_suffix(".compiler"), name + "\n")
        os.replace(c_tmp, target.with_suffix(".c"))  # kept for reading, not used
    finally:
        for tmp in (c_tmp, so_tmp):
            if os.path.exists(tmp):
                os.unlink(tmp)
    return name


def built_by(path: Path) -> Optional[str]:
    """Which compiler built the cached library ``path`` (its ``.compiler`` record), or None."""
    try:
        return path.with_suffix(".compiler").read_text().strip() or None
    except OSError:
        return None


def write_text_atomically(path: Path, text) -> None:
    """``text`` (a str, or bytes written as they are) into ``path``: a temporary file beside it made
    exclusively (never a planted link), then renamed over it, so a reader sees the old file or the
    whole new one."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb" if isinstance(text, bytes) else "w") as fh:
            fh.write(text)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


# -- the loaded library ------------------------------------------------------------------------------
class Kernel:
    """The compiled functions of one model geometry (bound with :mod:`ctypes`).

    Single-state functions take and fill float64 arrays: ``rhs(y, p, out)``, ``ham_rhs(z, p, out)``, ``jac(y, p, out)`` (out 5x5),
    ``energy(y, p) -> float``, ``momenta``, ``velocities``, ``tips``; row functions
    ``energies(ys, p)``, ``tips_many(ys, p)``, ``speeds_many(zs, p)``.  The raw resumable
    integrators are ``lib.sp_dop853``, ``lib.sp_rk4`` and ``lib.sp_gauss`` (see
    ``integrators.c``), driven by :mod:`skewpend.numeric.simulation`.  The *flip kernel*
    (``kernel_module(params, flip=True)``, ``flip`` True) has these and ``lib.sp_flip``, which
    integrates many starts at rest side by side until a joint flips, driven by
    :mod:`skewpend.numeric.ensemble` (with ``flip_ws_size``, ``flip_lanes``, ``flip_odd``,
    ``flip_potential_many``).

    ``origin`` says where it came from: ``"compiled"`` (built in this process, taking
    ``build_time`` seconds) or ``"cache"``; ``compiler`` which compiler built it (None if not recorded).
    """

    def __init__(self, path: Path, origin: str, build_time: float, *, flip: bool = False, chaos: bool = False,
                 shooting: bool = False):
        import numpy as np

        self.path, self.origin, self.build_time = path, origin, build_time
        self.compiler = built_by(path)
        lib = self.lib = ctypes.CDLL(str(path))
        dp = ctypes.POINTER(ctypes.c_double)
        i64 = ctypes.c_int64
        layout = (i64 * 3)()
        lib.sp_layout.argtypes, lib.sp_layout.restype = [ctypes.POINTER(i64)], None
        lib.sp_layout(layout)
        #: the number of coordinates (2 for the double pendulum, n for a chain), of p's entries, and the
        #: integrators' largest state; ``State`` is the resumable state's mirror of that size
        self.nq, self.nparam, self.nmax = int(layout[0]), int(layout[1]), int(layout[2])
        self.State = state_type(self.nmax)
        sp = ctypes.POINTER(self.State)
        for name in ("sp_rhs", "sp_ham_rhs", "sp_jac", "sp_momenta", "sp_velocities", "sp_tips"):
            if hasattr(lib, name):  # a chain's library has no Jacobian (yet)
                getattr(lib, name).argtypes, getattr(lib, name).restype = [dp, dp, dp], None
        lib.sp_energy.argtypes, lib.sp_energy.restype = [dp, dp], ctypes.c_double
        for name in ("sp_energies", "sp_tips_many", "sp_momenta_many", "sp_axes_many"):
            getattr(lib, name).argtypes, getattr(lib, name).restype = [dp, i64, i64, dp, dp], None
        vp = ctypes.c_void_p  # addresses: the quickest ctypes call (simulate's per-chunk account)
        lib.sp_energy_account.argtypes, lib.sp_energy_account.restype = [vp, i64, i64, vp, vp, vp], None
        lib.sp_speeds_many.argtypes, lib.sp_speeds_many.restype = [dp, i64, i64, dp], None
        lib.sp_state_size.argtypes, lib.sp_state_size.restype = [], i64
        d, ip = ctypes.c_double, ctypes.POINTER(i64)
        lib.sp_dop853.argtypes = [sp, ctypes.c_int, dp, d, d, d, i64, i64, d, i64, ip, dp, i64, ip]
        lib.sp_rk4.argtypes = [sp, ctypes.c_int, dp, d, d, i64, i64, i64, dp, i64, ip]
        lib.sp_gauss.argtypes = [sp, ctypes.c_int, dp, d, d, i64, i64, d, i64, i64, dp, i64, ip]
        self.ControlStruct = control_struct_type(self.nq)  #: this model's ``sp_control``
        cp = ctypes.POINTER(self.ControlStruct)
        lib.sp_dop853_ctl.argtypes = [cp, sp, ctypes.c_int, dp, d, d, d, i64, i64, d, i64, ip, dp, i64, ip]
        lib.sp_rk4_ctl.argtypes = [cp, sp, ctypes.c_int, dp, d, d, i64, i64, i64, dp, i64, ip]
        lib.sp_inputs_many.argtypes, lib.sp_inputs_many.restype = [cp, dp, i64, i64, dp, dp], None
        lib.sp_control_size.argtypes, lib.sp_control_size.restype = [], i64
        i8p, i32p = ctypes.POINTER(ctypes.c_int8), ctypes.POINTER(ctypes.c_int32)
        lib.sp_capture_many.argtypes = [cp, dp, dp, i64, d, d, d, i64, dp, d, dp, ip, ip, i8p]
        lib.sp_capture_many.restype = None
        lib.sp_flip_many.argtypes, lib.sp_flip_many.restype = [dp, dp, i64, d, d, d, i64, dp, i32p, ip, ip, i8p], None
        lib.sp_rhs_ctl_many.argtypes, lib.sp_rhs_ctl_many.restype = [cp, dp, i64, i64, dp, dp], None
        lib.sp_rk4_hold.argtypes, lib.sp_rk4_hold.restype = [dp, dp, dp, d, dp], None
        lib.sp_protocol.argtypes, lib.sp_protocol.restype = [cp, dp, dp, i64, d, i64, d, dp, dp, dp, ctypes.c_int32, dp, dp, dp], i64
        for name in ("sp_dop853", "sp_rk4", "sp_gauss", "sp_dop853_ctl", "sp_rk4_ctl"):
            getattr(lib, name).restype = ctypes.c_int
        if lib.sp_control_size() != ctypes.sizeof(self.ControlStruct):
            raise CompilerError(f"{path}: control layout mismatch ({lib.sp_control_size()} != "
                                f"{ctypes.sizeof(self.ControlStruct)} bytes)")
        #: the form of the generated code (:data:`FORMS`), said by the loader
        self.form = ""
        self.flip, self.chaos, self.shooting = flip, chaos, shooting
        for on, kind, fn in ((flip, "flip", "sp_flip"), (chaos, "chaos", "sp_lyap"),
                             (shooting, "shooting", "sp_shoot")):
            if on and not hasattr(lib, fn):
                raise CompilerError(f"{path}: not a {kind} kernel (no {fn})")
        if flip:  # the flip kernel: sp_flip, many starts at rest side by side (integrators.c)
            lib.sp_flip.argtypes = [ctypes.c_void_p, dp, dp, i64, d, d, d, i64, i64, dp, i32p, ip, ip]
            lib.sp_flip.restype = ctypes.c_int
            lib.sp_flip_layout.argtypes, lib.sp_flip_layout.restype = [ctypes.POINTER(i64)], None
            lib.sp_flip_potential_many.argtypes, lib.sp_flip_potential_many.restype = [dp, i64, dp, dp], None
            #: bytes of the sp_flip workspace, trajectories side by side, and whether the model's
            #: equations without torques are odd under (q, q') -> -(q, q') (a symbolic check)
            layout = (i64 * 3)()
            lib.sp_flip_layout(layout)
            self.flip_ws_size, self.flip_lanes, self.flip_odd = int(layout[0]), int(layout[1]), bool(layout[2])
        if chaos:  # the chaos kernel: Lyapunov exponents and Poincare sections (chaos.c)
            #: the resumable Benettin run's mirror for this model's state (2 nq components)
            self.LyapState = lyap_state_type(2 * self.nq)
            lp = ctypes.POINTER(self.LyapState)
            lib.sp_lyap.argtypes, lib.sp_lyap.restype = [lp, dp, d, d, d, i64, i64, dp, i64, ip], ctypes.c_int
            lib.sp_flow.argtypes, lib.sp_flow.restype = [lp, dp, d, d, d, i64, i64], ctypes.c_int
            lib.sp_lyap1_many.argtypes = [dp, dp, i64, d, d, i64, d, d, i64, dp, i32p, ip, ip]
            lib.sp_lyap1_many.restype = None
            if hasattr(lib, "sp_section"):  # Poincare sections: the double pendulum's only (two-dimensional)
                lib.sp_section.argtypes = [sp, dp, ctypes.c_int, d, d, ctypes.c_int, ctypes.c_int, i64, d, d, d, i64,
                                           i64, dp, i64, ip]
                lib.sp_section.restype = ctypes.c_int
            lib.sp_lyap_state_size.argtypes, lib.sp_lyap_state_size.restype = [], i64
            if lib.sp_lyap_state_size() != ctypes.sizeof(self.LyapState):
                raise CompilerError(f"{path}: Lyapunov state layout mismatch")
        if shooting:  # multiple shooting: RK4 with parameter sensitivities (shooting.c)
            lib.sp_shoot.argtypes, lib.sp_shoot.restype = [dp, dp, i64, i64, i64, d, dp, dp, dp, dp], ctypes.c_int
            lib.sp_rhs_sens.argtypes, lib.sp_rhs_sens.restype = [dp, dp, dp, dp, dp], None
        if lib.sp_state_size() != ctypes.sizeof(self.State):
            raise CompilerError(f"{path}: integrator state layout mismatch ({lib.sp_state_size()} != "
                                f"{ctypes.sizeof(self.State)} bytes)")
        self._np = np

    # -- helpers -------------------------------------------------------------------------------
    def _in(self, a):
        a = self._np.ascontiguousarray(a, dtype=self._np.float64)
        return a, a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))

    def _p(self, p):
        """``p`` as the C code reads it: every entry of :data:`PARAMETER_ORDER` (a shorter array would be read past its end)."""
        p, pp = self._in(p)
        if p.ndim != 1 or p.size != self.nparam:
            raise ValueError(f"p must hold the {self.nparam} entries of the model's parameter order "
                             f"(parameter_vector), got shape {p.shape}")
        return p, pp

    def _call3(self, fn, y, p, out, size):
        y, yp = self._in(y)
        p, pp = self._p(p)
        if out.dtype != self._np.float64 or not out.flags.c_contiguous or out.size < size:
            raise ValueError(f"out must be a C-contiguous float64 array of at least {size} entries")
        fn(yp, pp, out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)))

    def rhs(self, y, p, out) -> None:
        self._call3(self.lib.sp_rhs, y, p, out, 2 * self.nq + 1)

    def ham_rhs(self, z, p, out) -> None:
        self._call3(self.lib.sp_ham_rhs, z, p, out, 2 * self.nq + 1)

    def jac(self, y, p, out) -> None:
        self._call3(self.lib.sp_jac, y, p, out, (2 * self.nq + 1) ** 2)

    def momenta(self, y, p, out) -> None:
        self._call3(self.lib.sp_momenta, y, p, out, self.nq)

    def velocities(self, z, p, out) -> None:
        self._call3(self.lib.sp_velocities, z, p, out, self.nq)

    def tips(self, y, p, out) -> None:
        self._call3(self.lib.sp_tips, y, p, out, 3 * self.nq)

    def energy(self, y, p) -> float:
        y, yp = self._in(y)
        p, pp = self._p(p)
        return float(self.lib.sp_energy(yp, pp))

    def _rows(self, ys):
        ys = self._np.ascontiguousarray(ys, dtype=self._np.float64)
        if ys.ndim != 2 or ys.shape[1] < 2 * self.nq:
            raise ValueError(f"expected rows of states, shape (n, >= {2 * self.nq})")
        return ys

    def _per_row(self, fn, ys, p, offset: int, width: int):
        """``fn(rows, nrows, stride, p, out)`` over the states ``ys[i, offset:]``: out (n, width)."""
        ys = self._rows(ys)
        p, pp = self._p(p)
        out = self._np.empty((ys.shape[0], width))
        base = ctypes.cast(ys.ctypes.data + 8 * offset, ctypes.POINTER(ctypes.c_double))
        fn(base, ys.shape[0], ys.shape[1], pp, out.ctypes.data_as(ctypes.POINTER(ctypes.c_double)))
        return out

    def energies(self, ys, p, *, offset: int = 0):
        """Energy of each row ``ys[i, offset:]`` (a state) [J], shape (n,)."""
        return self._per_row(self.lib.sp_energies, ys, p, offset, 1)[:, 0]

    def momenta_many(self, ys, p, *, offset: int = 0):
        """Canonical momenta ``M(q) q'`` of each row ``ys[i, offset:]``: shape (n, 2) (the same C
        function as :meth:`momenta`, row by row: the same bits)."""
        return self._per_row(self.lib.sp_momenta_many, ys, p, offset, self.nq)

    def tips_many(self, ys, p, *, offset: int = 0):
        """Rod ends of each row ``ys[i, offset:]``: shape (n, 6) [m]."""
        return self._per_row(self.lib.sp_tips_many, ys, p, offset, 3 * self.nq)

    def axes_many(self, ys, p, *, offset: int = 0):
        """Hinge axes of each row: ``(n1, e)`` in the world frame, shape (n, 6) (unit vectors)."""
        return self._per_row(self.lib.sp_axes_many, ys, p, offset, 3 * self.nq)

    def flip_potential_many(self, qs, p):
        """``V = Pi - tau . q`` at each row ``qs[i] = (phi, psi)`` [J], shape (n,): the potential
        energy with the work of the constant joint torques (generated, see ``flip_c_source``)."""
        qs = self._np.ascontiguousarray(qs, dtype=self._np.float64)
        if qs.ndim != 2 or qs.shape[1] != 2:
            raise ValueError("expected rows of angles, shape (n, 2)")
        p, pp = self._p(p)
        out = self._np.empty(qs.shape[0])
        dp = ctypes.POINTER(ctypes.c_double)
        self.lib.sp_flip_potential_many(qs.ctypes.data_as(dp), qs.shape[0], pp, out.ctypes.data_as(dp))
        return out

    def speeds_many(self, zs, p, *, offset: int = 0, inplace: bool = False):
        """Canonical rows ``(phi, psi, p_phi, p_psi, ...)`` -> ``(phi, psi, dphi, dpsi, ...)``."""
        zs = self._rows(zs)
        ys = zs if inplace else zs.copy()
        p, pp = self._p(p)
        base = ctypes.cast(ys.ctypes.data + 8 * offset, ctypes.POINTER(ctypes.c_double))
        self.lib.sp_speeds_many(base, ys.shape[0], ys.shape[1], pp)
        return ys


# -- the cache ----------------------------------------------------------------------------------------
_LOCK = threading.Lock()
_KEY_LOCKS: Dict[str, threading.Lock] = {}


class _LibraryLock:
    """A library's lock across threads and processes: the thread lock of this process, then an
    exclusive ``flock`` on ``.skewpend_KEY.lock`` in the cache's folder, so two processes wanting the
    same library build it once -- the second waits and loads what the first built.  Where the folder is
    not writable or ``fcntl`` is missing (Windows) the process lock alone holds (the atomic rename keeps
    either build whole)."""

    def __init__(self, key: str, thread_lock: threading.Lock) -> None:
        self.key, self.thread_lock, self.fd = key, thread_lock, None

    def __enter__(self):
        self.thread_lock.acquire()
        try:
            import fcntl

            directory = cache_dir() / "kernels"
            directory.mkdir(parents=True, exist_ok=True)
            self.fd = os.open(directory / f".skewpend_{self.key}.lock", os.O_RDWR | os.O_CREAT, 0o644)
            fcntl.flock(self.fd, fcntl.LOCK_EX)
        except BaseException as exc:  # no flock here (the process lock alone), or Ctrl-C while waiting
            if self.fd is not None:
                os.close(self.fd)
            self.fd = None
            if not isinstance(exc, (ImportError, OSError)):  # nothing held
                self.thread_lock.release()
                raise
        return self

    def __exit__(self, *exc) -> None:
        try:
            if self.fd is not None:
                os.close(self.fd)  # closing the descriptor releases the flock
        finally:
            self.fd = None
            self.thread_lock.release()


def _key_lock(key: str) -> _LibraryLock:
    """One lock per library: two threads or processes wanting the same library build it once, while
    different libraries (the model's, the flip map's, the chaos kernel) compile at the same time."""
    with _LOCK:
        return _LibraryLock(key, _KEY_LOCKS.setdefault(key, threading.Lock()))
_LOADED: Dict[str, Kernel] = {}
_BYGEOMETRY: Dict[str, Kernel] = {}
_FALLBACK_DIR: Optional[Path] = None


@lru_cache(maxsize=None)
def _source_digest() -> str:
    """Hash of everything that shapes the generated library but the geometry (once per process)."""
    h = hashlib.sha256()
    for text in (__version__, " ".join(CFLAGS), platform.machine(), sys.platform):
        h.update(text.encode())
    for name in _SOURCES:
        h.update((_PACKAGE / name).read_bytes())
    return h.hexdigest()


def _key(geometry_repr: str) -> str:
    h = hashlib.sha256(_source_digest().encode())
    h.update(geometry_repr.encode())
    return h.hexdigest()[:20]


def _writable_directory() -> Path:
    """The kernel directory, created if needed; a private temporary one if that is impossible."""
    directory = cache_dir() / "kernels"
    try:
        directory.mkdir(parents=True, exist_ok=True)
        probe = tempfile.NamedTemporaryFile(dir=directory, prefix=".probe.", delete=True)
        probe.close()
        return directory
    except OSError as exc:
        global _FALLBACK_DIR
        with _LOCK:  # one private directory for this run's libraries, whichever thread gets here first
            if _FALLBACK_DIR is None:
                _FALLBACK_DIR = _fallback_directory(directory, exc)
        return _FALLBACK_DIR


def _fallback_directory(directory: Path, exc: OSError) -> Path:
    """A private temporary directory (with a warning), removed at exit (the loaded libraries stay mapped)."""
    import atexit

    fallback = Path(tempfile.mkdtemp(prefix="skewpend-kernels-"))
    atexit.register(shutil.rmtree, fallback, ignore_errors=True)
    warnings.warn(f"cannot write the kernel cache {directory} ({exc.strerror or exc}); using {fallback} for this run "
                  "(set SKEWPEND_CACHE_DIR to a writable directory to keep compiled kernels)", RuntimeWarning,
                  stacklevel=4)
    return fallback


def _intact(path: Path) -> bool:
    sha = path.with_suffix(".sha256")
    try:
        recorded = sha.read_text().strip()
        return hashlib.sha256(path.read_bytes()).hexdigest() == recorded
    except OSError:
        return False


def _remove_stale_temporaries(directory: Path, age: float = 3600.0) -> None:
    """Temporary files of builds killed mid-way (older than ``age`` seconds)."""
    now = time.time()
    for tmp in directory.glob(".*.tmp"):
        try:
            if now - tmp.stat().st_mtime > age:
                tmp.unlink()
        except OSError:
            pass


def _announce(kind: str, cached: bool, which: str = "") -> None:
    """One line on stderr before a build (seconds with the packaged compiler), in a terminal and in a pipe;
    ``SKEWPEND_QUIET=1`` silences it.  A compiler that cannot be run is said first, alone."""
    cc = find_compiler()
    if os.path.sep not in cc[0] and shutil.which(cc[0]) is None or os.path.sep in cc[0] and not os.access(cc[0], os.X_OK):
        raise CompilerError(f"cannot run the C compiler {compiler_name(cc)!r}: No such file or directory; install gcc "
                            "or clang, or set CC")
    if os.environ.get("SKEWPEND_QUIET", "") not in ("", "0"):
        return
    what = {"flip": "the flip-map kernels", "chaos": "the chaos kernels", "taylor": "the Taylor kernel",
            "shooting": "the identification's shooting kernels", "chain": "the chain's kernels",
            "mpc": "the model-predictive controller"}.get(kind, "the model's kernels")
    when = "first use only; cached for later runs" if cached else "for this run: the cache is not writable"
    try:  # ``which``: what tells two builds of one kind apart (a report builds the rig's and MuJoCo's bodies)
        sys.stderr.write(f"skewpend: compiling {what}{which} ({when})...\n")
        sys.stderr.flush()
    except (OSError, ValueError, AttributeError):  # a closed or missing stderr: nothing to say it on
        pass


def announce_background(what: str, meanwhile: str, key: str = "") -> None:
    """One line on stderr when a library is built in the background (``SKEWPEND_QUIET=1`` silences it),
    once per process and library ``key`` (identify's held-out pieces asked eight times in one call)."""
    if os.environ.get("SKEWPEND_QUIET", "") not in ("", "0") or (key or what) in _ANNOUNCED:
        return
    _ANNOUNCED.add(key or what)
    try:
        sys.stderr.write(f"skewpend: building {what} in the background (first use only; {meanwhile})\n")
        sys.stderr.flush()
    except (OSError, ValueError, AttributeError):
        pass


#: The background builds said in this process (:func:`announce_background`).
_ANNOUNCED: set = set()


def _library(key: str, make, source, *, kind: str, which: str = "", flags: Tuple[str, ...] = (),
             archives: Tuple[str, ...] = ()):
    """The one loader of every compiled library (a model's, its flip, chaos and shooting libraries, the Taylor
    integrator's, of any form): under the key's lock, from this process, else from the cache (checked
    against its recorded hash; a damaged file is rebuilt), else ``source()`` announced (:func:`_announce`
    with ``kind`` and ``which``), compiled with ``flags`` and cached atomically (a killed build leaves no
    partial library).  ``make(path, origin, build_time)`` binds the library (a :class:`Kernel`, a
    :class:`TaylorKernel`)."""
    with _key_lock(key):
        if key in _LOADED:
            return _LOADED[key]
        path = cache_dir() / "kernels" / f"skewpend_{key}{LIB_SUFFIX}"
        loaded = None
        if path.exists() and _intact(path):
            try:
                loaded = make(path, "cache", 0.0)
            except (OSError, CompilerError):
                loaded = None  # damaged: rebuilt below
        if loaded is None:
            start = time.perf_counter()
            directory = _writable_directory()
            path = directory / f"skewpend_{key}{LIB_SUFFIX}"
            _remove_stale_temporaries(directory)
            _announce(kind, cached=directory == cache_dir() / "kernels", which=which)
            _compile(source(), path, flags, archives)  # a model without what the source needs is refused here
            loaded = make(path, "compiled", time.perf_counter() - start)
        _LOADED[key] = loaded
        return loaded


def casadi_library(fn, *, kind: str, which: str = "", flags: Tuple[str, ...] = (), archives: Tuple[str, ...] = ()):
    """The CasADi function ``fn`` as C (CasADi's code generator: its graph's operations, and the code of the
    solvers it calls where CasADi generates them) compiled through the one loader (:func:`_library`: the
    cache, its lock, the announcement of ``kind``) with ``flags`` and linked with ``archives``: the loaded
    ``ctypes.CDLL`` (its entry points are ``fn``'s name, ``<name>_work``, ``<name>_checkout`` as CasADi's
    generated C declares them)."""
    import casadi as ca

    gen = ca.CodeGenerator(f"{fn.name()}.c", {"with_header": False, "verbose": False})
    gen.add(fn)
    text = gen.dump()
    key = _key("casadi\0" + " ".join(flags) + "\0" + " ".join(Path(a).name for a in archives) + "\0" + text)
    return _library(key, lambda path, origin, seconds: ctypes.CDLL(str(path)), lambda: text, kind=kind, which=which,
                    flags=flags, archives=archives)


def _bodies_words(geometry) -> str:
    """Nothing for thin rods, `` for general bodies`` otherwise (a report's MuJoCo check builds both)."""
    from .conventions import COM_NAMES, INERTIA_NAMES

    rods = all(getattr(geometry, n, None) is None for n in COM_NAMES + INERTIA_NAMES)
    return "" if rods else " for general bodies"


def kernel_module(params: Parameters, *, flip: bool = False, chaos: bool = False, shooting: bool = False) -> Kernel:
    """The compiled kernel for the bodies and axes of ``params`` (scalars are runtime inputs), by
    :func:`_library`.  ``flip=True``:
    the larger library that also holds the flip-time ensembles (``sp_flip``), built on the
    first flip map so that simulations never wait for it.  ``chaos=True``: the library that also
    holds the Lyapunov and Poincare-section routines (``chaos.c``), built on first use.
    ``shooting=True``: identification's library, the parameter sensitivities and multiple
    shooting's integrator (``shooting.c``), for every entry of both bodies read from ``p``
    (``structure_of(params, full=True)``: one library for every fit of the same axes and terms).
    (The Taylor integrator has libraries of its own, one per order: :func:`taylor_kernel`.)
    """
    if flip + chaos + shooting > 1:
        raise ValueError("kernel_module: flip, chaos and shooting are separate libraries")
    kind = "flip" if flip else ("chaos" if chaos else ("shooting" if shooting else ""))
    gkey = repr([getattr(params, k) for k in GEOMETRY] + list(optional_terms(params))) + ("|" + kind if kind else "")
    kernel = _BYGEOMETRY.get(gkey)
    if kernel is not None:
        return kernel
    geometry = structure_of(params, full=shooting)
    key = _key(repr(geometry.to_dict())) + ("_" + kind if kind else "")

    def source() -> str:
        from .kernel_source import kernel_c_source

        text = kernel_c_source(geometry, flip=flip, shooting=shooting) + "\n" + _numeric_text("integrators.c")
        return text + "".join("\n" + _numeric_text(name) for name, on in (("chaos.c", chaos), ("shooting.c", shooting)) if on)

    kernel = _library(key, lambda path, origin, seconds: Kernel(path, origin, seconds, flip=flip, chaos=chaos,
                                                                 shooting=shooting),
                      source, kind=kind, which=_bodies_words(geometry))
    kernel.form = "exact"
    _BYGEOMETRY[gkey] = kernel
    return kernel


def _numeric_text(name: str) -> str:
    """The text of a C file of :mod:`skewpend.numeric` (the integrators, the chaos and shooting routines)."""
    return (_PACKAGE / "numeric" / name).read_text()


def chain_kernel(chain, form: str = "", *, shooting: bool = False, chaos: bool = False) -> Kernel:
    """The compiled model functions of a chain of links (:class:`skewpend.symbolic.chain.Chain`): its
    equations by the recursive algorithms (:mod:`skewpend.numeric.recursive`), keyed by the chain's
    structure (the number of links, the hinge axes' patterns -- ``recursive.axis_pattern``; none in the
    compact form -- whether friction and rotors exist); every value, the axes' components included, is
    the run-time array ``recursive.parameter_vector(chain)``.  Cached like :func:`kernel_module`.
    ``form``: ``"straight"`` or ``"compact"`` code (default: ``recursive.chain_form``, by the length).
    ``shooting=True``: identification's library, the straight-line code with the parameter
    sensitivities (``recursive.chain_sensitivity_c_source``) and multiple shooting's integrator
    (``shooting.c``), as :func:`kernel_module`'s for the double pendulum; ``chaos=True``: the
    Lyapunov routines and the state-transition flow (``chaos.c``) on the same sensitivities."""
    from .recursive import chain_form, structure_of_chain

    if shooting and chaos:
        raise ValueError("chain_kernel: shooting and chaos are separate libraries")
    structure = structure_of_chain(chain)
    form = "straight" if (shooting or chaos) else (form or chain_form(structure))
    if form not in ("straight", "compact"):
        raise ValueError(f"form must be 'straight' or 'compact', got {form!r}")
    extra = "|shooting" if shooting else ("|chaos" if chaos else "")
    key = _key(structure.key(form) + "|" + form + extra) + "_chain"

    def source() -> str:
        from .recursive import chain_sensitivity_c_source, chain_source

        text = chain_source(structure, form) + "\n" + _numeric_text("integrators.c")
        if shooting or chaos:
            text += "\n" + chain_sensitivity_c_source(structure) + "\n" + _numeric_text("shooting.c" if shooting else "chaos.c")
        return text

    kernel = _library(key, lambda path, origin, seconds: Kernel(path, origin, seconds, shooting=shooting, chaos=chaos),
                      source, kind="shooting" if shooting else ("chaos" if chaos else "chain"))
    kernel.form = form
    return kernel


#: The forms of a model's generated code (an argument of one pipeline, not the model's type): ``exact``, the
#: specification's derivation (SymPy; two links the double pendulum's parameters hold: there the fastest -- a
#: 20 s DOP853 run at 1e-10 takes 9.58e6 instructions, the straight form 1.53x, the compact 2.70x); ``straight``
#: and ``compact``, the recursive algorithms (any chain; ``recursive.chain_form`` picks by the length).
FORMS = ("exact", "straight", "compact")


def model_form(model, form: str = "", kind: str = ""):
    """``(form, printed)``: the form of ``model``'s code for a library of ``kind`` (``""``, ``"flip"``,
    ``"chaos"``, ``"shooting"``) and the model that form prints (the double pendulum's parameters for
    ``exact``, the chain otherwise).  ``form=""``: the fastest that prints it, for every kind (so that
    :func:`model_vector` agrees with any library's default) -- ``exact`` where the model has it, the straight
    form for chaos and shooting libraries otherwise (their sensitivities), else by the chain's length.
    A form the model has not, or one that does not exist: one line naming the forms."""
    from ..errors import ParameterError

    exact = model.exact_model()
    if not form:
        if exact is not None:
            return "exact", exact
        if kind in ("chaos", "shooting"):
            return "straight", model.as_chain()
        from .recursive import chain_form, structure_of_chain

        chain = model.as_chain()
        return chain_form(structure_of_chain(chain)), chain
    if form not in FORMS:
        raise ParameterError(f"form must be one of {', '.join(FORMS)}, got {form!r}")
    if form == "exact":
        if exact is None:
            raise ParameterError(f"the exact form (the specification's derivation) prints two links the double pendulum's "
                                 f"parameters hold; this model is {model.title}: use form 'straight' or 'compact'")
        return form, exact
    if kind == "flip":
        raise ParameterError("the flip kernel (its SIMD lanes) is printed in the exact form only")
    if kind in ("chaos", "shooting") and form != "straight":
        raise ParameterError(f"the {kind} library is printed in the exact or the straight form, got {form!r}")
    chain = model.as_chain()
    if form == "compact" and chain.has_rotor:
        raise ParameterError("the compact form prints chains without rotors; this model has geared rotors: use form "
                             "'exact' or 'straight'")
    return form, chain


def model_kernel(model, form: str = "", *, flip: bool = False, chaos: bool = False, shooting: bool = False) -> Kernel:
    """The one door to a model's compiled library: the model's own, ``flip=True`` with the flip map's SIMD
    lanes (exact form only), ``chaos=True`` with the Lyapunov routines and the state-transition flow,
    ``shooting=True`` identification's.  ``form``: the generated code's form (:data:`FORMS`; default the
    fastest that prints the model, :func:`model_form`); the kernel says its ``form``."""
    kind = "flip" if flip else ("chaos" if chaos else ("shooting" if shooting else ""))
    form, printed = model_form(model, form, kind)
    if form == "exact":
        return kernel_module(printed, flip=flip, chaos=chaos, shooting=shooting)
    return chain_kernel(printed, form, chaos=chaos, shooting=shooting)


def model_vector_names(model, form: str = "") -> tuple:
    """The names of :func:`model_vector`'s entries, in its order (the specification's parameters for the
    exact form, ``recursive.parameter_names`` for the recursive ones)."""
    form, printed = model_form(model, form)
    if form == "exact":
        return tuple(PARAMETER_ORDER)
    from .recursive import parameter_names

    return parameter_names(printed.n)


def model_vector(model, form: str = ""):
    """The run-time array ``p`` of ``model`` for the kernel of ``form`` (:func:`model_kernel`'s default alike)."""
    form, printed = model_form(model, form)
    if form == "exact":
        return parameter_vector(printed)
    from .recursive import parameter_vector as chain_vector

    return chain_vector(printed)


# -- the Taylor integrator: one small library per geometry and order ------------------------------
class TaylorKernel:
    """The Taylor integrator of one geometry at one order (``lib.sp_taylor``, see ``taylor.c``):
    its loops are unrolled for that order, so each order is a library of its own, a fraction of a
    second to build.  ``origin``, ``build_time``, ``compiler`` as :class:`Kernel`'s."""

    def __init__(self, path: Path, origin: str, build_time: float, order: int, tn: int = SP_TN):
        self.path, self.origin, self.build_time, self.order = path, origin, build_time, order
        self.State = taylor_state_type(tn)  # the run's state (a chain's is larger)
        self.compiler = built_by(path)
        lib = ctypes.CDLL(str(path))
        i64, d = ctypes.c_int64, ctypes.c_double
        vp, ip = ctypes.c_void_p, ctypes.POINTER(i64)
        # pointers as addresses (c_void_p): the fastest call ctypes makes
        lib.sp_taylor.argtypes = [vp, vp, d, d, d, d, i64, i64, d, i64, ip, vp, i64, ip]
        lib.sp_taylor.restype = ctypes.c_int
        lib.sp_taylor_state_size.argtypes, lib.sp_taylor_state_size.restype = [], i64
        if lib.sp_taylor_state_size() != ctypes.sizeof(self.State):
            raise CompilerError(f"{path}: Taylor state layout mismatch")
        self.lib = lib


_TAYLOR_OF: Dict[tuple, "TaylorKernel"] = {}


def taylor_kernel(params: Parameters, order: int, *, model: Optional[Kernel] = None, form: str = "") -> TaylorKernel:
    """The Taylor integrator of order ``order`` for the bodies and axes of ``params``, from the
    cache or generated (:mod:`skewpend.numeric.taylor_source`) and compiled on first use.  Raises
    ValueError (before compiling) for equations with a function that has no series recurrence.
    ``model``: the model's :func:`kernel_module` when the caller has it (a quicker look-up).  A chain of links
    (:class:`~skewpend.symbolic.chain.Chain`): its recurrences from the recursive algorithms' equations read
    as polynomials (:mod:`skewpend.numeric.polynomial`), by the same generator."""
    if model is not None and (model.path, order) in _TAYLOR_OF:
        return _TAYLOR_OF[model.path, order]
    form, printed = model_form(params, model.form if model is not None else form)
    gkey = _taylor_gkey(printed, order) if form == "exact" else ""
    loaded = _BYGEOMETRY.get(gkey)
    if loaded is None:
        key, tn, flags, source, which = _taylor_library(form, printed, order)
        loaded = _library(key, lambda path, origin, seconds: TaylorKernel(path, origin, seconds, order, tn), source,
                          kind="taylor", which=which, flags=flags)
        if gkey:
            _BYGEOMETRY[gkey] = loaded  # type: ignore[assignment]
    if model is not None:
        _TAYLOR_OF[model.path, order] = loaded  # type: ignore[assignment]
    return loaded  # type: ignore[return-value]


def _taylor_library(form: str, printed, order: int):
    """``(key, tn, flags, source, which)`` of the Taylor library of ``printed`` in ``form`` at ``order``: its
    cache key (the structure, the generator's and driver's text -- not part of the other libraries' key --
    and whether the processor's fused multiply-add is used, :func:`fused_multiply_add`), its state size, the
    compiler flags, the C source's maker and the words of its announcement."""
    fused, flags = fused_multiply_add()
    names = ("taylor_source.py", "taylor.c", "rows.h")
    if form == "exact":
        structure = structure_of(printed)
        tn, tag, which, text = SP_TN, "taylor", _bodies_words(structure), repr(structure.to_dict())
    else:
        from .recursive import structure_of_chain

        structure, tag, which = structure_of_chain(printed), "ctaylor", ""
        tn, text, names = 2 * structure.n + 1, structure.key(), ("polynomial.py", "taylor_source.py", "recursive.py",
                                                                 "taylor.c", "rows.h")
    extra = b"".join((_PACKAGE / "numeric" / name).read_bytes() for name in names)
    key = _key(text + hashlib.sha256(extra).hexdigest() + f"|fused={fused} {' '.join(flags)}") + f"_{tag}{order}"

    def source() -> str:  # a model without recurrences is refused here
        from .taylor_source import exact_system, polynomial_system, taylor_c_source

        system = exact_system(structure) if form == "exact" else polynomial_system(structure)
        return taylor_c_source(system, order, fused=fused)

    return key, tn, flags, source, f" of order {order}{which}"


def taylor_library_key(model, order: int, form: str = "") -> str:
    """The cache key of the Taylor library ``taylor_kernel(model, order)`` loads in ``form``."""
    return _taylor_library(*model_form(model, form), order)[0]


def series_form(model, form: str = "") -> bool:
    """Whether ``simulate``'s ``method="auto"`` takes the Taylor series for ``model`` in ``form``: the exact
    form's always, a chain's up to :data:`~skewpend.numeric.conventions.SERIES_MAX_LINKS` links."""
    from .conventions import SERIES_MAX_LINKS

    form, printed = model_form(model, form)
    return form == "exact" or printed.n <= SERIES_MAX_LINKS


def _taylor_gkey(params: Parameters, order: int) -> str:
    return repr([getattr(params, k) for k in GEOMETRY] + list(optional_terms(params))) + f"|taylor{order}"


def built_taylor_kernel(params, order: int, *, model: Optional[Kernel] = None, form: str = "") -> Optional[TaylorKernel]:
    """The Taylor library of ``params``' structure (in ``form``) and ``order`` if it is built (loaded in this
    process, or in the cache on disk: then loaded), else None -- it never builds."""
    if model is not None and (model.path, order) in _TAYLOR_OF:
        return _TAYLOR_OF[model.path, order]
    exact = params.exact_model()
    if (form or model_form(params)[0]) == "exact" and _BYGEOMETRY.get(_taylor_gkey(exact, order)) is not None:
        return taylor_kernel(exact, order, model=model)
    key = taylor_library_key(params, order, form)
    path = cache_dir() / "kernels" / f"skewpend_{key}{LIB_SUFFIX}"
    if key in _LOADED or path.exists() and _intact(path):
        return taylor_kernel(params, order, model=model, form=form)
    return None


#: How a first use builds the Taylor library that ``method="auto"`` would choose: ``background`` (the
#: default: the run takes dop853 at once and a detached process builds the library for later runs) or
#: ``foreground`` (the run waits for the library and takes taylor: one choice whatever the cache holds).
TAYLOR_BUILD_ENV = "SKEWPEND_TAYLOR_BUILD"
#: A background build younger than this [s] is not started again (its marker file says it runs).
_BUILD_MARK_AGE = 300.0


def taylor_build_in_foreground() -> bool:
    """Whether ``SKEWPEND_TAYLOR_BUILD=foreground`` asks a first use to wait for the Taylor library."""
    value = os.environ.get(TAYLOR_BUILD_ENV, "background").strip().lower()
    if value not in ("background", "foreground", ""):
        from ..errors import ParameterError

        raise ParameterError(f"{TAYLOR_BUILD_ENV} must be 'background' or 'foreground', got {value!r}")
    return value == "foreground"


def build_taylor_in_background(params: Parameters, order: int, form: str = "") -> bool:
    """Start building the Taylor library of ``params``' structure and ``order`` in a detached process
    (its own session: a Ctrl-C of this one does not stop it, and it outlives a command that ends
    first), unless one is building it already (a marker file beside the library, under
    :data:`_BUILD_MARK_AGE` s old) or the cache is not writable.  True if a build was started or runs."""
    import json

    key = taylor_library_key(params, order, form)
    directory = cache_dir() / "kernels"
    mark = directory / f".skewpend_{key}.building"
    try:
        directory.mkdir(parents=True, exist_ok=True)
        if mark.exists() and time.time() - mark.stat().st_mtime < _BUILD_MARK_AGE:
            return True
        mark.write_text(str(os.getpid()), encoding="utf-8")
        code = ("import json, sys\nfrom skewpend.numeric.kernels import _build_taylor_from_json\n"
                "_build_taylor_from_json(sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4])\n")
        env = {**os.environ, "SKEWPEND_QUIET": "1", TAYLOR_BUILD_ENV: "foreground"}
        subprocess.Popen([sys.executable, "-c", code, json.dumps(params.to_dict()), str(order), str(mark), form],
                         stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         start_new_session=True, close_fds=True, env=env)
    except OSError:
        return False
    return True


def _build_taylor_from_json(params_json: str, order: int, mark: str, form: str = "") -> None:
    """The detached builder's body: build (or find) the library, then remove the marker."""
    import json

    from ..symbolic.model import model_from_mapping

    try:
        taylor_kernel(model_from_mapping(json.loads(params_json)), order, form=form)
    finally:
        try:
            os.unlink(mark)
        except OSError:
            pass
