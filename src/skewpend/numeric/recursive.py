"""A chain's equations of motion by recursive algorithms, printed as straight-line code.

For a chain of any length (:class:`skewpend.symbolic.chain.Chain`) the equations ``M(q) q'' = f(q, q')``
are built by the recursive algorithms of multibody dynamics on CasADi's scalar expression graphs
(``casadi.SX``: common subexpressions shared, zeros folded), in the world frame with every body
frame parallel to ``i, j, k`` when the chain hangs (the specification's conventions, ``j`` down):

* kinematics link by link, the specification's rotation tensors composed
  ``R_i = R_{i-1} P(q_i, e_i)`` (Rodrigues' formula about the numeric unit axis ``e_i``), the hinge
  ``o_i = o_{i-1} + R_{i-1} h_i``, its axis ``a_i = R_{i-1} e_i``;
* the mass matrix by the composite-rigid-body algorithm: ``M_kl = S_k . (I_C(l) S_l)`` for ``k <= l``,
  ``S_k = (a_k, o_k x a_k)`` the unit twist of hinge ``k`` and ``I_C(l)`` the spatial inertia of the
  links ``l ... n`` about the origin;
* the forcing by the recursive Newton-Euler algorithm at ``q'' = 0`` (velocity, gravity terms) plus
  the joint forces ``Q_i = tau_i - c_i q_i' - cf_i atan(cfs q_i')``;
* the energy ``T + Pi`` (``Pi = 0`` hanging), and ``dT/dq`` for Hamilton's equations by CasADi's
  automatic differentiation; the rotors' kinetic energy ``Ir/2 (omega_parent . a_i + gr q_i')^2``
  enters through Lagrange's equations (differentiated the same way).

The structure compiles (the number of links, the hinge axes, whether friction and rotor terms exist);
every value -- hinge offsets, masses, centres of mass, inertias, damping, friction, torques, rotors,
``g`` -- is the run-time array ``p`` in :func:`parameter_names`' order.  The checks: the two-link chain
against the symbolic derivation (:func:`skewpend.derive`), every chain against MuJoCo
(``tests/test_chain.py``).  The linear solve is the kernels' one LDL^T (``codegen.spd_c_lines``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Dict, List, Sequence, Tuple

from ..errors import require
from ..schema import CHAIN_NAMES, LINK_FIELDS
from ..symbolic.chain import Chain

__all__ = ["ChainStructure", "structure_of_chain", "parameter_names", "parameter_vector", "PER_LINK",
           "chain_functions", "c_function_lines"]

def _per_link() -> Tuple[str, ...]:
    """One link's entries of ``p``, from the schema's link fields in their order: every field but the
    axis (the structure), a vector as its three components, an inertia as its six entries."""
    from .conventions import TENSOR_ENTRIES

    out: List[str] = []
    for key, stem, kind in LINK_FIELDS:
        if key == "axis":
            continue
        short = {"com": "r", "inertia": "I"}.get(stem, stem)
        out += {"vector": [f"{short}{x}" for x in "xyz"], "inertia": [f"{short}{e}" for e in TENSOR_ENTRIES],
                "scalar": [stem]}[kind]
    return tuple(out)


#: One link's entries of ``p``, in order (the hinge offset, the rod's length, the body, the joint).
PER_LINK = _per_link()
#: The chain's own entries, after the links'.
GLOBAL = CHAIN_NAMES


@dataclass(frozen=True)
class ChainStructure:
    """What a chain's compiled code depends on: its hinge axes and which optional terms exist.
    Everything else is read from ``p``."""

    axes: Tuple[Tuple[float, float, float], ...]
    friction: bool
    rotor: bool

    @property
    def n(self) -> int:
        return len(self.axes)

    def key(self) -> str:
        axes = ";".join(",".join(repr(float(x)) for x in a) for a in self.axes)
        return f"chain{self.n}|{axes}|f{int(self.friction)}|r{int(self.rotor)}"


def structure_of_chain(chain: Chain) -> ChainStructure:
    return ChainStructure(tuple(link.axis for link in chain.links), chain.has_friction, chain.has_rotor)


def parameter_names(n: int) -> Tuple[str, ...]:
    """The names of ``p``'s entries for ``n`` links: ``hx1, hy1, ..., gr1, hx2, ..., g, cfs``."""
    return tuple(f"{e}{i}" for i in range(1, n + 1) for e in PER_LINK) + GLOBAL


