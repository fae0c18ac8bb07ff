"""Non-finite values of a model, named where they arise (issue 50, items 2 and 8).

Two checks, each one line naming the equation:

- :func:`check_finite_numbers`, at load: every number an equation computes from constants and
  built-ins alone (``Gamma = 2*A*(rho*g)**n/(n + 2)``, the ``k**1e308`` of ``k**1e308 *
  laplacian(u)``) is evaluated once and refused when it is inf or nan — a float64 overflows
  beyond 1.8e308 — naming the constants it reads, before a matrix full of inf reaches a solver;
- :func:`nonfinite_definitions`, after a run: each definition whose stored values hold inf or
  nan (``v = 1/x`` on a mesh with vertices at x = 0), with how many of its entries are."""

from __future__ import annotations

import numpy as np

from decrun.methods.model.kinds import NUMBER
from decrun.methods.model.language import Binary, Call, Equation, ModelError, Name, Negate, Node, Number, to_text

__all__ = ["check_finite_numbers", "nonfinite_definitions", "negative_norms", "nonfinite_lines"]


def _sides(equation: Equation) -> list[Node]:
    pairs = equation.pairs or ((equation.lhs, equation.rhs),)
    return [side for pair in pairs for side in pair if side is not None and not _is_dt(side)]


def _is_dt(node: Node) -> bool:
    return isinstance(node, Call) and node.function == "dt"


def check_finite_numbers(compiler, equations: list[Equation], key: str) -> None:
    """Refuse an equation holding a number that depends on constants and built-ins only (no
    field that changes, no solve's unknown) and is not finite: one line naming the equation, the
    term, its value and the constants it reads (``key``: ``app``, their config prefix)."""
    known = set(compiler.static_env)
    for equation in equations:
        for side in _sides(equation):
            for term in _static_numbers(compiler, side, known):
                with np.errstate(all="ignore"):
                    value = compiler.static_value(term)
                if np.all(np.isfinite(value)):
                    continue
                constants = sorted(name for name in compiler.reads(term) if name in compiler.static_env
                                   and np.ndim(compiler.static_env[name]) == 0 and name not in ("pi", "h", "dt", "area"))
                read = ", ".join(f"{key}.constants.{name}={float(compiler.static_env[name]):g}" for name in constants)
                raise ModelError(f"{equation.where}: {to_text(term)} is {float(value)} (a float64 overflows beyond "
                                 f"1.8e308){' with ' + read if read else ''}; choose constants for which it is "
                                 "finite")


def _static_numbers(compiler, node: Node, known: set[str]):
    """The largest subtrees of ``node`` that are numbers computed from ``known`` names only
    (definitions followed), literals and names themselves left out (a constant is finite)."""
    if isinstance(node, (Number, Name)):
        return
    reads = compiler.reads(node) - set(compiler.definitions)
    if reads <= known and compiler.is_static(node) and compiler.kind(node, "?") == NUMBER:
        yield node
        return
    children = node.args if isinstance(node, Call) else (node.left, node.right) if isinstance(node, Binary) else \
        (node.operand,) if isinstance(node, Negate) else ()
    for child in children:
        yield from _static_numbers(compiler, child, known)


def nonfinite_definitions(model, env: dict) -> dict[str, str]:
    """Each definition whose value in ``env`` holds inf or nan, by name: one line with its key,
    the definition as written, and how many of its entries are not finite (of how many)."""
    lines = {}
    wheres = {equation.target: equation for equation in model.equations if equation.kind == "definition"}
    for what, item in model.order:
        if what != "definition" or item[0] not in env:
            continue
        name = item[0]
        value = np.asarray(env[name], dtype=np.float64)
        bad = int(np.count_nonzero(~np.isfinite(value)))
        if bad:
            equation = wheres[name]
            lines[name] = (f"{equation.where}: the definition {equation.text.strip()} is not finite at {bad} of its "
                           f"{value.size} entries")
    return lines


def negative_norms(model, env: dict) -> list[str]:
    """One line per declared metric holding ``norm(w)`` of a form whose ⋆ inner product ⟨w, w⟩ is
    negative at ``env`` (the norm is then nan, not a clamped 0): the metric's key, the term,
    ⟨w, w⟩ and how many entries of the ⋆ that weighs it are negative, with the fixes."""
    from decrun.methods.model.language import parse_expression
    from decrun.methods.model.operators import inner_product, weights

    lines = []
    compiler, ops = model.compiler, model.ops
    for name, text in model.spec.metrics.items():
        where = f"{model.spec.key}.metrics.{name}"
        for term in _calls(parse_expression(text, where), "norm"):
            kind = compiler.kind(term.args[0], where)
            if not kind.is_form:
                continue
            with np.errstate(all="ignore"):
                value = compiler.compile(term.args[0], where)(env)
                square = inner_product(ops, kind, value, value)
            if not square < 0:
                continue
            degree = weights(ops, kind)[1]
            star = ops.dec.star(degree)
            diagonal = np.asarray(star.diagonal() if hasattr(star, "diagonal") else star, dtype=np.float64)
            negative = int(np.count_nonzero(diagonal < 0))
            lines.append(f"{where}: {to_text(term)} is nan: its ⋆ inner product is {square:.3g} < 0, because ⋆{degree} "
                         f"has {negative} negative entries (circumcentric ⋆ on obtuse triangles); use "
                         "`operator=whitney` or a mesh without obtuse triangles")
    return lines


def _calls(node: Node, function: str) -> list[Call]:
    """Every call of ``function`` in ``node``."""
    found = [node] if isinstance(node, Call) and node.function == function else []
    children = node.args if isinstance(node, Call) else (node.left, node.right) if isinstance(node, Binary) else \
        (node.operand,) if isinstance(node, Negate) else ()
    for child in children:
        found += _calls(child, function)
    return found


def nonfinite_lines(model, env: dict) -> list[str]:
    """The run's warnings about non-finite values at its end (``env``): the metrics that could not
    be evaluated (:func:`~decrun.methods.model.metrics.metric_values`), the definitions
    (:func:`nonfinite_definitions`) and the norms of indefinite inner products (:func:`negative_norms`)."""
    failed = [f"{model.spec.key}.metrics.{name}: cannot be evaluated ({error}); its value is nan"
              for name, error in getattr(model, "metric_errors", {}).items()]
    return [*failed, *nonfinite_definitions(model, env).values(), *negative_norms(model, env)]
