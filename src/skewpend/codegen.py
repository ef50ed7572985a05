"""Numeric code generated from the symbolic derivation (the one source of truth).

Every numeric function skewpend runs, and the standalone Python, C and JavaScript a
user can take away, is printed here from :func:`skewpend.derive`'s expressions
with common-subexpression elimination.  No equation of motion is typed by hand;
the only hand-written numerics are the 2x2 linear solve ``M q'' = f`` and the
integrators (:mod:`skewpend._kernels`).

Conventions shared by every generated routine:

* state ``y = (phi, psi, dphi, dpsi)`` [rad, rad, rad/s, rad/s];
* parameters ``p = (a, b, m1, m2, alpha, g, c1, c2, tau1, tau2)`` (SI units, radians),
  the order of :data:`PARAMETER_ORDER`;
* general-body geometry (``com``, ``inertia``, ``axis``) is baked into the code as numbers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, List, Sequence, Tuple

import sympy as sp

from . import __version__
from .derivation import SYMBOLS, derive
from .model import Parameters

__all__ = [
    "PARAMETER_ORDER",
    "STATE_ORDER",
    "generate",
    "kernel_source",
    "kernel_module",
    "parameter_vector",
]

from .compiled import PARAMETER_ORDER, STATE_ORDER, geometry_of, kernel_module, parameter_vector


# -- the expressions to print -------------------------------------------------------------------
@dataclass(frozen=True)
class _Expressions:
    M: sp.Matrix  # 2x2
    f: sp.Matrix  # 2x1
    T: sp.Expr
    Pi: sp.Expr
    Q: sp.Matrix  # 2x1 generalised non-potential forces
    dT_dq: sp.Matrix  # 2x1, partial derivative of T in q at fixed speeds
    dPi_dq: sp.Matrix
    df_dy: sp.Matrix  # 2x4
    dM_dq: Tuple[sp.Matrix, sp.Matrix]
    tips: sp.Matrix  # 6x1: rod 1's end a j and rod 2's end, world frame


def _expressions(geometry: Parameters) -> _Expressions:
    eom = derive(geometry)
    s = SYMBOLS
    q = [s["phi"], s["psi"]]
    dq = [s["dphi"], s["dpsi"]]
    Q = sp.Matrix([s["tau1"] - s["c1"] * dq[0], s["tau2"] - s["c2"] * dq[1]])
    return _Expressions(
        M=eom.mass_matrix,
        f=eom.forcing,
        T=eom.kinetic_energy,
        Pi=eom.potential_energy,
        Q=Q,
        dT_dq=sp.Matrix([eom.kinetic_energy.diff(x) for x in q]),
        dPi_dq=sp.Matrix([eom.potential_energy.diff(x) for x in q]),
        df_dy=eom.forcing.jacobian(q + dq),
        dM_dq=(eom.mass_matrix.diff(q[0]), eom.mass_matrix.diff(q[1])),
        tips=_tips(eom),
    )


def _tips(eom) -> sp.Matrix:
    """World positions of the rod ends: ``P1 . a j`` and ``P1 . a j + P . b j`` [m]."""
    j = sp.Matrix([0, 1, 0])
    a, b = SYMBOLS["a"], SYMBOLS["b"]
    tip1 = eom.steps["P1"] * j * a
    tip2 = tip1 + eom.steps["P"] * j * b
    return sp.Matrix.vstack(tip1, tip2)


# -- printing -----------------------------------------------------------------------------------------
class _Lang:
    """How one target language writes assignments, reads inputs and forms a function."""

    def __init__(self, name: str, printer: Callable[[sp.Expr], str], declare: str, end: str):
        self.name, self.printer, self.declare, self.end = name, printer, declare, end

    def assign(self, target: str, expr: sp.Expr, indent: str) -> str:
        return f"{indent}{self.declare}{target} = {self.printer(expr)}{self.end}"


def _py_printer():
    from sympy.printing.pycode import PythonCodePrinter

    printer = PythonCodePrinter({"fully_qualified_modules": True, "standard": "python3"})
    return printer.doprint


def _c_printer():
    from sympy.printing.c import C99CodePrinter

    return C99CodePrinter().doprint


def _js_printer():
    from sympy.printing.jscode import JavascriptCodePrinter

    return JavascriptCodePrinter().doprint


def _inputs(lang: _Lang, indent: str, state: str, names: Sequence[str]) -> List[str]:
    lines = []
    for i, n in enumerate(names):
        lines.append(f"{indent}{lang.declare}{n} = {state}[{i}]{lang.end}")
    return lines


def _cse_block(
    lang: _Lang, exprs: Sequence[sp.Expr], targets: Sequence[str], indent: str, prefix: str = "x"
) -> List[str]:
    """Assignments computing ``targets = exprs`` with common subexpressions shared."""
    symbols = sp.numbered_symbols(prefix)
    replacements, reduced = sp.cse(list(exprs), symbols=symbols, optimizations="basic")
    lines = [lang.assign(str(sym), e, indent) for sym, e in replacements]
    lines += [lang.assign(t, e, indent) for t, e in zip(targets, reduced)]
    return lines


def _param_lines(lang: _Lang, indent: str, used: set) -> List[str]:
    return [
        f"{indent}{lang.declare}{n} = p[{i}]{lang.end}" for i, n in enumerate(PARAMETER_ORDER) if n in used
    ]


def _used_names(exprs: Sequence[sp.Expr]) -> set:
    names = set()
    for e in exprs:
        names |= {s.name for s in sp.sympify(e).free_symbols}
    return names


# -- the compiled kernel module (numba) ---------------------------------------------------------------
_NJIT = '@nb.njit(cache=True, error_model="numpy")'


def kernel_source(geometry: Parameters) -> str:
    """Source of the numba kernel module for ``geometry`` (scalars symbolic), without the
    integrator template that :func:`skewpend.compiled.kernel_module` appends."""
    return _kernel_source(_expressions(geometry), geometry)


def _kernel_source(ex: _Expressions, geometry: Parameters) -> str:
    py = _Lang("python", _py_printer(), "", "")
    I = "    "
    M = [ex.M[0, 0], ex.M[0, 1], ex.M[1, 1]]
    f = [ex.f[0], ex.f[1]]
    Q = [ex.Q[0], ex.Q[1]]
    state = ["phi", "psi", "dphi", "dpsi"]
    out: List[str] = [
        f'"""Generated by skewpend {__version__} from the symbolic derivation -- do not edit.',
        "",
        "State y = (phi, psi, dphi, dpsi, W): angles [rad], speeds [rad/s], and W [J], the work",
        "done by the non-potential forces Q = tau - c q' (so E(t) - W(t) is conserved).",
        f"Parameters p = ({', '.join(PARAMETER_ORDER)}).",
        f"Geometry: {geometry.to_dict() if not geometry.is_thin_rods else 'thin uniform rods, default axes'}",
        '"""',
        "import math",
        "import numpy as np",
        "import numba as nb",
        "",
    ]

    def header(name, args, doc, used_exprs):
        lines = [_NJIT, f"def {name}({args}):", f'{I}"""{doc}"""']
        used = _used_names(used_exprs)
        lines += [f"{I}{n} = y[{i}]" for i, n in enumerate(state) if n in used]
        lines += _param_lines(py, I, used)
        return lines

    def mass_forcing_solve(indent):
        # numeric 2x2 solve of M q'' = f (no symbolic inverse)
        return [
            f"{indent}det = M11 * M22 - M12 * M12",
            f"{indent}ddphi = (M22 * f1 - M12 * f2) / det",
            f"{indent}ddpsi = (M11 * f2 - M12 * f1) / det",
        ]

    # rhs
    exprs = M + f + Q
    out += header("rhs", "y, p, out", "dy/dt of y = (phi, psi, dphi, dpsi, W) into out (5,).", exprs)
    out += _cse_block(py, exprs, ["M11", "M12", "M22", "f1", "f2", "Q1", "Q2"], I)
    out += mass_forcing_solve(I)
    out += [
        f"{I}out[0] = y[2]",
        f"{I}out[1] = y[3]",
        f"{I}out[2] = ddphi",
        f"{I}out[3] = ddpsi",
        f"{I}out[4] = Q1 * y[2] + Q2 * y[3]",
        "",
        "",
    ]
    # energy
    out += header("energy", "y, p", "Mechanical energy T + Pi [J] of the state y.", [ex.T, ex.Pi])
    out += _cse_block(py, [ex.T + ex.Pi], ["E"], I)
    out += [f"{I}return E", "", ""]
    # jacobian
    dM = [[d[0, 0], d[0, 1], d[1, 1]] for d in ex.dM_dq]
    jac_exprs = M + f + list(ex.df_dy) + dM[0] + dM[1] + [sp.diff(x, v) for x in Q for v in (SYMBOLS["dphi"], SYMBOLS["dpsi"])]
    df_names = [f"df{i}{j}" for i in range(2) for j in range(4)]
    dM_names = [f"dM{k}_{n}" for k in range(2) for n in ("11", "12", "22")]
    dQ_names = ["dQ1_1", "dQ1_2", "dQ2_1", "dQ2_2"]
    out += header("jac", "y, p, out", "Jacobian d(dy/dt)/dy (5x5) into out.", jac_exprs + Q)
    out += _cse_block(py, jac_exprs + Q, ["M11", "M12", "M22", "f1", "f2"] + df_names + dM_names + dQ_names + ["Q1", "Q2"], I)
    out += mass_forcing_solve(I)
    out += [
        f"{I}for r in range(5):",
        f"{I}    for c in range(5):",
        f"{I}        out[r, c] = 0.0",
        f"{I}out[0, 2] = 1.0",
        f"{I}out[1, 3] = 1.0",
        f"{I}dMs = np.empty((2, 3))",
        *[f"{I}dMs[{k}, {n}] = dM{k}_{e}" for k in range(2) for n, e in enumerate(("11", "12", "22"))],
        f"{I}dfs = np.empty((2, 4))",
        *[f"{I}dfs[{r}, {c}] = df{r}{c}" for r in range(2) for c in range(4)],
        f"{I}for c in range(4):",
        f"{I}    r1 = dfs[0, c]",
        f"{I}    r2 = dfs[1, c]",
        f"{I}    if c < 2:",
        f"{I}        r1 -= dMs[c, 0] * ddphi + dMs[c, 1] * ddpsi",
        f"{I}        r2 -= dMs[c, 1] * ddphi + dMs[c, 2] * ddpsi",
        f"{I}    out[2, c] = (M22 * r1 - M12 * r2) / det",
        f"{I}    out[3, c] = (M11 * r2 - M12 * r1) / det",
        f"{I}out[4, 2] = Q1 + dQ1_1 * y[2] + dQ2_1 * y[3]",
        f"{I}out[4, 3] = Q2 + dQ1_2 * y[2] + dQ2_2 * y[3]",
        "",
        "",
    ]
    # canonical momenta and the Hamiltonian vector field (for the symplectic method)
    out += header("momenta", "y, p, out", "Canonical momenta p_q = M(q) q' [J s] of y into out (2,).", M)
    out += _cse_block(py, M, ["M11", "M12", "M22"], I)
    out += [f"{I}out[0] = M11 * y[2] + M12 * y[3]", f"{I}out[1] = M12 * y[2] + M22 * y[3]", "", ""]

    ham_exprs = M + list(ex.dPi_dq)
    out += [
        _NJIT,
        "def velocities(z, p, out):",
        f'{I}"""Speeds q\' = M(q)^-1 p_q of z = (phi, psi, p_phi, p_psi, W) into out (2,)."""',
    ]
    used = _used_names(M)
    out += [f"{I}{n} = z[{i}]" for i, n in enumerate(state[:2]) if n in used]
    out += _param_lines(py, I, used)
    out += _cse_block(py, M, ["M11", "M12", "M22"], I)
    out += [
        f"{I}det = M11 * M22 - M12 * M12",
        f"{I}out[0] = (M22 * z[2] - M12 * z[3]) / det",
        f"{I}out[1] = (M11 * z[3] - M12 * z[2]) / det",
        "",
        "",
    ]
    # ham_rhs: q' = M^-1 p; p' = dT/dq(q, q') - dPi/dq + Q(q'); W' = Q . q'
    out += [
        _NJIT,
        "def ham_rhs(z, p, out):",
        f'{I}"""dz/dt of z = (phi, psi, p_phi, p_psi, W) into out (5,) (Hamilton\'s equations)."""',
    ]
    used = _used_names(ham_exprs)
    out += [f"{I}{n} = z[{i}]" for i, n in enumerate(state[:2]) if n in used]
    out += _param_lines(py, I, used)
    out += _cse_block(py, ham_exprs, ["M11", "M12", "M22", "dPi1", "dPi2"], I)
    out += [
        f"{I}det = M11 * M22 - M12 * M12",
        f"{I}dphi = (M22 * z[2] - M12 * z[3]) / det",
        f"{I}dpsi = (M11 * z[3] - M12 * z[2]) / det",
    ]
    used2 = _used_names(list(ex.dT_dq) + Q)
    out += _param_lines(py, I, used2 - used)
    out += _cse_block(py, list(ex.dT_dq) + Q, ["dT1", "dT2", "Q1", "Q2"], I, prefix="u")
    out += [
        f"{I}out[0] = dphi",
        f"{I}out[1] = dpsi",
        f"{I}out[2] = dT1 - dPi1 + Q1",
        f"{I}out[3] = dT2 - dPi2 + Q2",
        f"{I}out[4] = Q1 * dphi + Q2 * dpsi",
        "",
        "",
    ]
    # rod-end positions and per-row evaluation helpers
    tips = list(ex.tips)
    out += header("tips", "y, p, out", "World positions of the rod ends (x1, y1, z1, x2, y2, z2) [m] into out (6,).", tips)
    out += _cse_block(py, tips, [f"t{i}" for i in range(6)], I)
    out += [f"{I}out[{i}] = t{i}" for i in range(6)] + ["", ""]
    out += [
        _NJIT,
        "def energies(ys, p):",
        f'{I}"""Mechanical energy of each row of ys (n, >=4)."""',
        f"{I}e = np.empty(ys.shape[0])",
        f"{I}for i in range(ys.shape[0]):",
        f"{I}    e[i] = energy(ys[i], p)",
        f"{I}return e",
        "",
        "",
        _NJIT,
        "def speeds_many(zs, p):",
        f'{I}"""Rows (phi, psi, p_phi, p_psi, W) -> (phi, psi, dphi, dpsi, W)."""',
        f"{I}ys = zs.copy()",
        f"{I}v = np.empty(2)",
        f"{I}for i in range(zs.shape[0]):",
        f"{I}    velocities(zs[i], p, v)",
        f"{I}    ys[i, 2] = v[0]",
        f"{I}    ys[i, 3] = v[1]",
        f"{I}return ys",
        "",
        "",
        _NJIT,
        "def tips_many(ys, p):",
        f'{I}"""Rod-end positions of each row of ys: (n, 6)."""',
        f"{I}r = np.empty((ys.shape[0], 6))",
        f"{I}for i in range(ys.shape[0]):",
        f"{I}    tips(ys[i], p, r[i])",
        f"{I}return r",
        "",
        "",
    ]
    return "\n".join(out) + "\n"