def parameter_vector(chain: Chain):
    """The run-time array ``p`` of ``chain`` (float64, :func:`parameter_names`' order)."""
    import numpy as np

    from .conventions import TENSOR_INDICES

    out: List[float] = []
    for link in chain.links:
        for key, _, kind in LINK_FIELDS:
            value: Any = getattr(link, key)
            if key == "axis":
                continue
            if kind == "vector":
                out += [float(x) for x in value]
            elif kind == "inertia":
                out += [float(value[i][j]) for i, j in TENSOR_INDICES]
            else:
                out.append(float(value))
    out += [float(getattr(chain, k)) for k in CHAIN_NAMES]
    return np.array(out, dtype=float)


def _ca():
    return require("casadi", "a chain of links (its recursive algorithms)")


def _cross(ca, u, v):
    return ca.vertcat(u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])


def _rotation(ca, c, s, e):
    """Rodrigues' formula ``P(q, e) = cos q E + sin q [e]x + (1 - cos q) e e^T`` for a numeric unit ``e``."""
    x, y, z = e
    k = 1 - c
    return ca.vertcat(
        ca.horzcat(c + k * x * x, k * x * y - s * z, k * x * z + s * y),
        ca.horzcat(k * y * x + s * z, c + k * y * y, k * y * z - s * x),
        ca.horzcat(k * z * x - s * y, k * z * y + s * x, c + k * z * z),
    )


