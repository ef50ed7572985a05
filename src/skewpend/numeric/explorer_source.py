"""The explorer's physics, one contract for every model and form (one physics printer for the page):
:func:`explorer_js` prints it in :func:`page_form`'s form -- the derivation's expressions for the double pendulum's
parameters (:func:`skewpend.numeric.codegen.exact_explorer_js`), the recursive algorithms' CasADi graphs otherwise
(:func:`skewpend.numeric.recursive.chain_code`'s module, its ``linear`` by CasADi's differentiation).  Above both
generators (it imports them; neither imports it)."""

from __future__ import annotations

from typing import List

from ..symbolic.model import Parameters
from .codegen import exact_explorer_js, js_rows
from .conventions import SCALAR_ORDER

__all__ = ["page_form", "page_vector", "explorer_js"]


def page_form(model=None):
    """The form of the explorer's physics for ``model`` (default: the specification's thin rods, every scalar
    symbolic: the sliders at the reference case's values) and the model it prints: ``("exact", params)``, the
    derivation of the double pendulum's parameters where the model has them (``model.exact_model()``: every
    scalar in ``p``, a slider), or ``("recursive", chain)``, the recursive algorithms' graphs (its bodies
    fixed: longer chains, and any model with Coulomb friction or rotors, which the sliders do not set)."""
    model = Parameters() if model is None else model
    exact = None if model.has_friction or model.has_rotor else model.exact_model()
    if exact is not None:
        return "exact", exact
    if not model.is_numeric:
        from ..errors import ParameterError

        raise ParameterError("the explorer has Coulomb friction and rotor inertia in a numeric model only (its physics "
                             "then the recursive algorithms', its sliders g and the damping); give every value, or leave "
                             "cf1 = cf2 = Ir = 0")
    return "recursive", model.as_chain()


def page_vector(model=None):
    """``(form, printed, names, values)``: :func:`page_form` and the parameter vector ``p`` of the page's physics,
    its entries' names and the model's values (the reference case's where symbolic: the sliders' start)."""
    form, printed = page_form(model)
    if form == "exact":
        from ..config import reference_parameters

        reference = reference_parameters()
        return form, printed, SCALAR_ORDER, [0.0 if n == "alpha" and not printed.uses_alpha else float(
            getattr(printed, n) if getattr(printed, n) is not None else getattr(reference, n)) for n in SCALAR_ORDER]
    from .recursive import parameter_names, parameter_vector as chain_vector

    return form, printed, parameter_names(printed.n), [float(v) for v in chain_vector(printed)]


def explorer_js(model=None, rest=None) -> str:
    """The explorer's physics for ``model`` (an ES module), one contract for every model and form: its
    ``PARAMETER_ORDER``, ``P`` (:func:`page_vector`), ``N`` links, ``rhs(y, p)``, ``energy(y, p)``, the
    drawing's ``tips(y, p)`` (the rods' ends, 3 n [m]), ``hinges(y, p)`` (the hinges' positions, 3 n [m]: each
    link drawn from its hinge to the next one) and ``axes(y, p)`` (the hinge axes in the world frame, 3 n), ``linear(y, p)`` (``[M0, K0]`` at rest, n x n: the mass matrix and the Hessian of Pi, for the
    normal modes computed in the browser), the equations of motion as ``TERMS`` (``[entry, exponents, LaTeX
    of the monomial]``, :func:`~skewpend.numeric.codegen.equation_terms`; none where the form has no symbolic
    equations) with ``coefficients(p)``, and ``FLIP_ODD`` (without torques the equations are odd under ``(q,
    q') -> -(q, q')``).  Printed by the model's own code generators in :func:`page_form`'s form; nothing is
    typed by hand but the LDL^T solve.  ``rest``: the angles of the hanging rest ``linear`` is taken at and
    ``REST`` holds (default every q = 0; the DeepMind acrobot's, whose zero is upright, (pi, 0): the views pass
    :func:`~skewpend.analysis.control.hanging_rest`'s)."""
    form, printed, _, values = page_vector(model)
    if form == "exact":
        return exact_explorer_js(printed, values)
    from .recursive import chain_code

    return chain_code(printed, "javascript") + "\n".join(["", *_recursive_linear(printed, rest), *_no_terms()])


def _recursive_linear(chain, rest=None) -> List[str]:
    """``linear(y, p)`` of a chain's page, from its recursive algorithms' graphs: ``[M0, K0]`` at the hanging rest
    ``rest`` (default q = 0; M there, K0 the Hessian of the energy Pi there, by CasADi's differentiation), and
    ``REST``, its angles."""
    from ..errors import require
    from .recursive import chain_functions, function_lines, structure_of_chain

    ca, n = require("casadi", "a chain of links (its recursive algorithms)"), chain.n
    fns = chain_functions(structure_of_chain(chain))
    q, p = ca.SX.sym("q", n), ca.SX.sym("p", fns["energy"].size1_in(1))
    hessian = ca.hessian(fns["energy"](ca.vertcat(q, ca.SX.zeros(n)), p), q)[0]
    rest = [0.0] * n if rest is None else [float(v) for v in rest]
    at_rest = lambda e: ca.substitute(e, q, ca.DM(rest))  # noqa: E731
    # K0 has structural zeros where Pi does not depend on an angle (the rotary pendulum's arm: its row and
    # column): the printer writes them 0.0 (function_lines writes every entry of every output)
    linear = ca.Function("linear", [p], [at_rest(fns["mass"](q, p)), at_rest(ca.reshape(hessian, n * n, 1))])
    packed = [f"m{i}_{j}" for i in range(n) for j in range(i + 1)]
    return ["/** the hanging rest's angles [rad]: where linear is taken */",
            f"export const REST = [{', '.join(repr(v) for v in rest)}];",
            "/** the linearisation at the hanging rest REST: [M0, K0], M0 = M(REST), K0 = the Hessian of Pi there (y is not read) */",
            "export function linear(y, p = P) {",
            *function_lines(linear, ["p"], [packed, [f"r{i}" for i in range(n * n)]], "  ", True, "javascript"),
            f"  return [{js_rows(n, lambda i, j: f'm{max(i, j)}_{min(i, j)}')}, {js_rows(n, lambda i, j: f'r{i * n + j}')}];", "}", ""]


def _no_terms() -> List[str]:
    return ["/** the equations' terms: none (the recursive algorithms print no symbolic equations: the page shows M0, K0) */",
            "export const TERMS = [];", "export function coefficients(p = P) { return []; }",
            "/** mirror starts are not assumed to flip alike (a chain's bodies need not be symmetric) */",
            "export const FLIP_ODD = false;", ""]


