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

The structure compiles (the number of links, the hinge axes' patterns -- which components are zero,
:func:`axis_pattern` -- and whether friction and rotor terms exist); every value -- the hinge axes'
components, offsets, masses, centres of mass, inertias, damping, friction, torques, rotors, ``g`` -- is
the run-time array ``p`` in :func:`parameter_names`' order, so tilting an axis within its pattern
compiles nothing.  The checks: the two-link chain
against the symbolic derivation (:func:`skewpend.derive`), every chain against MuJoCo
(``tests/test_chain.py``).  The linear solve is the kernels' one LDL^T (``codegen.spd_c_lines``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from itertools import accumulate
from typing import Any, Dict, List, Sequence, Tuple

from ..errors import require
from ..schema import CHAIN_NAMES, LINK_FIELDS
from ..symbolic.chain import Chain

__all__ = ["ChainStructure", "axis_pattern", "axis_of", "structure_of_chain", "parameter_names", "parameter_vector", "PER_LINK",
           "chain_functions", "c_function_lines", "function_lines", "chain_code", "CODE_LANGUAGES", "standard_names",
           "standard_vector", "regressor_function", "hinge_positions"]

def _per_link() -> Tuple[str, ...]:
    """One link's entries of ``p``, from the schema's link fields in their order: a vector as its three
    components (the hinge axis ``ex, ey, ez`` first), an inertia as its six entries."""
    from .conventions import TENSOR_ENTRIES

    out: List[str] = []
    for key, stem, kind in LINK_FIELDS:
        short = {"com": "r", "inertia": "I", "axis": "e"}.get(stem, stem)
        out += {"vector": [f"{short}{x}" for x in "xyz"], "inertia": [f"{short}{e}" for e in TENSOR_ENTRIES],
                "scalar": [stem]}[kind]
    return tuple(out)


#: One link's entries of ``p``, in order (the hinge offset, the rod's length, the body, the joint).
PER_LINK = _per_link()
#: The chain's own entries, after the links'.
GLOBAL = CHAIN_NAMES


def axis_pattern(axis) -> str:
    """What of a unit hinge axis is structure: its components that are not zero (``"xz"``: an axis in the
    ``i, k`` plane, ``"xyz"``: any) -- their values are entries of ``p`` -- or, for an axis along a
    coordinate direction, that direction (``"+z"``: ``k``; ``"-x"``: ``-i``), a constant.  A tilt within
    the pattern compiles nothing; the pattern keys only the straight-line code, where the zeros fold
    (a generic axis in ``p`` costs a planar triple pendulum 5.5x its operations, the zero pattern a
    skewed one 2.7 %: ``docs/benchmarks.md``)."""
    nonzero = [(c, float(x)) for c, x in zip("xyz", axis) if float(x) != 0.0]
    if len(nonzero) == 1:
        return ("+" if nonzero[0][1] > 0 else "-") + nonzero[0][0]
    return "".join(c for c, _ in nonzero)


def axis_of(pattern: str, link: Dict[str, Any]):
    """The hinge axis of ``pattern`` as three entries: constants, zeros, or ``link``'s ``ex, ey, ez``."""
    if pattern[0] in "+-":
        sign = 1.0 if pattern[0] == "+" else -1.0
        return tuple(sign if c == pattern[1] else 0.0 for c in "xyz")
    return tuple(link[f"e{c}"] if c in pattern else 0.0 for c in "xyz")


@dataclass(frozen=True)
class ChainStructure:
    """What a chain's compiled code depends on: its hinge axes' patterns (:func:`axis_pattern`) and
    which optional terms exist.  Everything else, the axes' components included, is read from ``p``."""

    patterns: Tuple[str, ...]
    friction: bool
    rotor: bool

    @property
    def n(self) -> int:
        return len(self.patterns)

    def key(self, form: str = "straight") -> str:
        """The compile key of ``form``'s code: the compact form loops over the links with each axis read
        from ``p``, so its key has no patterns."""
        axes = "" if form == "compact" else ";".join(self.patterns)
        return f"chain{self.n}|{axes}|f{int(self.friction)}|r{int(self.rotor)}"


#: Chains of this many links and more take the compact form (:func:`compact_c_source`): its code does
#: not grow with the links, so it compiles in about 1.5 s at any length, where the straight-line code of
#: :func:`chain_c_source` grows by ~1 s a link (docs/benchmarks.md: the measured times of both).
COMPACT_FROM = 4


def chain_form(structure: "ChainStructure") -> str:
    """``"compact"`` or ``"straight"``: the form of the chain's compiled code (rotors: straight only)."""
    return "compact" if structure.n >= COMPACT_FROM and not structure.rotor else "straight"


def chain_source(structure: "ChainStructure", form: str = "") -> str:
    """The C source of the chain's model functions in ``form`` (default :func:`chain_form`)."""
    form = form or chain_form(structure)
    return compact_c_source(structure) if form == "compact" else chain_c_source(structure)


def structure_of_chain(chain: Chain) -> ChainStructure:
    return ChainStructure(tuple(axis_pattern(link.axis) for link in chain.links), chain.has_friction, chain.has_rotor)


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
    """Rodrigues' formula ``P(q, e) = cos q E + sin q [e]x + (1 - cos q) e e^T`` for a unit ``e`` (its entries
    constants or entries of ``p``; a zero folds away)."""
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
            e = axis_of(structure.patterns[i], L)
            a = ca.mtimes(R, ca.vertcat(*e))
            R = ca.mtimes(R, _rotation(ca, ca.cos(self.q[i]), ca.sin(self.q[i]), e))
            Ib = _sym6(ca, [L[f"I{t}"] for t in ("xx", "xy", "xz", "yy", "yz", "zz")])
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

    def equations(self):
        """``(M, Q, bias)``: ``M(q) q'' = Q - bias`` (:meth:`mass_matrix`, :meth:`joint_forces`, :meth:`bias`)."""
        return self.mass_matrix(), self.joint_forces(), self.bias()

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
        return [self.ca.dot(self.a[k], self.a[i]) for k in range(i)] + [self.link[i]["gr"]] + [None] * (self.n - i - 1)

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
        """``Pi = -g sum m_i (j c_i)``, zero with the chain hanging."""
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

    def hinges(self):
        """The hinges' positions ``o_i`` (hinge ``i + 1`` at ``o_i + R_i h_{i+1}``, ``h`` its offset): where the
        drawings join the links (a link drawn from its hinge to the next one, the last to its rod's end)."""
        return list(self.o)


def _packed(M, n):
    return [M[i][j] for i in range(n) for j in range(i + 1)]