class _Graph:
    """The chain's quantities on SX graphs of ``q, q'`` (``y``) and ``p``."""

    def __init__(self, structure: ChainStructure):
        ca = self.ca = _ca()
        n = self.n = structure.n
        self.structure = structure
        self.q, self.dq = ca.SX.sym("q", n), ca.SX.sym("dq", n)
        self.p = ca.SX.sym("p", len(parameter_names(n)))
        P = self.p
        w = len(PER_LINK)
        chain_values = {k: P[n * w + i] for i, k in enumerate(GLOBAL)}
        self.g, self.cfs = chain_values["g"], chain_values["cfs"]
        self.link = [{name: P[i * w + k] for k, name in enumerate(PER_LINK)} for i in range(n)]
        R = ca.SX.eye(3)
        o = ca.SX.zeros(3, 1)
        self.R, self.o, self.a, self.c, self.Iw, self.oa = [], [], [], [], [], []
        for i in range(n):
            L = self.link[i]
            o = o + ca.mtimes(R, ca.vertcat(L["hx"], L["hy"], L["hz"]))
            a = ca.mtimes(R, ca.DM(list(structure.axes[i])))
            R = ca.mtimes(R, _rotation(ca, ca.cos(self.q[i]), ca.sin(self.q[i]), structure.axes[i]))
            Ib = ca.vertcat(ca.horzcat(L["Ixx"], L["Ixy"], L["Ixz"]), ca.horzcat(L["Ixy"], L["Iyy"], L["Iyz"]),
                            ca.horzcat(L["Ixz"], L["Iyz"], L["Izz"]))
            self.R.append(R)
            self.o.append(o)
            self.a.append(a)
            self.oa.append(_cross(ca, o, a))  # the moment part of hinge i's unit twist (a_i, o_i x a_i)
            self.c.append(o + ca.mtimes(R, ca.vertcat(L["rx"], L["ry"], L["rz"])))
            self.Iw.append(ca.mtimes(ca.mtimes(R, Ib), R.T))
        # velocities: omega_i = omega_{i-1} + a_i q_i'; the centres of mass' velocities
        self.omega, self.v = [], []
        omega = ca.SX.zeros(3, 1)
        v_o = ca.SX.zeros(3, 1)
        o_prev = ca.SX.zeros(3, 1)
        for i in range(n):
            v_o = v_o + _cross(ca, omega, self.o[i] - o_prev)  # the hinge moves with the parent
            omega = omega + self.a[i] * self.dq[i]
            self.omega.append(omega)
            self.v.append(v_o + _cross(ca, omega, self.c[i] - self.o[i]))
            o_prev = self.o[i]

    # -- the mass matrix: composite rigid bodies ----------------------------------------------------------
    def mass_matrix(self):
        ca, n = self.ca, self.n
        M = [[None] * n for _ in range(n)]
        mC = 0
        hC = ca.SX.zeros(3, 1)  # first moment sum m c about the origin
        JC = ca.SX.zeros(3, 3)  # inertia about the origin
        for l in reversed(range(n)):
            m, c = self.link[l]["m"], self.c[l]
            mC = mC + m
            hC = hC + m * c
            JC = JC + self.Iw[l] + m * (ca.dot(c, c) * ca.SX.eye(3) - ca.mtimes(c, c.T))
            # the momentum of the composite l..n under the unit twist of hinge l: omega = a_l, v(0) = o_l x a_l
            w, v0 = self.a[l], self.oa[l]
            lin = mC * v0 + _cross(ca, w, hC)
            ang = ca.mtimes(JC, w) + _cross(ca, hC, v0)
            for k in range(l + 1):
                M[k][l] = M[l][k] = ca.dot(self.a[k], ang) + ca.dot(self.oa[k], lin)
        if self.structure.rotor:
            for i in range(n):
                u = self._rotor_row(i)
                Ir = self.link[i]["Ir"]
                for k in range(n):
                    for l in range(k + 1):
                        if u[k] is not None and u[l] is not None:
                            M[k][l] = M[k][l] + Ir * u[k] * u[l]
                            if k != l:
                                M[l][k] = M[k][l]
        return M

    def _rotor_row(self, i):
        """d(spin of rotor i)/dq': the parent's axes projected on a_i, and gr_i at i (None: 0)."""
        ca = self.ca
        row = [ca.dot(self.a[k], self.a[i]) for k in range(i)] + [self.link[i]["gr"]] + [None] * (self.n - i - 1)
        return row

    def rotor_energy(self):
        ca = self.ca
        T = 0
        for i in range(self.n):
            parent = self.omega[i - 1] if i > 0 else ca.SX.zeros(3, 1)
            spin = ca.dot(parent, self.a[i]) + self.link[i]["gr"] * self.dq[i]
            T = T + self.link[i]["Ir"] * spin * spin / 2
        return T

    # -- the forcing: recursive Newton-Euler at q'' = 0 -----------------------------------------------------
    def joint_forces(self, dq=None):
        ca = self.ca
        dq = self.dq if dq is None else dq
        out = []
        for i in range(self.n):
            L = self.link[i]
            Q = L["tau"] - L["c"] * dq[i]
            if self.structure.friction:
                Q = Q - L["cf"] * ca.atan(self.cfs * dq[i])
            out.append(Q)
        return out

    def bias(self):
        """``C(q, q') q' + dPi/dq`` (the inverse dynamics at ``q'' = 0``, rotors included)."""
        ca, n = self.ca, self.n
        down = ca.DM([0.0, 1.0, 0.0])
        omega = ca.SX.zeros(3, 1)
        alpha = ca.SX.zeros(3, 1)
        acc_o = ca.SX.zeros(3, 1)
        o_prev = ca.SX.zeros(3, 1)
        F, N = [], []
        for i in range(n):
            d = self.o[i] - o_prev
            acc_o = acc_o + _cross(ca, alpha, d) + _cross(ca, omega, _cross(ca, omega, d))
            alpha = alpha + _cross(ca, omega, self.a[i] * self.dq[i])
            omega = self.omega[i]
            r = self.c[i] - self.o[i]
            acc_c = acc_o + _cross(ca, alpha, r) + _cross(ca, omega, _cross(ca, omega, r))
            m = self.link[i]["m"]
            F.append(m * (acc_c - self.g * down))
            Iw = self.Iw[i]
            N.append(ca.mtimes(Iw, alpha) + _cross(ca, omega, ca.mtimes(Iw, omega)))
            o_prev = self.o[i]
        tau = [None] * n
        f = ca.SX.zeros(3, 1)
        nm = ca.SX.zeros(3, 1)  # moment about o_i of the links i..n
        for i in reversed(range(n)):
            if i < n - 1:
                nm = nm + _cross(ca, self.o[i + 1] - self.o[i], f)
            nm = nm + N[i] + _cross(ca, self.c[i] - self.o[i], F[i])
            f = f + F[i]
            tau[i] = ca.dot(self.a[i], nm)
        if self.structure.rotor:  # Lagrange's equations of the rotors' energy at q'' = 0
            Tr = self.rotor_energy()
            dT = ca.gradient(Tr, self.dq)
            extra = ca.mtimes(ca.jacobian(dT, self.q), self.dq) - ca.gradient(Tr, self.q)
            tau = [tau[i] + extra[i] for i in range(n)]
        return tau

    def lagrangian_gradient(self):
        """``dT/dq - dPi/dq`` at fixed ``q'`` (Hamilton's equations' ``p'`` without ``Q``), link by link:
        turning hinge ``i`` at fixed speeds turns the links ``i ... n`` and their joints' twists, so
        ``dT/dq_i = (V_{i-1} x S_i) . H_i`` with ``V_{i-1}`` the parent's twist, ``S_i`` hinge ``i``'s unit
        twist and ``H_i`` the spatial momentum of the links ``i ... n``; ``dPi/dq_i = -g j . (a_i x (h_i -
        m_i o_i))`` with ``m_i``, ``h_i`` their mass and first moment.  The rotors' part by CasADi's
        automatic differentiation of their energy."""
        ca, n = self.ca, self.n
        L = [None] * n
        lin = ca.SX.zeros(3, 1)
        ang = ca.SX.zeros(3, 1)
        mC, hC = 0, ca.SX.zeros(3, 1)
        for i in reversed(range(n)):
            m, c = self.link[i]["m"], self.c[i]
            p_lin = m * self.v[i]
            lin = lin + p_lin
            ang = ang + _cross(ca, c, p_lin) + ca.mtimes(self.Iw[i], self.omega[i])
            mC, hC = mC + m, hC + m * c
            L[i] = (lin, ang, mC, hC)
        out = []
        w_prev, v0_prev = ca.SX.zeros(3, 1), ca.SX.zeros(3, 1)  # the parent's twist at the origin
        for i in range(n):
            lin, ang, mC, hC = L[i]
            a, oa = self.a[i], self.oa[i]
            dS_ang = _cross(ca, w_prev, a)
            dS_lin = _cross(ca, w_prev, oa) + _cross(ca, v0_prev, a)
            dT = ca.dot(dS_ang, ang) + ca.dot(dS_lin, lin)
            dPi = -self.g * _cross(ca, a, hC - mC * self.o[i])[1]
            out.append(dT - dPi)
            w_prev, v0_prev = w_prev + a * self.dq[i], v0_prev + oa * self.dq[i]
        if self.structure.rotor:
            Tr = self.rotor_energy()
            g = ca.gradient(Tr, self.q)
            out = [out[i] + g[i] for i in range(n)]
        return out

    # -- energies ------------------------------------------------------------------------------------------
    def kinetic_energy(self):
        ca = self.ca
        T = 0
        for i in range(self.n):
            T = T + (self.link[i]["m"] * ca.dot(self.v[i], self.v[i]) + ca.dot(self.omega[i], ca.mtimes(self.Iw[i], self.omega[i]))) / 2
        if self.structure.rotor:
            T = T + self.rotor_energy()
        return T

    def potential_energy(self):
        """``Pi = -g sum m_i j . c_i``, zero with the chain hanging."""
        ca = self.ca
        Pi = 0
        o = ca.SX.zeros(3, 1)
        for i in range(self.n):
            L = self.link[i]
            o = o + ca.vertcat(L["hx"], L["hy"], L["hz"])
            hanging_y = o[1] + L["ry"]
            Pi = Pi - self.g * L["m"] * (self.c[i][1] - hanging_y)
        return Pi

    def ends(self):
        """The rods' ends ``o_i + R_i (0, l_i, 0)`` (the last one is the chain's tip)."""
        return [self.o[i] + self.R[i][:, 1] * self.link[i]["l"] for i in range(self.n)]


