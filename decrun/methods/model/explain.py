"""What a compiled model is, as text: every equation's typed tree and the blocks it was lowered
into (``decrun app=<model> app.explain=true`` prints it and runs nothing).

The typed tree shows each node with its kind (primal/dual k-form, number, vector field), one
node a line, indented by depth. The block structure lists, in evaluation order, each definition
(a closure), each solve and system (its unknowns and the size and nonzeros of its matrix,
factorized once), and for each evolution its lowering
(:class:`~decrun.methods.model.lowering.Evolution`): the mass M_u, the linear blocks A_uv with
constant coefficients (implicit integrators put them in their matrix), and the other terms —
*explicit* when they read no evolved field, *nonlinear* when they do (Newton, lagging or an
explicit integrator handles those).
"""

from __future__ import annotations

import scipy.sparse as sp

from decrun.methods.model.border_labels import legend, relabel
from decrun.methods.model.language import Node, to_text

__all__ = ["explain", "typed_tree"]


def typed_tree(compiler, node: Node, where: str, depth: int = 1) -> list[str]:
    """The lines of ``node``'s typed tree (:class:`~decrun.methods.model.typed.Typed`), each node
    with its kind, as the kind pass kept it."""
    return compiler.typed(node, where).lines(depth)


def _matrix(A) -> str:
    return f"{A.shape[0]}×{A.shape[1]}, {A.nnz} nonzeros"


def _trees(model) -> list[str]:
    """Every equation and metric as written, then its typed trees (``model.typed``); a solve's
    and a system's sides are labelled."""
    texts = {equation.where: equation.text.strip() for equation in model.equations}
    texts.update({f"{model.spec.key}.metrics.{name}": str(text).strip() for name, text in model.spec.metrics.items()})
    sided = {side.where for side in model.typed if side.role.startswith("left side")}
    lines, shown = ["typed trees:"], set()
    for side in model.typed:
        if side.where not in shown:
            shown.add(side.where)
            lines.append(f"  {side.where}: {texts.get(side.where, '')}")
        if side.where in sided:
            lines.append(f"   {side.role}:")
        lines += side.tree.lines(2)
    return lines


def _order(model) -> list[str]:
    lines = ["definitions and solves, in evaluation order:"]
    for what, item in model.order:
        if what == "definition":
            name = item[0]
            lines.append(f"  definition {name} : {model.kinds[name]} (a closure)")
        elif what == "solve":
            lines.append(f"  solve for {item.unknown} : {model.kinds[item.unknown]}: linear, matrix "
                         f"{_matrix(item.system.A_full)} factorized once")
        elif what == "newton":
            lines.append(f"  solve for {item.unknown} : {model.kinds[item.unknown]}: nonlinear, Newton with the exact "
                         f"sparse Jacobian of {to_text(item.equation.lhs)}")
        else:
            names = ", ".join(item.unknowns)
            lines.append(f"  system for {names}: block matrix {_matrix(item.system.A_full)} factorized once")
    if len(lines) == 1:
        lines.append("  (none)")
    return lines


def _evolution(model) -> list[str]:
    evolution = model.evolution
    evolved = set(evolution.names)
    lines = ["evolution blocks (M_u u' = Σ_v A_uv v + M_u R_u):"]
    for u in evolution.names:
        M = evolution.mass[u]
        diagonal = (M - sp.diags(M.diagonal())).count_nonzero() == 0
        lines.append(f"  dt({u}) : {model.kinds[u]}, mass M_{u} {_matrix(M)} ({'diagonal' if diagonal else 'Galerkin'})")
        for (row, v), A in evolution.blocks.items():
            if row == u:
                lines.append(f"    linear A_{u}{v} (constant coefficients, implicit): {_matrix(A)}")
        for sign, term in evolution.rest_trees[u]:
            role = "nonlinear (reads " + ", ".join(sorted(model.compiler.reads(term) & evolved)) + ")" \
                if model.compiler.depends_on(term, evolved) else "explicit (reads no evolved field)"
            lines.append(f"    {role}: {'-' if sign < 0 else '+'} {to_text(term)}")
        if u in model.fixed:
            lines.append(f"    fixed (Dirichlet) values on {model.fixed[u][0].size} border simplices")
    return lines


def explain(model) -> str:
    """The typed trees and the block structure of a compiled model (module docstring)."""
    computed = {target: equation.where for equation in model.equations
                for target in equation.targets or (equation.target,)}
    roles = {name: "evolved" if name in model.evolved else "input" if name in model.inputs else
             f"computed by {computed[name]}" for name in model.spec.fields}
    kinds = ", ".join(f"{name} : {model.kinds[name]} ({role})" for name, role in roles.items())
    lines = [f"model: evolved {', '.join(model.evolved) or '(none: definitions and solves only)'}; "
             f"inputs {', '.join(model.inputs) or '(none)'}", f"fields: {kinds}"]
    lines += _trees(model) + _order(model)
    if model.evolved:
        lines += _evolution(model)
    lines += [f"metric {name} : number" for name in model.metrics]
    return relabel("\n".join(lines + legend(model.spec, model.kinds)), model.spec)  # border terms by meaning