@lru_cache(maxsize=16)
def chain_functions(structure: ChainStructure) -> Dict[str, object]:
    """CasADi functions of the chain (``y = (q, q')``, ``p``): ``model`` -> (M packed lower, f = Q - bias),
    ``mass`` -> M packed, ``energy`` -> T + Pi, ``hamilton`` -> (dT/dq - dPi/dq, Q) for Hamilton's
    equations, ``ends`` -> the rods' ends, ``hinges`` -> the hinges' positions, ``axes`` -> the hinge axes (3 n
    each, world frame)."""
    ca = _ca()
    G = _Graph(structure)
    n = G.n
    y = ca.vertcat(G.q, G.dq)
    M, Q, b = G.equations()
    f = [Q[i] - b[i] for i in range(n)]
    T, Pi = G.kinetic_energy(), G.potential_energy()
    fns = {
        "model": ca.Function("model", [y, G.p], [ca.vertcat(*_packed(M, n)), ca.vertcat(*f), ca.vertcat(*Q)]),
        "mass": ca.Function("mass", [G.q, G.p], [ca.vertcat(*_packed(M, n))]),
        "energy": ca.Function("energy", [y, G.p], [T + Pi]),
        "hamilton": ca.Function("hamilton", [y, G.p], [ca.vertcat(*G.lagrangian_gradient()), ca.vertcat(*Q)]),
        "ends": ca.Function("ends", [G.q, G.p], [ca.vertcat(*G.ends())]),
        "hinges": ca.Function("hinges", [G.q, G.p], [ca.vertcat(*G.hinges())]),
        "axes": ca.Function("axes", [G.q, G.p], [ca.vertcat(*G.a)]),
    }
    return fns


def hinge_positions(chain: Chain, q):
    """The hinges' positions of ``chain`` at the angles ``q`` (one row of n angles, or rows of them: only the
    first n columns are read, so states do), world frame, j down [m]: shape (rows, n, 3), or (n, 3) for one
    row -- from the recursive algorithms' graph (:func:`chain_functions`' ``hinges``), evaluated over the rows
    at once.  With every hinge at the end of the rod before, hinge ``i + 1`` is rod ``i``'s end."""
    import numpy as np

    q = np.asarray(q, dtype=float)
    n = chain.n
    rows = np.atleast_2d(q)[:, :n]
    if rows.shape[1] != n:
        raise ValueError(f"q must hold {n} angles a row, got {rows.shape[1]}")
    fn = chain_functions(structure_of_chain(chain))["hinges"]
    p = parameter_vector(chain)
    out = np.asarray(fn.map(rows.shape[0])(rows.T, p)).T.reshape(-1, n, 3) if rows.shape[0] else np.zeros((0, n, 3))
    return out[0] if q.ndim == 1 else out


# -- printing CasADi's instructions as C, JavaScript and Python ---------------------------------------------
#: How each language writes CasADi's operations (``{0}``, ``{1}``: the operands), declares its work registers
#: and ends a statement.
_LANGUAGES = {
    "c": dict(fn=lambda f: f, fabs="fabs({0})", pow="pow({0}, {1})", declare="double ", end=";"),
    "javascript": dict(fn=lambda f: f"Math.{f}", fabs="Math.abs({0})", pow="Math.pow({0}, {1})", declare="let ", end=";"),
    "python": dict(fn=lambda f: f"math.{f}", fabs="abs({0})", pow="({0}) ** ({1})", declare="", end=""),
}


def function_lines(fn, inputs: Sequence[str], outputs: Sequence[Sequence[str]], indent: str = "    ",
                   declare: bool = True, language: str = "c", registers: str = "") -> List[str]:
    """Statements in ``language`` (``"c"``, ``"javascript"``, ``"python"``) evaluating the CasADi SX function
    ``fn``: ``inputs[k]`` is the array expression of its input ``k``, ``outputs[k][j]`` the name that receives
    entry ``j`` of output ``k`` (declared when ``declare``: C's ``double``, JavaScript's ``let``).  Entries are
    the dense ones, column-major as CasADi's (``j = row + column * rows``), whatever the sparsity: an output's
    structural zeros (CasADi keeps no entry where an expression cannot depend on anything, as a Hessian's row
    of an angle that moves no weight) are written ``0.0`` after the operations, so every name is assigned in
    every language (an output given no names, ``[]``, is not written).  Work registers are locals ``w0, w1,
    ...`` (or, ``registers`` naming an array, its entries, declared by the caller: one statement a line after
    the declarations, so that a long function can be cut into several); every language evaluates the same
    operations in the same order."""
    ca = _ca()
    for k, names in enumerate(outputs):
        if names and len(names) != fn.numel_out(k):
            raise ValueError(f"{fn.name()}'s output {k} has {fn.numel_out(k)} entries, given {len(names)} names")
    dense_in = [_dense_entries(fn.sparsity_in(k)) for k in range(fn.n_in())]
    dense_out = [_dense_entries(fn.sparsity_out(k)) for k in range(fn.n_out())]
    L = _LANGUAGES[language]
    call = L["fn"]
    ops = {ca.OP_ADD: "{0} + {1}", ca.OP_SUB: "{0} - {1}", ca.OP_MUL: "{0} * {1}", ca.OP_DIV: "{0} / {1}",
           ca.OP_NEG: "-{0}", ca.OP_SQ: "{0} * {0}", ca.OP_TWICE: "2.0 * {0}", ca.OP_SIN: call("sin") + "({0})",
           ca.OP_COS: call("cos") + "({0})", ca.OP_ATAN: call("atan") + "({0})", ca.OP_SQRT: call("sqrt") + "({0})",
           ca.OP_INV: "1.0 / {0}", ca.OP_ASSIGN: "{0}", ca.OP_FABS: L["fabs"], ca.OP_EXP: call("exp") + "({0})",
           ca.OP_LOG: call("log") + "({0})", ca.OP_TAN: call("tan") + "({0})", ca.OP_POW: L["pow"],
           ca.OP_CONSTPOW: L["pow"]}
    end = L["end"]
    lines: List[str] = []
    if declare and L["declare"]:
        lines += [f"{indent}{L['declare']}{', '.join(name for out in outputs for name in out)}{end}"]
    nw = fn.sz_w()
    if nw and L["declare"] and not registers:
        lines += [f"{indent}{L['declare']}" + ", ".join(f"w{k}" for k in range(nw)) + end]
    w = (registers + "[{}]") if registers else "w{}"
    for k in range(fn.n_instructions()):
        op = fn.instruction_id(k)
        ins, outs = fn.instruction_input(k), fn.instruction_output(k)
        if op == ca.OP_INPUT:  # (input, its nonzero): the nonzero's dense entry
            lines.append(f"{indent}{w.format(outs[0])} = {inputs[ins[0]]}[{dense_in[ins[0]][ins[1]]}]{end}")
        elif op == ca.OP_OUTPUT:
            if outputs[outs[0]]:
                lines.append(f"{indent}{outputs[outs[0]][dense_out[outs[0]][outs[1]]]} = {w.format(ins[0])}{end}")
        elif op == ca.OP_CONST:
            lines.append(f"{indent}{w.format(outs[0])} = {float(fn.instruction_constant(k))!r}{end}")
        elif op in ops:
            args = [w.format(i) for i in ins]
            lines.append(f"{indent}{w.format(outs[0])} = {ops[op].format(*args)}{end}")
        else:
            raise NotImplementedError(f"CasADi operation {op} has no {language} form here")
    for k, names in enumerate(outputs):
        stored = set(dense_out[k])
        lines += [f"{indent}{name} = 0.0{end}" for j, name in enumerate(names) if j not in stored]
    return lines


def _dense_entries(sparsity) -> List[int]:
    """The dense entry (column-major: ``row + column * rows``) of each nonzero of a CasADi sparsity, in order."""
    rows, cols = sparsity.get_triplet()
    return [r + c * sparsity.size1() for r, c in zip(rows, cols)]