def _packed(M, n):
    return [M[i][j] for i in range(n) for j in range(i + 1)]


@lru_cache(maxsize=16)
def chain_functions(structure: ChainStructure) -> Dict[str, object]:
    """CasADi functions of the chain (``y = (q, q')``, ``p``): ``model`` -> (M packed lower, f = Q - bias),
    ``mass`` -> M packed, ``energy`` -> T + Pi, ``hamilton`` -> (dT/dq - dPi/dq, Q) for Hamilton's
    equations, ``ends`` -> the rods' ends, ``axes`` -> the hinge axes (3 n each, world frame)."""
    ca = _ca()
    G = _Graph(structure)
    n = G.n
    y = ca.vertcat(G.q, G.dq)
    M = G.mass_matrix()
    Q = G.joint_forces()
    b = G.bias()
    f = [Q[i] - b[i] for i in range(n)]
    T, Pi = G.kinetic_energy(), G.potential_energy()
    fns = {
        "model": ca.Function("model", [y, G.p], [ca.vertcat(*_packed(M, n)), ca.vertcat(*f), ca.vertcat(*Q)]),
        "mass": ca.Function("mass", [G.q, G.p], [ca.vertcat(*_packed(M, n))]),
        "energy": ca.Function("energy", [y, G.p], [T + Pi]),
        "hamilton": ca.Function("hamilton", [y, G.p], [ca.vertcat(*G.lagrangian_gradient()), ca.vertcat(*Q)]),
        "ends": ca.Function("ends", [G.q, G.p], [ca.vertcat(*G.ends())]),
        "axes": ca.Function("axes", [G.q, G.p], [ca.vertcat(*G.a)]),
    }
    return fns


