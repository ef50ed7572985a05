"""The LaTeX layout of long derived expressions: line breaking that keeps display mathematics
within a page's width, aligned blocks of matrix components, the equations of motion and the
linearised equations as typeset rows -- shared by the report and the web explorer (and any
other view that shows the derivation).

``layout(label, label_cols, value, tex)`` typesets a scalar, vector or matrix under a label,
breaking long sums between terms; ``equations_tex(M, f, tex)`` the equations ``M q'' = f`` (one
row per equation); ``linear_tex(lin, tex)`` the linearised ``M0 q'' + C0 q' + K0 q = 0``;
``numeric(expr, digits)`` rounds the numbers of an expression for display.  ``tex`` is the
renderer's LaTeX of one expression (:func:`skewpend.symbolic.render.tex`).
"""

from __future__ import annotations

from typing import List, Optional, Sequence, Tuple

__all__ = ["LINE_COLUMNS", "layout", "aligned", "equations_tex", "equations_fit", "numeric", "rounded_linear",
           "linear_tex"]


#: Width of a line of display mathematics, in columns of SymPy's pretty printer (about 7.5 px
#: each at the report's font size: the text column holds about 100).
LINE_COLUMNS = 88


def _width(expr) -> int:
    """Rough rendered width of an expression, in columns (SymPy's 2-D pretty print)."""
    import sympy as sp

    from ..symbolic.render import UNICODE

    text = sp.pretty(expr.xreplace(UNICODE), use_unicode=True, wrap_line=False, num_columns=10**6)
    return max((len(line) for line in text.splitlines()), default=0)


def _signed(tex: str, first: bool) -> str:
    """A term's LaTeX after the previous one: `` + t`` or `` - t`` (the first keeps its sign)."""
    if first:
        return tex
    return " - " + tex[1:] if tex.startswith("-") else " + " + tex


def _pack(items: Sequence[Tuple[str, int]], room: int, later: int) -> List[str]:
    """``(tex, width)`` terms of a sum packed into lines of at most ``room`` (the first line) and
    ``later`` columns; every line but the first starts with its sign."""
    lines: List[str] = []
    current, used = "", 0
    for k, (tex, w) in enumerate(items):
        limit = room if not lines else later
        if current and used + w + 3 > limit:
            lines.append(current)
            current, used = "", 0
        current += _signed(tex, first=(k == 0))
        used += w + 3
    lines.append(current)
    return [ln.lstrip() for ln in lines]


def _flat_terms(terms: Sequence, limit: int) -> List:
    """Terms of a sum, a term wider than ``limit`` that is a product with a sum in it distributed
    over that sum (so that it can be broken too)."""
    import sympy as sp

    out: List = []
    for t in terms:
        if _width(t) > limit and isinstance(t, sp.Mul) and any(isinstance(f, sp.Add) for f in t.args):
            out += _flat_terms(sp.Add.make_args(sp.expand(t, deep=False, trig=False, power_exp=False, log=False, multinomial=False)), limit)
        else:
            out.append(t)
    return out


def _sum_lines(expr, tex, room: int, later: int) -> Optional[Tuple[str, List[str], str]]:
    """``(head, lines, tail)`` for a long expression broken between the terms of a sum, or of the
    one sum in a product (``head [ ... ] tail``); None when it cannot be broken."""
    import sympy as sp

    if isinstance(expr, sp.Add):
        terms = _flat_terms(sp.Add.make_args(expr), later)
        lines = _pack([(tex(t), _width(t)) for t in terms], room, later)
        return ("", lines, "") if len(lines) > 1 else None
    if isinstance(expr, sp.Mul):
        sums = [f for f in expr.args if isinstance(f, sp.Add)]
        if len(sums) == 1:
            inner = sums[0]
            rest = sp.Mul(*[f for f in expr.args if f is not inner])
            head = "" if rest == 1 else ("-" if rest == -1 else tex(rest))
            w = _width(rest) + 2
            terms = _flat_terms(sp.Add.make_args(inner), later - 2)
            lines = _pack([(tex(t), _width(t)) for t in terms], room - w, later - 2)
            if len(lines) > 1:
                return head + r"\Bigl[", lines, r"\Bigr]"
    return None