def c_function_lines(fn, inputs: Sequence[str], outputs: Sequence[Sequence[str]], indent: str = "    ",
                     declare: bool = True) -> List[str]:
    """C statements evaluating the CasADi SX function ``fn`` (:func:`function_lines` in C): ``inputs[k]`` is
    the C array expression of its input ``k``, ``outputs[k][j]`` the name that receives entry ``j`` of output
    ``k`` (declared ``double`` when ``declare``).  Work registers are ``double`` locals ``w0, w1, ...``."""
    return function_lines(fn, inputs, outputs, indent, declare, "c")


def _header(structure: ChainStructure, form: str) -> List[str]:
    """The generated source's first lines: what it is, the layout the integrators and the kernels read."""
    from .. import __version__
    from .kernel_source import status_defines

    n = structure.n
    names = parameter_names(n)
    torque = [names.index(f"tau{i}") for i in range(1, n + 1)]
    return [
        f"/* Generated by skewpend {__version__} from a chain's recursive algorithms{form} -- do not edit.",
        f" * {n} links; hinge axes' patterns {'; '.join(structure.patterns) if 'compact' not in form else '(every axis from p)'}.",
        f" * State y = (q1..q{n}, dq1..dq{n}, W); parameters p = ({', '.join(names)}).",
        " */",
        "#include <math.h>",
        "#include <stdint.h>",
        *status_defines(),
        f"#define SP_NQ {n}",
        f"#define SP_NPARAM {len(names)}",
        f"#define SP_NMAX {max(8, 2 * n + 2)}",
        f"#define SP_TAU_INDEX {{{', '.join(map(str, torque))}}}  /* p's torques, a coordinate each */",
        "#define SP_NO_JAC 1",
    ]