# -- printing CasADi's instructions as C -------------------------------------------------------------------
def c_function_lines(fn, inputs: Sequence[str], outputs: Sequence[Sequence[str]], indent: str = "    ",
                     declare: bool = True) -> List[str]:
    """C statements evaluating the CasADi SX function ``fn``: ``inputs[k]`` is the C array expression
    of its input ``k``, ``outputs[k][j]`` the name that receives entry ``j`` of output ``k`` (declared
    ``double`` when ``declare``).  Work registers are ``double`` locals ``w0, w1, ...``."""
    ca = _ca()
    ops = {ca.OP_ADD: "{0} + {1}", ca.OP_SUB: "{0} - {1}", ca.OP_MUL: "{0} * {1}", ca.OP_DIV: "{0} / {1}",
           ca.OP_NEG: "-{0}", ca.OP_SQ: "{0} * {0}", ca.OP_TWICE: "2.0 * {0}", ca.OP_SIN: "sin({0})",
           ca.OP_COS: "cos({0})", ca.OP_ATAN: "atan({0})", ca.OP_SQRT: "sqrt({0})", ca.OP_INV: "1.0 / {0}",
           ca.OP_ASSIGN: "{0}", ca.OP_FABS: "fabs({0})", ca.OP_EXP: "exp({0})", ca.OP_LOG: "log({0})",
           ca.OP_TAN: "tan({0})", ca.OP_POW: "pow({0}, {1})", ca.OP_CONSTPOW: "pow({0}, {1})"}
    lines: List[str] = []
    if declare:
        lines += [f"{indent}double {', '.join(name for out in outputs for name in out)};"]
    nw = fn.sz_w()
    if nw:
        lines += [f"{indent}double " + ", ".join(f"w{k}" for k in range(nw)) + ";"]
    for k in range(fn.n_instructions()):
        op = fn.instruction_id(k)
        ins, outs = fn.instruction_input(k), fn.instruction_output(k)
        if op == ca.OP_INPUT:
            lines.append(f"{indent}w{outs[0]} = {inputs[ins[0]]}[{ins[1]}];")
        elif op == ca.OP_OUTPUT:
            lines.append(f"{indent}{outputs[outs[0]][outs[1]]} = w{ins[0]};")
        elif op == ca.OP_CONST:
            lines.append(f"{indent}w{outs[0]} = {float(fn.instruction_constant(k))!r};")
        elif op in ops:
            args = [f"w{i}" for i in ins]
            lines.append(f"{indent}w{outs[0]} = {ops[op].format(*args)};")
        else:
            raise NotImplementedError(f"CasADi operation {op} has no C form here")
    return lines