def _long(label: str, label_cols: int, expr, tex) -> List[str]:
    """``label &= expr`` as rows of an ``aligned`` block, broken between the terms of a long sum
    (or of the one sum in a product, written ``factor [ ... ]``); continuation rows start at
    the alignment point."""
    room = LINE_COLUMNS - label_cols - 3
    if _width(expr) <= room or room < 24:
        return [f"{label} &= {tex(expr)}"]
    split = _sum_lines(expr, tex, room, room - 3)
    if split is None:
        return [f"{label} &= {tex(expr)}"]
    head, lines, tail = split
    rows = [f"{label} &= {head}{lines[0]}"] + [r"&\quad " + ln for ln in lines[1:]]
    rows[-1] += tail
    return rows


def aligned(rows: Sequence[str]) -> str:
    return r"\begin{aligned}" + r" \\ ".join(rows) + r"\end{aligned}"


def _component(label: str, i: int, j: Optional[int] = None) -> str:
    """``P_{12}``, ``f_{1}``; ``(\\underline{\\vartheta}_c)_{1}`` for a decorated label (1, 2, 3 = i, j, k)."""
    index = f"{i + 1}" if j is None else f"{i + 1}{j + 1}"
    plain = {r"\underline{\underline{P}}": "P", r"\underline{\underline{\Theta}}_2": r"\Theta_{2}",
             r"\underline{\vartheta}_c": r"\vartheta_{c}", r"\underline{\omega}_2": r"\omega_{2}", r"\underline{e}": "e"}
    base = plain.get(label, label)
    if base.endswith("}") and "_{" in base:  # \Theta_{2} -> \Theta_{2,12}
        return base[:-1] + "," + index + "}"
    return f"{base}_{{{index}}}"


def layout(label: str, label_cols: int, value, tex, *, prefix: str = "") -> str:
    """Display mathematics for ``label = prefix value``: whole when it fits a line; else a matrix
    or vector entry by entry (components 1, 2, 3 along i, j, k; a symmetric matrix's entries
    below the diagonal named with those above; zero entries listed together), each long entry
    broken between terms."""
    import sympy as sp

    if not isinstance(value, sp.MatrixBase):
        rows = _long(f"{label} = {prefix}".rstrip(" ="), label_cols, value, tex)
        return aligned(rows) if len(rows) > 1 else rows[0].replace("&=", "=")
    if _width(value) + label_cols <= LINE_COLUMNS:
        return f"{label} = {prefix}" + tex(value)
    rows = [f"{label} &= {prefix.rstrip(' =')}" + r",\quad\text{by components:}" if prefix else ""]
    rows = [r for r in rows if r]
    symmetric = value.rows == value.cols and value.rows > 1 and value == value.T
    zeros = []
    for i in range(value.rows):
        for j in range(value.cols):
            if symmetric and j < i:
                continue
            name = _component(label, i) if value.cols == 1 else _component(label, i, j)
            if symmetric and i != j:
                name += " = " + _component(label, j, i)
            if value[i, j] == 0:
                zeros.append(name)
                continue
            rows += _long(name, 10 if not (symmetric and i != j) else 20, value[i, j], tex)
    if zeros:
        rows.append(", ".join(zeros) + " &= 0")
    return aligned(rows)


def _equation_rows(lhs: str, lhs_cols: int, rhs, tex) -> List[str]:
    """``lhs = rhs`` as left-aligned rows: one line if it fits; else the left-hand side on its
    own line and ``= rhs`` below it, broken between terms."""
    room = LINE_COLUMNS - 4
    if lhs_cols + _width(rhs) + 3 <= room:
        return [f"&{lhs} = {tex(rhs)}"]
    split = _sum_lines(rhs, tex, room - 6, room - 6)
    if split is None:
        return [f"&{lhs}", r"&\qquad = " + tex(rhs)]
    head, lines, tail = split
    rows = [f"&{lhs}", r"&\qquad = " + head + lines[0]] + [r"&\qquad\quad " + ln for ln in lines[1:]]
    rows[-1] += tail
    return rows