def chain_c_source(structure: ChainStructure) -> str:
    """C source of a chain's model functions with the integrators' contract (``integrators.c``):
    ``rhs``, ``ham_rhs``, ``energy``, ``momenta``, ``velocities``, ``tips`` (the rods' ends, 3 n),
    ``axes`` (3 n), and the layout ``SP_NQ``, ``SP_NPARAM``, ``SP_NMAX``; the exported entry points are
    the kernels' (``kernel_source.exports``)."""
    from .codegen import spd_c_lines
    from .kernel_source import exports

    fns = chain_functions(structure)
    n = structure.n
    I = "    "
    Mn = [f"M{i}_{j}" for i in range(n) for j in range(i + 1)]
    f = [f"f{i}" for i in range(n)]
    Q = [f"Q{i}" for i in range(n)]
    acc = [f"acc{i}" for i in range(n)]
    out = _header(structure, "") + [
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
    for name, c_name, doc in (("ends", "tips", "the rods' ends (x, y, z per link) [m] into out[3 n]"),
                              ("axes", "axes", "the hinge axes in the world frame into out[3 n]")):
        out += [f"/* {doc} */", f"static void {c_name}(const double *y, const double *p, double *out)", "{"]
        out += c_function_lines(fns[name], ["y", "p"], [[f"out[{k}]" for k in range(3 * n)]], I, declare=False)
        out += ["}", ""]
    out.append(exports())
    return "\n".join(out) + "\n"


#: The languages of :func:`chain_code` (the C is the kernels', :func:`chain_source`).
CODE_LANGUAGES = ("python", "javascript")


def chain_code(chain: Chain, language: str) -> str:
    """A standalone module of ``chain``'s model in ``language`` (``"python"``: plain ``math``, ``rhs(t, y, p=P)``
    with SciPy's ``solve_ivp`` signature; ``"javascript"``: an ES module, ``rhs(y, p = P)``), printed from the
    same CasADi graphs of the recursive algorithms as the kernels' C: ``P`` (the chain's parameter vector, in
    ``PARAMETER_ORDER``), ``rhs`` (``dy/dt = (q1' … qn', q1'' … qn'')``, ``M q'' = f`` solved by LDL^T),
    ``energy`` (``T + Pi`` [J]), ``ends`` (the rods' ends, 3 n [m], j pointing down) and ``axes`` (the hinge
    axes in the world frame, 3 n) and ``hinges`` (the hinges' positions, 3 n [m]: where the drawings join the
    links) of the angles ``q``."""
    from .. import __version__
    from .codegen import ldlt_steps

    if language not in CODE_LANGUAGES:
        raise ValueError(f"language must be one of {', '.join(CODE_LANGUAGES)}, got {language!r}")
    structure = structure_of_chain(chain)
    fns = chain_functions(structure)
    n = structure.n
    names = parameter_names(n)
    values = [float(v) for v in parameter_vector(chain)]
    py = language == "python"
    I = "    " if py else "  "
    decl, end = ("", "") if py else ("const ", ";")
    Mn = [f"M{i}_{j}" for i in range(n) for j in range(i + 1)]
    f = [f"f{i}" for i in range(n)]
    acc = [f"a{i}" for i in range(n)]
    doc = [f"Generated by skewpend {__version__} from a chain's recursive algorithms (CasADi graphs) -- do not edit.",
           f"{n} links; hinge axes (each in its parent's frame, the chain hanging): "
           + "; ".join("(" + ", ".join(f"{x:.17g}" for x in link.axis) + ")" for link in chain.links) + ".",
           f"State y = (q1 .. q{n}, dq1 .. dq{n}): the joint angles [rad] (zero with every rod hanging) and their rates.",
           "Parameters p (PARAMETER_ORDER) in SI units, the default P the chain's values.",
           "Equations: M(q) q'' = f(q, q'), solved numerically (LDL^T of the symmetric positive-definite M)."]

    def body(name, args, fn, inputs, outputs, ret, comment):
        lines = function_lines(fn, inputs, outputs, I, True, language)
        if py:
            return [f"def {name}({args}):", f'{I}"""{comment}"""', *lines, f"{I}return {ret}", "", ""]
        return [f"/** {comment} */", f"export function {name}({args}) {{", *lines, f"{I}return {ret};", "}", ""]

    rhs_lines = function_lines(fns["model"], ["y", "p"], [Mn, f, [f"Q{i}" for i in range(n)]], I, True, language)
    rhs_lines += [f"{I}{decl}{t} = {e}{end}" for t, e in ldlt_steps(Mn, f, acc)]
    ret_rhs = "[" + ", ".join([f"y[{n + i}]" for i in range(n)] + acc) + "]"
    vec = lambda k: "[" + ", ".join(f"r{i}" for i in range(k)) + "]"  # noqa: E731
    rest = (body("energy", "y, p=P" if py else "y, p = P", fns["energy"], ["y", "p"], [["E"]], "E",
                 "mechanical energy T + Pi [J]; Pi = 0 with every rod hanging")
            + body("ends", "q, p=P" if py else "q, p = P", fns["ends"], ["q", "p"], [[f"r{i}" for i in range(3 * n)]],
                   vec(3 * n), "the rods' ends [x1, y1, z1, ..., zn] [m] at the angles q (j points down)")
            + body("axes", "q, p=P" if py else "q, p = P", fns["axes"], ["q", "p"], [[f"r{i}" for i in range(3 * n)]],
                   vec(3 * n), "the hinge axes in the world frame [a1x, a1y, a1z, ..., anz] at the angles q")
            + body("hinges", "q, p=P" if py else "q, p = P", fns["hinges"], ["q", "p"],
                   [[f"r{i}" for i in range(3 * n)]], vec(3 * n),
                   "the hinges' positions [x1, y1, z1, ..., zn] [m] at the angles q (j points down): each link is "
                   "drawn from its hinge to the next one, the last to its rod's end"))
    if py:
        head = ['"""' + "\n".join(doc) + '\n"""', "import math", "", "",
                "#: The parameter vector's entries, in order.",
                f"PARAMETER_ORDER = ({', '.join(repr(x) for x in names)})",
                "#: The chain's values (the default parameter vector).",
                f"P = ({', '.join(repr(v) for v in values)})", "#: Links.", f"N = {n}", "", "",
                "def rhs(t, y, p=P):", f'{I}"""dy/dt = (dq1 .. dq{n}, ddq1 .. ddq{n}); signature of scipy.integrate.solve_ivp."""',
                *rhs_lines, f"{I}return {ret_rhs}", "", ""]
    else:
        head = ["/**", *(" * " + line for line in doc), " */", "",
                f"export const PARAMETER_ORDER = [{', '.join(repr(x) for x in names)}];",
                "/** the chain's values (the default parameter vector) */",
                f"export const P = [{', '.join(repr(v) for v in values)}];", f"export const N = {n};", "",
                f"/** dy/dt = [dq1 .. dq{n}, ddq1 .. ddq{n}] */", "export function rhs(y, p = P) {", *rhs_lines,
                f"{I}return {ret_rhs};", "}", ""]
        rest += ["/** the rods' ends of a state y (ends reads its first n entries): the name the front end's scenes "
                 "call */", "export const tips = ends;", ""]
    return "\n".join(head + rest).rstrip() + "\n"


@lru_cache(maxsize=8)
def _sensitivity_functions(structure: ChainStructure):
    """``(y, a, p) -> d r/d y`` and ``(y, a, p) -> d r/d p`` of the residual ``r = f(y, p) - M(q, p) a``
    at fixed ``a`` (n x 2 n and n x len(p), column-major as CasADi keeps them)."""
    ca = _ca()
    G = _Graph(structure)
    n = G.n
    y = ca.vertcat(G.q, G.dq)
    a = ca.SX.sym("a", n)
    M, Q, b = G.equations()
    r = ca.vertcat(*[Q[i] - b[i] - sum((M[i][j] * a[j] for j in range(n)), ca.SX(0)) for i in range(n)])
    return (ca.Function("sens_y", [y, a, G.p], [ca.densify(ca.jacobian(r, y))]),
            ca.Function("sens_p", [y, a, G.p], [ca.densify(ca.jacobian(r, G.p))]))


def _solved_columns(I: str, n: int, what: str, cols, R: str, row) -> List[str]:
    """C loop: column c of ``what`` (row length ``row``) is ``M^-1`` column c of ``R`` (column-major, n rows),
    with the factors of ``M`` (``sp_m_``) computed before."""
    from .codegen import spd_c_lines

    rs, xs = [f"r{i}" for i in range(n)], [f"x{i}" for i in range(n)]
    out = [f"{I}for (int c = 0; c < {cols}; c++) {{"]
    out += [f"{I}    const double {rs[i]} = {R}[c * {n} + {i}];" for i in range(n)]
    out += spd_c_lines(I + "    ", rs, xs, prefix="sp_c")
    return out + [f"{I}    {what}[{i} * {row} + c] = {xs[i]};" for i in range(n)] + [f"{I}}}"]


def _solved_model(structure: ChainStructure, I: str) -> List[str]:
    """C statements: the model (``M``, ``f``, ``Q``), the LDL^T solve for the accelerations ``a0 ..``, and
    ``sp_a[n]`` holding them."""
    from .codegen import spd_c_lines

    n = structure.n
    Mn = [f"M{i}_{j}" for i in range(n) for j in range(i + 1)]
    out = c_function_lines(chain_functions(structure)["model"], ["y", "p"], [Mn, [f"f{i}" for i in range(n)],
                                                                             [f"Q{i}" for i in range(n)]], I)
    out += spd_c_lines(I, [f"f{i}" for i in range(n)], [f"a{i}" for i in range(n)], M=Mn, factors="sp_m_")
    return out + [f"{I}double sp_a[{n}];"] + [f"{I}sp_a[{i}] = a{i};" for i in range(n)]


def chain_sensitivity_c_source(structure: ChainStructure) -> str:
    """``rhs_sens(y, p, acc, A, B)`` of a chain (multiple shooting's core, ``shooting.c``) and
    ``rhs_jac(y, p, f, J)`` (the variational equations of ``chaos.c``): the accelerations ``q''`` and
    their derivatives ``A = d q''/d y`` (n x 2 n) and ``B = d q''/d p`` (n x ``SP_NPARAM``, row-major),
    from the residual of the equations at the solved accelerations:

        d q''/d x = M^-1 d(f - M a)/d x  at  a = q'',

    the derivative of ``f - M a`` by CasADi's automatic differentiation of the recursive algorithms
    (the same graphs as ``rhs``), each column one solve with the factors of ``M``.  ``rhs_jac`` is the
    whole right-hand side ``(q', q'', W')`` and its Jacobian, (2 n + 1) x (2 n + 1) row-major, the work
    ``W' = Q . q'`` included (its derivative in the speeds ``Q_i + q_i' dQ_i/dq_i'``; nothing depends
    on ``W``).  Appended to the straight-line source (:func:`chain_c_source`), which defines ``SP_TAU_INDEX``."""
    sens_y, sens_p = _sensitivity_functions(structure)
    n = structure.n
    names = parameter_names(n)
    npar = len(names)
    I = "    "
    out = [f"/* q'' into acc[{n}], d q''/d y into A[{n} x {2 * n}] and d q''/d p into B[{n} x SP_NPARAM] (row-major) */",
           "static void rhs_sens(const double *y, const double *p, double *acc, double *A, double *B)", "{"]
    out += _solved_model(structure, I) + [f"{I}for (int i = 0; i < {n}; i++) acc[i] = sp_a[i];"]
    out += [f"{I}double Ry[{n * 2 * n}], Rp[{n * npar}];", f"{I}{{"]
    out += c_function_lines(sens_y, ["y", "sp_a", "p"], [[f"Ry[{k}]" for k in range(2 * n * n)]], I + I, declare=False)
    out += [f"{I}}}", f"{I}{{"]
    out += c_function_lines(sens_p, ["y", "sp_a", "p"], [[f"Rp[{k}]" for k in range(n * npar)]], I + I, declare=False)
    out += [f"{I}}}"]
    out += _solved_columns(I, n, "A", 2 * n, "Ry", 2 * n) + _solved_columns(I, n, "B", npar, "Rp", "SP_NPARAM")
    out += ["}", "",
            "void sp_rhs_sens(const double *y, const double *p, double *acc, double *A, double *B) { rhs_sens(y, p, acc, A, B); }",
            ""]
    w = 2 * n + 1
    out += [f"/* (q', q'', W') into f[{w}] and its Jacobian into J[{w} x {w}] (row-major; the work's column is 0) */",
            "static void rhs_jac(const double *y, const double *p, double *f, double *J)", "{"]
    out += _solved_model(structure, I)
    out += [f"{I}double Ry[{n * 2 * n}], A[{n * 2 * n}];", f"{I}{{"]
    out += c_function_lines(sens_y, ["y", "sp_a", "p"], [[f"Ry[{k}]" for k in range(2 * n * n)]], I + I, declare=False)
    out += [f"{I}}}"] + _solved_columns(I, n, "A", 2 * n, "Ry", 2 * n)
    out += [f"{I}for (int k = 0; k < {w * w}; k++) J[k] = 0.0;"]
    for i in range(n):
        out += [f"{I}f[{i}] = y[{n + i}];", f"{I}f[{n + i}] = a{i};", f"{I}J[{i * w + n + i}] = 1.0;"]
        out += [f"{I}for (int c = 0; c < {2 * n}; c++) J[{(n + i) * w} + c] = A[{i * 2 * n} + c];"]
    out += [f"{I}f[{2 * n}] = " + " + ".join(f"Q{i} * y[{n + i}]" for i in range(n)) + ";"]
    # d(Q_i q_i')/d q_i' = Q_i + q_i' dQ_i/dq_i' with dQ_i/dq_i' = -c_i - cf_i cfs / (1 + (cfs q_i')^2)
    width = len(PER_LINK)
    cfs = f"p[{names.index('cfs')}]"
    for i in range(n):
        c = f"p[{i * width + PER_LINK.index('c')}]"
        dQ = f"-{c}"
        if structure.friction:
            cf = f"p[{i * width + PER_LINK.index('cf')}]"
            dQ += f" - {cf} * {cfs} / (1.0 + ({cfs} * y[{n + i}]) * ({cfs} * y[{n + i}]))"
        out += [f"{I}J[{2 * n * w + n + i}] = Q{i} + y[{n + i}] * ({dQ});"]
    out += ["}", ""]
    return "\n".join(out) + "\n"


# -- identification: the standard parameters and the regressor ---------------------------------------------
def standard_names(structure: ChainStructure) -> Tuple[str, ...]:
    """The chain's standard parameters ``pi``, link by link, in which the equations are linear:
    ``m_i``, the first moment ``h_i = m_i c_i`` (``h{i}x`` ...) and the inertia ``J_i`` about the hinge
    (``J{i}xx`` ...; both in the link's frame), the damping ``c_i``, and where the structure has them
    the Coulomb friction ``cf_i`` (at the chain's ``cfs``) and the rotor's inertia ``Ir_i`` (at its gear)
    -- the double pendulum's names (:data:`skewpend.symbolic.regressor.PI_NAMES`) for any length."""
    from .conventions import TENSOR_ENTRIES

    out: List[str] = []
    for i in range(1, structure.n + 1):
        out += [f"m{i}"] + [f"h{i}{x}" for x in "xyz"] + [f"J{i}{e}" for e in TENSOR_ENTRIES] + [f"c{i}"]
        out += [f"cf{i}"] * structure.friction + [f"Ir{i}"] * structure.rotor
    return tuple(out)


def standard_vector(chain: Chain):
    """``pi`` of ``chain`` (:func:`standard_names`' order): ``h = m c``, ``J = I_c + m (|c|^2 E - c c^T)``."""
    import numpy as np

    from .conventions import TENSOR_INDICES

    structure = structure_of_chain(chain)
    out: List[float] = []
    for link in chain.links:
        c = np.asarray(link.com, dtype=float)
        J = np.asarray(link.inertia, dtype=float) + link.mass * (float(c @ c) * np.eye(3) - np.outer(c, c))
        out += [link.mass, *(link.mass * c), *(J[i, j] for i, j in TENSOR_INDICES), link.damping]
        out += [link.coulomb] * structure.friction + [link.rotor] * structure.rotor
    return np.array(out, dtype=float)


@lru_cache(maxsize=8)
def regressor_function(structure: ChainStructure):
    """``(y, a, p, pi) -> Y`` (n x len(pi)): the equations ``M(q) a - f(q, q') + tau = Y(q, q', a) pi``
    are linear in the standard parameters (:func:`standard_names`); ``Y`` is their derivative, by
    CasADi's automatic differentiation of the recursive algorithms with ``p``'s bodies written in
    ``pi`` (``c = h/m``, ``I_c = J - (|h|^2 E - h h^T)/m``).  ``p`` supplies what is not in ``pi`` (the
    hinge offsets, ``g``, ``cfs``, gears); ``Y`` does not depend on ``pi``'s value (any positive masses)."""
    from .conventions import TENSOR_ENTRIES, TENSOR_INDICES

    ca = _ca()
    G = _Graph(structure)
    n = G.n
    y = ca.vertcat(G.q, G.dq)
    a = ca.SX.sym("a", n)
    names = standard_names(structure)
    pi = ca.SX.sym("pi", len(names))
    at = {name: pi[k] for k, name in enumerate(names)}
    pnames = parameter_names(n)
    new = [G.p[k] for k in range(len(pnames))]
    for i in range(1, n + 1):
        m = at[f"m{i}"]
        h = [at[f"h{i}{x}"] for x in "xyz"]
        J = {e: at[f"J{i}{e}"] for e in TENSOR_ENTRIES}
        hh = h[0] * h[0] + h[1] * h[1] + h[2] * h[2]
        new[pnames.index(f"m{i}")] = m
        for k, x in enumerate("xyz"):
            new[pnames.index(f"r{x}{i}")] = h[k] / m
        for e, (r, c) in zip(TENSOR_ENTRIES, TENSOR_INDICES):
            new[pnames.index(f"I{e}{i}")] = J[e] - ((hh if r == c else 0) - h[r] * h[c]) / m
        for stem in ("c", "cf", "Ir"):
            if f"{stem}{i}" in at:
                new[pnames.index(f"{stem}{i}")] = at[f"{stem}{i}"]
    M, Q, b = G.equations()
    r = ca.vertcat(*[sum((M[i][j] * a[j] for j in range(n)), ca.SX(0)) + b[i] - Q[i] for i in range(n)])
    r = ca.substitute(r, G.p, ca.vertcat(*new))
    return ca.Function("regressor", [y, a, G.p, pi], [ca.densify(ca.jacobian(r, pi))])


# -- compact code: one step of each recursion, looped over the links ----------------------------------------
#: The forward step's carried state: the link frame's rotation R (row-major), its hinge o, angular velocity
#: w, the hinge's velocity vo, angular acceleration al and the hinge's acceleration ao at q'' = 0, and the
#: hinge's height with the chain hanging (for Pi = 0 there).
_STATE = (("R", 9), ("o", 3), ("w", 3), ("vo", 3), ("al", 3), ("ao", 3), ("y0", 1))
#: What the forward step leaves for the backward step and the callers, per link.
_BODY = (("a", 3), ("oa", 3), ("F", 3), ("NO", 3), ("m", 1), ("mc", 3), ("JO", 6), ("pl", 3), ("pa", 3),
         ("T", 1), ("Pi", 1), ("Q", 1), ("dSa", 3), ("dSl", 3), ("o", 3), ("end", 3))
#: The backward step's carried composite of the links i ... n: mass, first moment, inertia about the
#: origin (6), force and moment about the origin, linear and angular momentum.
_COMPOSITE = (("m", 1), ("h", 3), ("J", 6), ("f", 3), ("n", 3), ("pl", 3), ("pa", 3))
#: The backward step's outputs per link: the bias, hinge i's unit twist's momentum in the composite
#: (ang, lin: the mass matrix's column), and dT/dq - dPi/dq at fixed speeds.
_OUT = (("bias", 1), ("ang", 3), ("lin", 3), ("dL", 1))
#: The same for the equations of motion alone (the integrators' right-hand side and the mass matrix): what
#: M and the bias need, without the momenta, energies, ends and Hamilton's terms.
_BODY_R = (("a", 3), ("oa", 3), ("F", 3), ("NO", 3), ("m", 1), ("mc", 3), ("JO", 6), ("Q", 1))
_COMPOSITE_R = (("m", 1), ("h", 3), ("J", 6), ("f", 3), ("n", 3))
_OUT_R = (("bias", 1), ("ang", 3), ("lin", 3))


def _size(layout) -> int:
    return sum(k for _, k in layout)


def _offsets(layout) -> Dict[str, int]:
    """Where each entry of ``layout`` starts."""
    return dict(zip((name for name, _ in layout), accumulate((size for _, size in layout), initial=0)))


def _split(ca, x, layout):
    return {name: x[k:k + size] for (name, size), k in zip(layout, _offsets(layout).values())}


def _sym6(ca, v):
    """The symmetric 3x3 of its entries in TENSOR_ENTRIES' order (xx, xy, xz, yy, yz, zz)."""
    return ca.vertcat(ca.horzcat(v[0], v[1], v[2]), ca.horzcat(v[1], v[3], v[4]), ca.horzcat(v[2], v[4], v[5]))


def _entries6(ca, M):
    return ca.vertcat(M[0, 0], M[0, 1], M[0, 2], M[1, 1], M[1, 2], M[2, 2])


def _twist_momentum(ca, mC, hC, JC, a, oa):
    """``(lin, ang)``: the momentum of a composite (mass ``mC``, first moment ``hC``, inertia entries ``JC``
    about the origin) under the unit twist ``(a, oa)``: a column of the mass matrix."""
    return mC * oa + _cross(ca, a, hC), ca.mtimes(_sym6(ca, [JC[i] for i in range(6)]), a) + _cross(ca, hC, oa)


@lru_cache(maxsize=4)
def compact_functions(friction: bool) -> Dict[str, object]:
    """The forward and backward steps of the recursions for one link with its axis as an input (CasADi
    functions): ``fwd(state, link, axis, q, dq, g, cfs) -> (state, body)`` and
    ``bwd(composite, body, g) -> (composite, out)``; the formulas are :class:`_Graph`'s, link by link.
    ``fwd_r`` and ``bwd_r``: the same steps for the equations of motion alone (the layouts ``_BODY_R``,
    ``_COMPOSITE_R``, ``_OUT_R``: no momenta, energies, ends or Hamilton's terms)."""
    ca = _ca()
    S = ca.SX.sym("S", _size(_STATE))
    Lp = ca.SX.sym("L", len(PER_LINK))
    e = ca.SX.sym("e", 3)
    q, dq, g, cfs = ca.SX.sym("q"), ca.SX.sym("dq"), ca.SX.sym("g"), ca.SX.sym("cfs")
    s = _split(ca, S, _STATE)
    L = {name: Lp[k] for k, name in enumerate(PER_LINK)}
    Rp = ca.reshape(s["R"], 3, 3).T  # row-major
    o = s["o"] + ca.mtimes(Rp, ca.vertcat(L["hx"], L["hy"], L["hz"]))
    a = ca.mtimes(Rp, e)
    R = ca.mtimes(Rp, _rotation(ca, ca.cos(q), ca.sin(q), (e[0], e[1], e[2])))
    r = ca.mtimes(R, ca.vertcat(L["rx"], L["ry"], L["rz"]))
    c = o + r
    Iw = ca.mtimes(ca.mtimes(R, _sym6(ca, [L[f"I{t}"] for t in ("xx", "xy", "xz", "yy", "yz", "zz")])), R.T)
    d = o - s["o"]
    wp = s["w"]
    vo = s["vo"] + _cross(ca, wp, d)
    w = wp + a * dq
    ao = s["ao"] + _cross(ca, s["al"], d) + _cross(ca, wp, _cross(ca, wp, d))
    al = s["al"] + _cross(ca, wp, a * dq)
    vc = vo + _cross(ca, w, r)
    ac = ao + _cross(ca, al, r) + _cross(ca, w, _cross(ca, w, r))
    m = L["m"]
    down = ca.DM([0.0, 1.0, 0.0])
    F = m * (ac - g * down)
    Iww = ca.mtimes(Iw, w)
    N = ca.mtimes(Iw, al) + _cross(ca, w, Iww)
    pl = m * vc
    y0 = s["y0"] + L["hy"]
    Q = L["tau"] - L["c"] * dq
    if friction:
        Q = Q - L["cf"] * ca.atan(cfs * dq)
    oa = _cross(ca, o, a)
    v0p = s["vo"] - _cross(ca, wp, s["o"])  # the parent's twist at the origin: (wp, v0p)
    state = ca.vertcat(R.T.reshape((9, 1)), o, w, vo, al, ao, y0)
    JO = _entries6(ca, Iw + m * (ca.dot(c, c) * ca.SX.eye(3) - ca.mtimes(c, c.T)))  # the inertia about the origin
    body = ca.vertcat(a, oa, F, N + _cross(ca, c, F), m, m * c, JO, pl, _cross(ca, c, pl) + Iww,
                      (m * ca.dot(vc, vc) + ca.dot(w, Iww)) / 2, -g * m * (c[1] - (y0 + L["ry"])), Q, _cross(ca, wp, a),
                      _cross(ca, wp, oa) + _cross(ca, v0p, a), o, o + R[:, 1] * L["l"])
    fwd = ca.Function("fwd", [S, Lp, e, q, dq, g, cfs], [state, body])
    body_r = ca.vertcat(a, oa, F, N + _cross(ca, c, F), m, m * c, JO, Q)
    fwd_r = ca.Function("fwd_r", [S, Lp, e, q, dq, g, cfs], [state, body_r])
    C = ca.SX.sym("C", _size(_COMPOSITE))
    B = ca.SX.sym("B", _size(_BODY))
    cc, b = _split(ca, C, _COMPOSITE), _split(ca, B, _BODY)
    mC, hC = cc["m"] + b["m"], cc["h"] + b["mc"]
    JC = cc["J"] + b["JO"]
    f, nO = cc["f"] + b["F"], cc["n"] + b["NO"]
    plC, paC = cc["pl"] + b["pl"], cc["pa"] + b["pa"]
    a, oa = b["a"], b["oa"]
    lin, ang = _twist_momentum(ca, mC, hC, JC, a, oa)
    dT = ca.dot(b["dSa"], paC) + ca.dot(b["dSl"], plC)
    dPi = -g * _cross(ca, a, hC - mC * b["o"])[1]
    composite = ca.vertcat(mC, hC, JC, f, nO, plC, paC)
    out = ca.vertcat(ca.dot(a, nO) + ca.dot(oa, f), ang, lin, dT - dPi)
    bwd = ca.Function("bwd", [C, B, g], [composite, out])
    Cr, Br = ca.SX.sym("Cr", _size(_COMPOSITE_R)), ca.SX.sym("Br", _size(_BODY_R))
    cr, br = _split(ca, Cr, _COMPOSITE_R), _split(ca, Br, _BODY_R)
    mC, hC, JC = cr["m"] + br["m"], cr["h"] + br["mc"], cr["J"] + br["JO"]
    f, nO, a, oa = cr["f"] + br["F"], cr["n"] + br["NO"], br["a"], br["oa"]
    lin, ang = _twist_momentum(ca, mC, hC, JC, a, oa)
    bwd_r = ca.Function("bwd_r", [Cr, Br, g], [ca.vertcat(mC, hC, JC, f, nO),
                                               ca.vertcat(ca.dot(a, nO) + ca.dot(oa, f), ang, lin)])
    return {"fwd": fwd, "bwd": bwd, "fwd_r": fwd_r, "bwd_r": bwd_r}


def _c_static(fn, name: str, args: Sequence[str], outs: Sequence[str], doc: str) -> List[str]:
    """``fn`` as a static C function of arrays: ``static void name(const double *args..., double *outs...)``."""
    sig = ", ".join([f"const double *{a}" for a in args] + [f"double *{o}" for o in outs])
    n_out = [fn.numel_out(k) for k in range(fn.n_out())]
    body = c_function_lines(fn, [f"{a}" for a in args], [[f"{o}[{j}]" for j in range(n_out[k])] for k, o in enumerate(outs)],
                            declare=False)
    return [f"/* {doc} */", f"static inline void {name}({sig})", "{"] + body + ["}", ""]


def compact_c_source(structure: ChainStructure) -> str:
    """C source of a chain's model functions in compact form: the forward and backward steps of the
    recursions printed once (:func:`compact_functions`, the axis an argument) and looped over the links,
    each axis read from ``p``; then the mass matrix's entries ``M_kl = a_k . ang_l + oa_k . lin_l``, the
    kernels' LDL^T solve, and the integrators' contract as :func:`chain_c_source`'s.  Its size does not
    grow with the number of links but for the printed solve (n (n + 1) / 2 factor steps), so a long chain
    compiles in about the time of a short one.  Rotors are not in this form (their energy couples the
    links through the parent's angular velocity: :func:`chain_c_source` holds them)."""
    from .codegen import spd_c_lines
    from .kernel_source import exports

    if structure.rotor:
        raise ValueError("compact chain code has no rotors")
    fns = compact_functions(structure.friction)
    n = structure.n
    names = parameter_names(n)
    w = len(PER_LINK)
    I = "    "
    NS = _size(_STATE)
    at = {(tag, nm): k for layout, tag in ((_BODY, "B"), (_OUT, "O"), (_BODY_R, "Br"), (_OUT_R, "Or"))
          for nm, k in _offsets(layout).items()}
    Mn = [f"sp_Mk[{k}]" for k in range(n * (n + 1) // 2)]
    f = [f"sp_f[{i}]" for i in range(n)]
    acc = [f"acc{i}" for i in range(n)]
    gi, ci = len(names) - len(GLOBAL) + GLOBAL.index("g"), len(names) - len(GLOBAL) + GLOBAL.index("cfs")
    ax = PER_LINK.index("ex")  # ex, ey, ez: the link's hinge axis, three entries of p
    out = _header(structure, " (compact form)") + [
        f"#define SP_NS {NS}",
        f"#define SP_NB {_size(_BODY)}",
        f"#define SP_NC {_size(_COMPOSITE)}",
        f"#define SP_NO {_size(_OUT)}",
        f"#define SP_NB_R {_size(_BODY_R)}",
        f"#define SP_NC_R {_size(_COMPOSITE_R)}",
        f"#define SP_NO_R {_size(_OUT_R)}",
        "",
    ]
    out += _c_static(fns["fwd"], "fwd", ["S", "L", "e", "q", "dq", "gravity", "rate"], ["S1", "B"],
                     "one link forward: the parent's state S -> the link's S1 and its body quantities B")
    out += _c_static(fns["bwd"], "bwd", ["C", "B", "gravity"], ["C1", "O"],
                     "one link backward: the composite of the links after it C -> with it C1, and its outputs O")
    out += _c_static(fns["fwd_r"], "fwd_r", ["S", "L", "e", "q", "dq", "gravity", "rate"], ["S1", "B"],
                     "fwd for the equations of motion alone (the body quantities M and the bias need)")
    out += _c_static(fns["bwd_r"], "bwd_r", ["C", "B", "gravity"], ["C1", "O"],
                     "bwd for the equations of motion alone (the composite and outputs M and the bias need)")
    for r, what in (("", "every body quantity and output"), ("_r", "what the equations of motion need")):
        B, C, O = f"SP_NB{r.upper()}", f"SP_NC{r.upper()}", f"SP_NO{r.upper()}"
        out += [
            f"/* the recursions over the links at y = (q, q'), {what}: body quantities B[n][{B}], outputs O[n][{O}] */",
            f"static void sweep{r}(const double *y, const double *p, double B[][{B}], double O[][{O}])",
            "{",
            f"{I}double S[SP_NS] = {{1, 0, 0, 0, 1, 0, 0, 0, 1}}, S1[SP_NS], C[{C}] = {{0}}, C1[{C}];",
            f"{I}const double g = p[{gi}], cfs = p[{ci}];",
            f"{I}for (int i = 0; i < SP_NQ; i++) {{",
            f"{I}{I}fwd{r}(S, p + {w} * i, p + {w} * i + {ax}, y + i, y + SP_NQ + i, &g, &cfs, S1, B[i]);",
            f"{I}{I}for (int k = 0; k < SP_NS; k++) S[k] = S1[k];",
            f"{I}}}",
            f"{I}for (int i = SP_NQ - 1; i >= 0; i--) {{",
            f"{I}{I}bwd{r}(C, B[i], &g, C1, O[i]);",
            f"{I}{I}for (int k = 0; k < {C}; k++) C[k] = C1[k];",
            f"{I}}}",
            "}",
            "",
        ]
    out += [
        "/* the mass matrix's packed lower triangle from the sweep: M_kl = a_k . ang_l + oa_k . lin_l (k <= l) */",
        "static void mass_from(double B[][SP_NB_R], double O[][SP_NO_R], double *Mk)",
        "{",
        f"{I}for (int l = 0; l < SP_NQ; l++)",
        f"{I}{I}for (int k = 0; k <= l; k++) {{",
        f"{I}{I}{I}const double *a = B[k] + {at[('Br', 'a')]}, *oa = B[k] + {at[('Br', 'oa')]};",
        f"{I}{I}{I}const double *ang = O[l] + {at[('Or', 'ang')]}, *lin = O[l] + {at[('Or', 'lin')]};",
        f"{I}{I}{I}Mk[l * (l + 1) / 2 + k] = a[0] * ang[0] + a[1] * ang[1] + a[2] * ang[2] + oa[0] * lin[0] + oa[1] * lin[1] + oa[2] * lin[2];",
        f"{I}{I}}}",
        "}",
        "",
        "static void rhs(const double *y, const double *p, double *out)",
        "{",
        f"{I}double B[SP_NQ][SP_NB_R], O[SP_NQ][SP_NO_R], sp_Mk[{len(Mn)}], sp_f[SP_NQ];",
        f"{I}sweep_r(y, p, B, O);",
        f"{I}mass_from(B, O, sp_Mk);",
        f"{I}double W = 0.0;",
        f"{I}for (int i = 0; i < SP_NQ; i++) {{",
        f"{I}{I}const double Q = B[i][{at[('Br', 'Q')]}];",
        f"{I}{I}sp_f[i] = Q - O[i][{at[('Or', 'bias')]}];",
        f"{I}{I}W += Q * y[SP_NQ + i];",
        f"{I}}}",
    ]
    out += spd_c_lines(I, f, acc, M=Mn)
    out += [f"{I}out[{i}] = y[{n + i}];" for i in range(n)] + [f"{I}out[{n + i}] = {acc[i]};" for i in range(n)]
    out += [f"{I}out[{2 * n}] = W;", "}", ""]
    out += ["static double energy(const double *y, const double *p)", "{",
            f"{I}double B[SP_NQ][SP_NB], O[SP_NQ][SP_NO], E = 0.0;", f"{I}sweep(y, p, B, O);",
            f"{I}for (int i = 0; i < SP_NQ; i++) E += B[i][{at[('B', 'T')]}] + B[i][{at[('B', 'Pi')]}];",
            f"{I}return E;", "}", ""]
    out += ["/* M(q) into the packed lower triangle out[n (n + 1) / 2] */",
            "static void mass(const double *q, const double *p, double *out)", "{",
            f"{I}double y[2 * SP_NQ] = {{0}}, B[SP_NQ][SP_NB_R], O[SP_NQ][SP_NO_R];",
            f"{I}for (int i = 0; i < SP_NQ; i++) y[i] = q[i];",
            f"{I}sweep_r(y, p, B, O);", f"{I}mass_from(B, O, out);", "}", ""]
    load = [f"{I}double sp_Mk[{len(Mn)}];", f"{I}mass(%s, p, sp_Mk);"]
    out += ["static void momenta(const double *y, const double *p, double *out)", "{"]
    out += [line.replace("%s", "y") for line in load]
    out += [f"{I}for (int i = 0; i < SP_NQ; i++) {{", f"{I}{I}double s = 0.0;",
            f"{I}{I}for (int j = 0; j < SP_NQ; j++) s += sp_Mk[i > j ? i * (i + 1) / 2 + j : j * (j + 1) / 2 + i] * y[SP_NQ + j];",
            f"{I}{I}out[i] = s;", f"{I}}}", "}", ""]
    v = [f"v{i}" for i in range(n)]
    out += ["static void velocities(const double *z, const double *p, double *out)", "{"]
    out += [line.replace("%s", "z") for line in load]
    out += spd_c_lines(I, [f"z[{n + i}]" for i in range(n)], v, M=Mn)
    out += [f"{I}out[{i}] = {v[i]};" for i in range(n)] + ["}", ""]
    out += ["static void ham_rhs(const double *z, const double *p, double *out)", "{"]
    out += [line.replace("%s", "z") for line in load]
    out += spd_c_lines(I, [f"z[{n + i}]" for i in range(n)], v, M=Mn)
    out += [f"{I}double yv[2 * SP_NQ], B[SP_NQ][SP_NB], O[SP_NQ][SP_NO], W = 0.0;"]
    out += [f"{I}yv[{i}] = z[{i}]; yv[{n + i}] = {v[i]};" for i in range(n)]
    out += [f"{I}sweep(yv, p, B, O);", f"{I}for (int i = 0; i < SP_NQ; i++) {{",
            f"{I}{I}const double Q = B[i][{at[('B', 'Q')]}];",
            f"{I}{I}out[i] = yv[SP_NQ + i];", f"{I}{I}out[SP_NQ + i] = O[i][{at[('O', 'dL')]}] + Q;",
            f"{I}{I}W += Q * yv[SP_NQ + i];", f"{I}}}", f"{I}out[2 * SP_NQ] = W;", "}", ""]
    for name, key in (("tips", "end"), ("axes", "a")):
        out += [f"static void {name}(const double *y, const double *p, double *out)", "{",
                f"{I}double B[SP_NQ][SP_NB], O[SP_NQ][SP_NO];", f"{I}sweep(y, p, B, O);",
                f"{I}for (int i = 0; i < SP_NQ; i++)",
                f"{I}{I}for (int k = 0; k < 3; k++) out[3 * i + k] = B[i][{at[('B', key)]} + k];", "}", ""]
    out.append(exports())
    return "\n".join(out) + "\n"


@lru_cache(maxsize=16)
def _linear_function(structure: ChainStructure):
    """CasADi function ``p -> (M0, dbias/dq, dbias/dq', f)`` at the hanging rest ``q = q' = 0``."""
    ca = _ca()
    G = _Graph(structure)
    n = G.n
    M, Q, b = G.equations()
    f = ca.vertcat(*Q) - ca.vertcat(*b)
    Mm = ca.vertcat(*[ca.horzcat(*row) for row in M])
    outs = [Mm, ca.jacobian(f, G.q), ca.jacobian(f, G.dq), f]
    outs = [ca.substitute(x, ca.vertcat(G.q, G.dq), ca.DM.zeros(2 * n)) for x in outs]
    return ca.Function("linear", [G.p], outs)


def linear_matrices(chain: Chain, coulomb: str = "exclude"):
    """``(M0, C0, K0)`` of the chain's linearisation about its hanging rest (``q = q' = 0``): exact
    derivatives of the recursive algorithms (CasADi's), evaluated at ``parameter_vector(chain)``.
    Coulomb friction enters ``C0`` only with ``coulomb="smoothed"`` (its slope ``cfs cf``), as for the
    double pendulum.  Raises :class:`~skewpend.errors.EquilibriumError` when the rest is no equilibrium."""
    import numpy as np

    from ..errors import EquilibriumError

    structure = structure_of_chain(chain)
    fn = _linear_function(structure)
    p = parameter_vector(chain)
    if coulomb != "smoothed" and chain.has_friction:  # the friction's slope at rest left out
        w = len(PER_LINK)
        for i in range(chain.n):
            p[i * w + PER_LINK.index("cf")] = 0.0
    M, dfdq, dfdv, f = (np.array(x, dtype=float) for x in fn(p))
    scale = max(1.0, float(np.abs(dfdq).max()))
    if np.max(np.abs(f)) > 1e-12 * scale:
        why = ("constant joint torques hold it elsewhere" if any(link.torque for link in chain.links) else
               "its centres of mass do not hang straight below their hinges there")
        raise EquilibriumError(f"q = 0 is not an equilibrium of this chain ({why}); its modes need the hanging rest")
    return M, -dfdv, -dfdq


@lru_cache(maxsize=16)
def _potential_function(structure: ChainStructure):
    """CasADi function ``(q, p) -> (Pi, dPi/dq, d2Pi/dq2, M, the rods' downward components)``: what
    equilibria need, exact (automatic differentiation)."""
    ca = _ca()
    G = _Graph(structure)
    Pi = G.potential_energy()
    M = G.mass_matrix()
    grad = ca.gradient(Pi, G.q)
    return ca.Function("potential", [G.q, G.p], [Pi, grad, ca.jacobian(grad, G.q),
                                                 ca.vertcat(*[ca.horzcat(*row) for row in M]),
                                                 ca.vertcat(*[G.R[k][1, 1] for k in range(G.n)])])


def potential_terms(chain: Chain):
    """``f(q) -> (Pi, grad Pi, Hessian of Pi, M(q), the rods' downward components)`` of a chain, numeric
    (NumPy arrays; CasADi evaluates the recursive algorithms' graph, no compiling)."""
    import numpy as np

    fn = _potential_function(structure_of_chain(chain))
    p = parameter_vector(chain)

    def evaluate(q):
        Pi, g, H, M, down = fn(np.asarray(q, dtype=float), p)
        return (float(Pi), np.array(g, dtype=float).ravel(), np.array(H, dtype=float), np.array(M, dtype=float),
                np.array(down, dtype=float).ravel())

    return evaluate