def chain_c_source(structure: ChainStructure) -> str:
    """C source of a chain's model functions with the integrators' contract (``integrators.c``):
    ``rhs``, ``ham_rhs``, ``energy``, ``momenta``, ``velocities``, ``tips`` (the rods' ends, 3 n),
    ``axes`` (3 n), and the layout ``SP_NQ``, ``SP_NPARAM``, ``SP_NMAX``; the exported entry points are
    the kernels' (``kernel_source.exports``)."""
    from .. import __version__
    from .codegen import spd_c_lines
    from .kernel_source import exports, status_defines

    fns = chain_functions(structure)
    n = structure.n
    names = parameter_names(n)
    I = "    "
    Mn = [f"M{i}_{j}" for i in range(n) for j in range(i + 1)]
    f = [f"f{i}" for i in range(n)]
    Q = [f"Q{i}" for i in range(n)]
    acc = [f"acc{i}" for i in range(n)]
    torque = [names.index(f"tau{i}") for i in range(1, n + 1)]
    out = [
        f"/* Generated by skewpend {__version__} from a chain's recursive algorithms -- do not edit.",
        f" * {n} links; hinge axes {'; '.join('(' + ', '.join(f'{x:.17g}' for x in a) + ')' for a in structure.axes)}.",
        f" * State y = (q1..q{n}, dq1..dq{n}, W); parameters p = ({', '.join(names)}).",
        " */",
        "#include <math.h>",
        "#include <stdint.h>",
        *status_defines(),
        f"#define SP_NQ {n}",
        f"#define SP_NPARAM {len(names)}",
        f"#define SP_NMAX {max(8, 2 * n + 2)}",
        f"#define SP_TAU1 {torque[0]}",
        f"#define SP_TAU2 {torque[min(1, n - 1)]}  /* two inputs of the integrators' controllers (links 1 and 2) */",
        "#define SP_NO_JAC 1",
        "",
        "/* dy/dt into out[2 n + 1]: M q'' = f solved by LDL^T; W' = Q . q' */",
        "static void rhs(const double *y, const double *p, double *out)",
        "{",
    ]
    out += c_function_lines(fns["model"], ["y", "p"], [Mn, f, Q], I)
    out += spd_c_lines(I, f, acc, M=Mn)
    out += [f"{I}out[{i}] = y[{n + i}];" for i in range(n)]
    out += [f"{I}out[{n + i}] = {acc[i]};" for i in range(n)]
    out += [f"{I}out[{2 * n}] = " + " + ".join(f"Q{i} * y[{n + i}]" for i in range(n)) + ";", "}", ""]
    out += ["/* mechanical energy T + Pi [J] */", "static double energy(const double *y, const double *p)", "{"]
    out += c_function_lines(fns["energy"], ["y", "p"], [["E"]], I) + [f"{I}return E;", "}", ""]
    out += ["/* the mass matrix M(q), its packed lower triangle, into out[n (n + 1) / 2] */",
            "static void mass(const double *q, const double *p, double *out)", "{"]
    out += c_function_lines(fns["mass"], ["q", "p"], [[f"out[{k}]" for k in range(len(Mn))]], I, declare=False)
    out += ["}", ""]
    load_mass = [f"{I}double sp_M[{len(Mn)}];", f"{I}mass(%s, p, sp_M);"] + \
        [f"{I}const double {name} = sp_M[{k}];" for k, name in enumerate(Mn)]
    out += ["/* p_q = M(q) q' into out[n] */", "static void momenta(const double *y, const double *p, double *out)", "{"]
    out += [line.replace("%s", "y") for line in load_mass]
    M = lambda i, j: Mn[max(i, j) * (max(i, j) + 1) // 2 + min(i, j)]  # noqa: E731
    out += [f"{I}out[{i}] = " + " + ".join(f"{M(i, j)} * y[{n + j}]" for j in range(n)) + ";" for i in range(n)]
    out += ["}", ""]
    v = [f"v{i}" for i in range(n)]
    out += ["/* q' = M(q)^-1 p_q into out[n] */", "static void velocities(const double *z, const double *p, double *out)", "{"]
    out += [line.replace("%s", "z") for line in load_mass]
    out += spd_c_lines(I, [f"z[{n + i}]" for i in range(n)], v, M=Mn)
    out += [f"{I}out[{i}] = {v[i]};" for i in range(n)] + ["}", ""]
    out += ["/* dz/dt of z = (q, p_q, W) into out[2 n + 1]: q' = M^-1 p_q, p_q' = dT/dq - dPi/dq + Q */",
            "static void ham_rhs(const double *z, const double *p, double *out)", "{"]
    out += [line.replace("%s", "z") for line in load_mass]
    out += spd_c_lines(I, [f"z[{n + i}]" for i in range(n)], v, M=Mn)
    out += [f"{I}double yv[{2 * n}];"] + [f"{I}yv[{i}] = z[{i}]; yv[{n + i}] = {v[i]};" for i in range(n)]
    dT = [f"dL{i}" for i in range(n)]
    out += [f"{I}{{"] + c_function_lines(fns["hamilton"], ["yv", "p"], [dT, Q], I + I)
    out += [f"{I}{I}out[{i}] = {v[i]};" for i in range(n)]
    out += [f"{I}{I}out[{n + i}] = dL{i} + Q{i};" for i in range(n)]
    out += [f"{I}{I}out[{2 * n}] = " + " + ".join(f"Q{i} * {v[i]}" for i in range(n)) + ";", f"{I}}}", "}", ""]
    for name, doc in (("ends", "the rods' ends (x, y, z per link) [m] into out[3 n]"),
                      ("axes", "the hinge axes in the world frame into out[3 n]")):
        c_name = "tips" if name == "ends" else "axes"
        out += [f"/* {doc} */", f"static void {c_name}(const double *y, const double *p, double *out)", "{"]
        out += c_function_lines(fns[name], ["y", "p"], [[f"out[{k}]" for k in range(3 * n)]], I, declare=False)
        out += ["}", ""]
    out.append(exports())
    return "\n".join(out) + "\n"
