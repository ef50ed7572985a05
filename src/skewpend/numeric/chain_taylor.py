"""C source of the Taylor integrator of a chain of links: the series recurrences of the chain's model, printed
from the recursive algorithms' expression graph (:func:`skewpend.numeric.recursive.chain_functions`' ``model``:
``M`` packed, ``f``, the joint forces ``Q``), then the driver ``taylor.c`` -- the double pendulum's driver, its
order and step rule, with ``SP_TN = 2 n + 1`` (``q``, ``q'``, ``W``).

Each operation of the graph becomes one on truncated power series, the coefficient ``k`` of every series
computed in graph order before ``k + 1``:

* what does not depend on the state (a function of the parameters only) is a *constant*, evaluated once a
  call into ``pc`` (``taylor_prepare``; the parameter vector itself is ``pc``'s head);
* ``u + v``, ``u - v``, ``-u``, ``2 u``, ``c u``: coefficient by coefficient; ``u v`` and ``u^2``: Cauchy
  products; ``u / v``: ``w[k] = (u[k] - sum_{j=1..k} v[j] w[k-j]) / v[0]``;
* ``sin u`` and ``cos u`` together: ``s[k] = (1/k) sum_{j=1..k} j u[j] c[k-j]``, ``c[k] = -(1/k) sum j u[j]
  s[k-j]``; ``atan u`` (Coulomb friction): ``d = 1 + u^2``, ``k a[k] d[0] = k u[k] - sum_{j=1..k-1} j a[j]
  d[k-j]``;
* ``M q'' = f`` in series: ``q''[k] = M[0]^-1 (f[k] - sum_{j>=1} M[j] q''[k-j])``, ``M[0] = L D L^T`` once a
  step (the one linear solve);
* ``W' = Q . q'`` when a joint term can be non-zero (``taylor_work``).

Nothing here is an equation of motion typed by hand: the chain's equations are the graph's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Dict, List, Tuple

from .. import __version__

__all__ = ["chain_taylor_c_source", "chain_tn"]


def chain_tn(n: int) -> int:
    """The Taylor state's size of a chain of ``n`` links: ``q``, ``q'`` and the work ``W``."""
    return 2 * n + 1


def chain_taylor_c_source(structure, order: int, fused: bool = True) -> str:
    """C of the Taylor kernel of the chain of ``structure`` (:class:`~skewpend.numeric.recursive.ChainStructure`)
    at ``order``: ``taylor_work(p)``, ``taylor_prepare(p, pc)``, ``taylor_jet(x, pc, work, e_out)`` (the
    coefficients 1 .. order of ``x[SP_TN][SP_TPMAX + 2]`` from its coefficients 0; the energy at them into
    ``*e_out`` when asked), then ``taylor.c``.  Raises ValueError for an operation without a recurrence here."""
    from .kernel_source import status_defines
    from ..errors import require
    from .recursive import chain_functions, function_lines, parameter_names
    from .taylor_source import SP_TPMAX, VECTOR_C

    if not 2 <= order <= SP_TPMAX:
        raise ValueError(f"taylor kernel: order {order} outside 2 .. {SP_TPMAX}")
    ca = require("casadi", "a chain of links (its recursive algorithms)")
    fns = chain_functions(structure)
    fn = fns["model"]
    n = structure.n
    names = parameter_names(n)
    npar = len(names)
    tn = chain_tn(n)
    I = "    "

    # -- the graph as series and constants ------------------------------------------------------------------
    # a value: ("k", text) a constant (a C expression of pc[...]), ("s", index) the series s[index] (or x[i]
    # for the state: ("x", i))
    consts: List[str] = []  # pc[npar + m] = consts[m]
    ops: List[Tuple] = []  # series operations in graph order: (kind, out, *operands)
    nseries = [0]

    def const(expr: str) -> Tuple[str, str]:
        consts.append(expr)
        return ("k", f"pc[{npar + len(consts) - 1}]")

    def series() -> int:
        nseries[0] += 1
        return nseries[0] - 1

    def val(v, k: str) -> str:
        """The coefficient ``k`` (a C expression) of value ``v``."""
        if v[0] == "k":
            return f"({k} == 0 ? {v[1]} : 0.0)"
        return f"x[{v[1]}][{k}]" if v[0] == "x" else f"s[{v[1]}][{k}]"

    reg: Dict[int, Tuple] = {}
    outputs: Dict[Tuple[int, int], Tuple] = {}
    binary = {ca.OP_ADD: "add", ca.OP_SUB: "sub", ca.OP_MUL: "mul", ca.OP_DIV: "div"}
    cexpr = {ca.OP_ADD: "{0} + {1}", ca.OP_SUB: "{0} - {1}", ca.OP_MUL: "{0} * {1}", ca.OP_DIV: "{0} / {1}",
             ca.OP_NEG: "-{0}", ca.OP_SQ: "{0} * {0}", ca.OP_TWICE: "2.0 * {0}", ca.OP_SIN: "sin({0})",
             ca.OP_COS: "cos({0})", ca.OP_ATAN: "atan({0})", ca.OP_SQRT: "sqrt({0})", ca.OP_INV: "1.0 / {0}",
             ca.OP_ASSIGN: "{0}", ca.OP_FABS: "fabs({0})", ca.OP_EXP: "exp({0})", ca.OP_LOG: "log({0})",
             ca.OP_POW: "pow({0}, {1})", ca.OP_CONSTPOW: "pow({0}, {1})", ca.OP_TAN: "tan({0})"}
    trig: Dict[int, Tuple[int, int]] = {}  # the series sin/cos pair of an operand's series
    for i in range(fn.n_instructions()):
        op = fn.instruction_id(i)
        ins, outs = fn.instruction_input(i), fn.instruction_output(i)
        if op == ca.OP_INPUT:
            reg[outs[0]] = ("x", ins[1]) if ins[0] == 0 else ("k", f"pc[{ins[1]}]")
            continue
        if op == ca.OP_OUTPUT:
            outputs[outs[0], outs[1]] = reg[ins[0]]
            continue
        if op == ca.OP_CONST:
            reg[outs[0]] = ("k", repr(float(fn.instruction_constant(i))))
            continue
        args = [reg[j] for j in ins[:2]] if op in (ca.OP_ADD, ca.OP_SUB, ca.OP_MUL, ca.OP_DIV, ca.OP_POW,
                                                   ca.OP_CONSTPOW) else [reg[ins[0]]]
        if all(a[0] == "k" for a in args):  # a constant: once a call
            reg[outs[0]] = const(cexpr[op].format(*(a[1] for a in args)))
            continue
        if op == ca.OP_ASSIGN:
            reg[outs[0]] = args[0]
        elif op in binary:
            w = series()
            ops.append((binary[op], w, *args))
            reg[outs[0]] = ("s", w)
        elif op in (ca.OP_NEG, ca.OP_TWICE):
            w = series()
            ops.append(("neg" if op == ca.OP_NEG else "twice", w, args[0]))
            reg[outs[0]] = ("s", w)
        elif op == ca.OP_SQ:
            w = series()
            ops.append(("mul", w, args[0], args[0]))
            reg[outs[0]] = ("s", w)
        elif op == ca.OP_INV:
            w = series()
            ops.append(("div", w, ("k", "1.0"), args[0]))
            reg[outs[0]] = ("s", w)
        elif op in (ca.OP_SIN, ca.OP_COS):
            key = args[0]
            if key not in trig:
                pair = (series(), series())
                ops.append(("sincos", pair, args[0]))
                trig[key] = pair
            reg[outs[0]] = ("s", trig[key][0 if op == ca.OP_SIN else 1])
        elif op == ca.OP_ATAN:
            d, w = series(), series()
            ops.append(("atan", (w, d), args[0]))
            reg[outs[0]] = ("s", w)
        else:
            raise ValueError(f"the chain's equations use CasADi operation {op}, which has no series recurrence here")
    nM = n * (n + 1) // 2
    M = [outputs.get((0, j), ("k", "0.0")) for j in range(nM)]
    f = [outputs.get((1, j), ("k", "0.0")) for j in range(n)]
    Q = [outputs.get((2, j), ("k", "0.0")) for j in range(n)]

    def mij(i: int, j: int):
        a, b = max(i, j), min(i, j)
        return M[a * (a + 1) // 2 + b]

    # -- the C text ---------------------------------------------------------------------------------------------
    per = structure.key() if hasattr(structure, "key") else repr(structure)
    out = [f"/* Generated by skewpend {__version__} from a chain's recursive algorithms (CasADi graph) -- do not edit.",
           f" * The Taylor integrator of order {order} of a chain of {n} links: the model's series recurrences, then",
           f" * taylor.c.  Structure {per}; {nseries[0]} series, {len(consts)} constants. */",
           "#include <math.h>", "#include <stdint.h>", "#include <string.h>", "", *status_defines(), "",
           f"#define SP_TN {tn}", f"#define SP_TPMAX {SP_TPMAX}", f"#define SP_TORDER {order}",
           f"#define SP_TAYLOR_NPC {npar + max(len(consts), 1)}", f"#define SP_FUSED {int(bool(fused))}",
           f"#define SP_NS {max(nseries[0], 1)}", "", *VECTOR_C, ""]
    from ..schema import FIELDS, NONCONSERVATIVE_ROLES

    stems = {f.stem for f in FIELDS if f.role in NONCONSERVATIVE_ROLES and f.per_body}  # each joint's damping, ...
    joint = [k for k, name in enumerate(names) if name.rstrip("0123456789") in stems]
    zero_q = all(v == ("k", "0.0") for v in Q)
    out += ["/* W' = Q . q' needs integrating unless every joint's damping, friction and torque is 0 */",
            "static int taylor_work(const double *p)", "{",
            f"{I}(void)p;" if zero_q or not joint else "",
            f"{I}return {'0' if zero_q else ' || '.join(f'p[{k}] != 0.0' for k in joint) if joint else '1'};", "}", ""]
    out += ["/* the parameters and the state-free subexpressions, once per call, into pc[SP_TAYLOR_NPC] */",
            "static void taylor_prepare(const double *p, double *pc)", "{",
            f"{I}for (int i = 0; i < {npar}; i++) pc[i] = p[i];"]
    out += [f"{I}pc[{npar + m}] = {e};" for m, e in enumerate(consts)] or [f"{I}pc[{npar}] = 0.0;"]
    out += ["}", ""]

    def sum_lines(target: str, terms: str, lo: str, hi: str) -> List[str]:
        return [f"{I}{I}{{", f"{I}{I}{I}double acc = 0.0;", f"{I}{I}{I}for (int j = {lo}; j <= {hi}; j++) acc = SP_FMA({terms}, acc);",
                f"{I}{I}{I}{target} = acc;", f"{I}{I}}}"]

    body: List[str] = []
    for o in ops:
        kind = o[0]
        if kind in ("add", "sub"):
            a, b = o[2], o[3]
            sign = "+" if kind == "add" else "-"
            body.append(f"{I}{I}s[{o[1]}][k] = {val(a, 'k')} {sign} {val(b, 'k')};")
        elif kind == "neg":
            body.append(f"{I}{I}s[{o[1]}][k] = -{val(o[2], 'k')};")
        elif kind == "twice":
            body.append(f"{I}{I}s[{o[1]}][k] = 2.0 * {val(o[2], 'k')};")
        elif kind == "mul":
            a, b = o[2], o[3]
            if a[0] == "k" or b[0] == "k":
                c, u = (a, b) if a[0] == "k" else (b, a)
                body.append(f"{I}{I}s[{o[1]}][k] = {c[1]} * {val(u, 'k')};")
            else:
                body += sum_lines(f"s[{o[1]}][k]", f"{val(a, 'j')}, {val(b, 'k - j')}", "0", "k")
        elif kind == "div":
            a, b = o[2], o[3]
            if b[0] == "k":
                body.append(f"{I}{I}s[{o[1]}][k] = {val(a, 'k')} / {b[1]};")
            else:
                w = o[1]
                body += [f"{I}{I}{{", f"{I}{I}{I}double acc = {val(a, 'k')};",
                         f"{I}{I}{I}for (int j = 1; j <= k; j++) acc = SP_FMA(-{val(b, 'j')}, s[{w}][k - j], acc);",
                         f"{I}{I}{I}s[{w}][k] = acc / {val(b, '0')};", f"{I}{I}}}"]
        elif kind == "sincos":
            (si, co), u = o[1], o[2]
            body += [f"{I}{I}if (k == 0) {{", f"{I}{I}{I}s[{si}][0] = sin({val(u, '0')});",
                     f"{I}{I}{I}s[{co}][0] = cos({val(u, '0')});", f"{I}{I}}} else {{",
                     f"{I}{I}{I}double as = 0.0, ac = 0.0;",
                     f"{I}{I}{I}for (int j = 1; j <= k; j++) {{",
                     f"{I}{I}{I}{I}const double ju = (double)j * {val(u, 'j')};",
                     f"{I}{I}{I}{I}as = SP_FMA(ju, s[{co}][k - j], as);",
                     f"{I}{I}{I}{I}ac = SP_FMA(ju, s[{si}][k - j], ac);", f"{I}{I}{I}}}",
                     f"{I}{I}{I}s[{si}][k] = as * inv[k];", f"{I}{I}{I}s[{co}][k] = -ac * inv[k];", f"{I}{I}}}"]
        elif kind == "atan":
            (w, d), u = o[1], o[2]
            body += [f"{I}{I}{{", f"{I}{I}{I}double dd = k == 0 ? 1.0 : 0.0;",
                     f"{I}{I}{I}for (int j = 0; j <= k; j++) dd = SP_FMA({val(u, 'j')}, {val(u, 'k - j')}, dd);",
                     f"{I}{I}{I}s[{d}][k] = dd;", f"{I}{I}}}",
                     f"{I}{I}if (k == 0) s[{w}][0] = atan({val(u, '0')});", f"{I}{I}else {{",
                     f"{I}{I}{I}double acc = 0.0;",
                     f"{I}{I}{I}for (int j = 1; j < k; j++) acc = SP_FMA((double)j * s[{w}][j], s[{d}][k - j], acc);",
                     f"{I}{I}{I}s[{w}][k] = ({val(u, 'k')} - acc * inv[k]) / s[{d}][0];", f"{I}{I}}}"]
    # the solve at order k: r = f[k] - sum_{j>=1} M[j] a[k-j]; a[k] = M[0]^-1 r (L D L^T of M[0] at k = 0)
    solve = [f"{I}{I}if (k == 0) {{  /* M[0] = L D L^T, the chain's mass matrix at the state */"]
    for i in range(n):
        for j in range(i + 1):
            solve.append(f"{I}{I}{I}m0[{i}][{j}] = {val(mij(i, j), '0')};")
    solve += [f"{I}{I}{I}for (int j = 0; j < {n}; j++) {{",
              f"{I}{I}{I}{I}double dj = m0[j][j];",
              f"{I}{I}{I}{I}for (int l = 0; l < j; l++) dj -= lo[j][l] * lo[j][l] * dg[l];",
              f"{I}{I}{I}{I}dg[j] = dj;",
              f"{I}{I}{I}{I}for (int i = j + 1; i < {n}; i++) {{",
              f"{I}{I}{I}{I}{I}double v = m0[i][j];",
              f"{I}{I}{I}{I}{I}for (int l = 0; l < j; l++) v -= lo[i][l] * lo[j][l] * dg[l];",
              f"{I}{I}{I}{I}{I}lo[i][j] = v / dj;", f"{I}{I}{I}{I}}}", f"{I}{I}{I}}}", f"{I}{I}}}"]
    for i in range(n):
        terms = [(mij(i, l), l) for l in range(n) if mij(i, l)[0] != "k"]
        solve.append(f"{I}{I}r[{i}] = {val(f[i], 'k')};")
        if terms:
            solve += [f"{I}{I}for (int j = 1; j <= k; j++) {{"]
            solve += [f"{I}{I}{I}r[{i}] = SP_FMA(-{val(m, 'j')}, a[{l}][k - j], r[{i}]);" for m, l in terms]
            solve += [f"{I}{I}}}"]
    solve += [f"{I}{I}for (int i = 0; i < {n}; i++) {{  /* L z = r, D y = z, L^T a = y */",
              f"{I}{I}{I}double v = r[i];", f"{I}{I}{I}for (int l = 0; l < i; l++) v -= lo[i][l] * r[l];",
              f"{I}{I}{I}r[i] = v;", f"{I}{I}}}",
              f"{I}{I}for (int i = {n - 1}; i >= 0; i--) {{", f"{I}{I}{I}double v = r[i] / dg[i];",
              f"{I}{I}{I}for (int l = i + 1; l < {n}; l++) v -= lo[l][i] * a[l][k];",
              f"{I}{I}{I}a[i][k] = v;", f"{I}{I}}}"]
    solve += [f"{I}{I}for (int i = 0; i < {n}; i++) {{",
              f"{I}{I}{I}x[i][k + 1] = x[{n} + i][k] * inv[k + 1];",
              f"{I}{I}{I}x[{n} + i][k + 1] = a[i][k] * inv[k + 1];", f"{I}{I}}}"]
    wterms = []
    for i, q in enumerate(Q):
        if q == ("k", "0.0"):
            continue
        if q[0] == "k":
            wterms.append(f"{I}{I}{I}w = SP_FMA({q[1]}, x[{n + i}][k], w);")
        else:
            wterms.append(f"{I}{I}{I}for (int j = 0; j <= k; j++) w = SP_FMA({val(q, 'j')}, x[{n + i}][k - j], w);")
    work = [f"{I}{I}if (work) {{", f"{I}{I}{I}double w = 0.0;", *wterms,
            f"{I}{I}{I}x[{tn - 1}][k + 1] = w * inv[k + 1];", f"{I}{I}}} else {{", f"{I}{I}{I}x[{tn - 1}][k + 1] = 0.0;",
            f"{I}{I}}}"]
    energy = function_lines(fns["energy"], ["y0", "pc"], [["E"]], f"{I}{I}", True, "c")
    out += ["/* coefficients 1 .. SP_TORDER of x[SP_TN] from x[i][0]: x[i][k + 1] = (x_i')[k] / (k + 1) */",
            "static void taylor_jet(double (*restrict x)[SP_TPMAX + 2], const double *restrict pc, int work, double *e_out)",
            "{",
            f"{I}static const double inv[SP_TPMAX + 2] = {{0.0, {', '.join(f'1.0 / {i}' for i in range(1, SP_TPMAX + 2))}}};",
            f"{I}static _Thread_local double s[SP_NS][SP_TORDER];",
            f"{I}double a[{n}][SP_TORDER], r[{n}], m0[{n}][{n}], lo[{n}][{n}], dg[{n}];",
            f"{I}if (e_out) {{  /* the energy T + Pi at x[.][0] */",
            f"{I}{I}double y0[{2 * n}];",
            f"{I}{I}for (int i = 0; i < {2 * n}; i++) y0[i] = x[i][0];",
            *energy, f"{I}{I}*e_out = E;", f"{I}}}",
            f"{I}for (int k = 0; k < SP_TORDER; k++) {{", *body, *solve, *work, f"{I}}}", "}", ""]
    driver = (Path(__file__).resolve().parent / "taylor.c").read_text()
    return "\n".join(out) + "\n" + driver