# -- standalone source for users -------------------------------------------------------------------------
def generate(params: Parameters, language: str) -> str:
    """Standalone source of the right-hand side and the energy in ``language``.

    ``language`` is ``"python"`` (``rhs(t, y, p)`` returning a list, ready for
    ``scipy.integrate.solve_ivp(rhs, ..., args=(p,))``), ``"c"`` (``skewpend_rhs``,
    ``skewpend_energy``) or ``"javascript"`` (``rhs(y, p)``, ``energy(y, p)``).  Geometry is
    baked in; scalar parameters are read from ``p`` in :data:`PARAMETER_ORDER`.
    """
    from .errors import ParameterError

    langs = {"python": _standalone_python, "c": _standalone_c, "javascript": _standalone_js}
    if language not in langs:
        raise ParameterError(f"unknown language {language!r}; allowed: {', '.join(langs)}")
    geometry = geometry_of(params)
    return langs[language](_expressions(geometry), geometry)


def _doc_lines(geometry: Parameters) -> List[str]:
    return [
        f"Generated by skewpend {__version__} from the symbolic derivation of the skewed double pendulum.",
        "State y = (phi, psi, dphi, dpsi): hinge angles [rad] (zero with both rods hanging) and their rates [rad/s].",
        f"Parameters p = ({', '.join(PARAMETER_ORDER)}) in SI units; alpha in radians.",
        "Equations: M(q) q'' = f(q, q'), solved numerically as a 2x2 linear system.",
        "Geometry: " + ("thin uniform rods, default hinge axes" if geometry.is_thin_rods else str(geometry.to_dict())),
    ]