def equations_tex(M, f, tex) -> str:
    """The equations of motion ``(M11) phi'' + (M12) psi'' = f1`` and the second row written out
    (in terms of the entries' names when a left-hand side is wider than a line)."""
    dd = (r"\ddot\varphi", r"\ddot\psi")
    wide = max(_width(M[i, 0]) + _width(M[i, 1]) for i in range(2)) + 14 > LINE_COLUMNS - 8
    rows: List[str] = []
    for i in range(2):
        if wide:
            rows.append(f"&M_{{{i + 1}1}}" + dd[0] + f" + M_{{{i + 1}2}}" + dd[1] + f" = f_{{{i + 1}}}")
            continue
        terms = [_coefficient(M[i, j], dd[j], tex) for j in range(2) if M[i, j] != 0]
        lhs = "".join(_signed(t, first=(k == 0)) for k, t in enumerate(terms))
        rows += _equation_rows(lhs, _width(M[i, 0]) + _width(M[i, 1]) + 14, f[i], tex)
        if i == 0:
            rows[-1] += r"\\[0.4em]"
    return aligned(rows).replace(r"\\[0.4em] \\", r"\\[0.4em]")


def equations_fit(M) -> bool:
    return max(_width(M[i, 0]) + _width(M[i, 1]) for i in range(2)) + 14 <= LINE_COLUMNS - 8


def numeric(expr, digits: int = 5):
    """An expression (or matrix) with its numbers rounded to ``digits`` significant digits and
    the terms in the speeds collected."""
    import sympy as sp

    from ..symbolic.symbols import SYMBOLS

    dphi, dpsi = SYMBOLS["dphi"], SYMBOLS["dpsi"]

    def one(e):
        e = sp.expand(e)
        if e.has(dphi) or e.has(dpsi):
            e = sp.collect(e, [dphi**2, dphi * dpsi, dpsi**2, dphi, dpsi])
        e = sp.N(e, digits)
        rounded = {}
        for x in e.atoms(sp.Float):
            v = float(f"{float(x):.{digits}g}")
            rounded[x] = sp.Integer(int(v)) if v.is_integer() else sp.Float(v, digits)
        return e.xreplace(rounded)

    return expr.applyfunc(one) if isinstance(expr, sp.MatrixBase) else one(expr)


def rounded_linear(lin, digits: int):
    from types import SimpleNamespace

    return SimpleNamespace(M=numeric(lin.M, digits), C=numeric(lin.C, digits), K=numeric(lin.K, digits))


def _coefficient(coeff, symbol: str, tex) -> str:
    """``coeff symbol`` (parentheses around a sum; ``1``/``-1`` left out)."""
    import sympy as sp

    if coeff == 1:
        return symbol
    if coeff == -1:
        return "-" + symbol
    if isinstance(coeff, sp.Add):
        return r"\left(" + tex(coeff) + r"\right)" + symbol
    return tex(coeff) + r"\," + symbol


def linear_tex(lin, tex) -> str:
    """``M0 q'' + C0 q' + K0 q = 0`` written out row by row, left-aligned, broken between terms."""
    names = ((lin.M, (r"\ddot\varphi", r"\ddot\psi")), (lin.C, (r"\dot\varphi", r"\dot\psi")), (lin.K, (r"\varphi", r"\psi")))
    rows = []
    for i in range(2):
        items = [(_coefficient(mat[i, j], sym[j], tex), _width(mat[i, j]) + 5)
                 for mat, sym in names for j in range(2) if mat[i, j] != 0]
        lines = _pack(items, LINE_COLUMNS - 6, LINE_COLUMNS - 10)
        lines[-1] += " = 0"
        rows += ["&" + lines[0]] + [r"&\quad " + ln for ln in lines[1:]]
    return aligned(rows)