def _body(lang: _Lang, ex: _Expressions, indent: str) -> Tuple[List[str], List[str]]:
    M = [ex.M[0, 0], ex.M[0, 1], ex.M[1, 1]]
    f = [ex.f[0], ex.f[1]]
    used = _used_names(M + f)
    rhs_lines = [f"{indent}{lang.declare}{n} = y[{i}]{lang.end}" for i, n in enumerate(STATE_ORDER) if n in used]
    rhs_lines += _param_lines(lang, indent, used)
    rhs_lines += _cse_block(lang, M + f, ["M11", "M12", "M22", "f1", "f2"], indent)
    rhs_lines += [
        f"{indent}{lang.declare}det = M11 * M22 - M12 * M12{lang.end}",
        f"{indent}{lang.declare}ddphi = (M22 * f1 - M12 * f2) / det{lang.end}",
        f"{indent}{lang.declare}ddpsi = (M11 * f2 - M12 * f1) / det{lang.end}",
    ]
    used = _used_names([ex.T, ex.Pi])
    en_lines = [f"{indent}{lang.declare}{n} = y[{i}]{lang.end}" for i, n in enumerate(STATE_ORDER) if n in used]
    en_lines += _param_lines(lang, indent, used)
    en_lines += _cse_block(lang, [ex.T + ex.Pi], ["E"], indent)
    return rhs_lines, en_lines


def _standalone_python(ex: _Expressions, geometry: Parameters) -> str:
    lang = _Lang("python", _py_printer(), "", "")
    rhs, en = _body(lang, ex, "    ")
    doc = "\n".join(_doc_lines(geometry))
    return "\n".join(
        [f'"""{doc}\n"""', "import math", "", "",
         "def rhs(t, y, p):", '    """dy/dt = (dphi, dpsi, ddphi, ddpsi); signature of scipy.integrate.solve_ivp."""',
         *rhs, "    return [y[2], y[3], ddphi, ddpsi]", "", "",
         "def energy(y, p):", '    """Mechanical energy T + Pi [J]; Pi = 0 with both rods hanging."""',
         *en, "    return E", ""]
    )


def _standalone_c(ex: _Expressions, geometry: Parameters) -> str:
    lang = _Lang("c", _c_printer(), "const double ", ";")
    rhs, en = _body(lang, ex, "    ")
    doc = "\n".join(" * " + line for line in _doc_lines(geometry))
    return "\n".join(
        ["/*", doc, " */", "#include <math.h>", "",
         "/* dydt = (dphi, dpsi, ddphi, ddpsi) */",
         "void skewpend_rhs(const double y[4], const double p[10], double dydt[4])", "{",
         *rhs, "    dydt[0] = y[2];", "    dydt[1] = y[3];", "    dydt[2] = ddphi;", "    dydt[3] = ddpsi;", "}", "",
         "/* mechanical energy T + Pi [J] */",
         "double skewpend_energy(const double y[4], const double p[10])", "{", *en, "    return E;", "}", ""]
    )


def _standalone_js(ex: _Expressions, geometry: Parameters) -> str:
    lang = _Lang("javascript", _js_printer(), "const ", ";")
    rhs, en = _body(lang, ex, "  ")
    doc = "\n".join(" * " + line for line in _doc_lines(geometry))
    return "\n".join(
        ["/**", doc, " */", "",
         "/** dy/dt = [dphi, dpsi, ddphi, ddpsi] */",
         "export function rhs(y, p) {", *rhs, "  return [y[2], y[3], ddphi, ddpsi];", "}", "",
         "/** mechanical energy T + Pi [J] */",
         "export function energy(y, p) {", *en, "  return E;", "}", ""]
    )
