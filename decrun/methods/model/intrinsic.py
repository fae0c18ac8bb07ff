"""What a model may read under ``operator=intrinsic_delaunay``, checked when it loads.

The intrinsic Delaunay triangulation shares the mesh's vertices but not its edges or triangles
(:mod:`decrun.core.intrinsic_calculus`). Its 0-forms are the mesh's; its primal 1-forms, vector
fields and per-triangle values live on the intrinsic edges and triangles, where the language has
d of 0-forms, ♯, ♭, δ of 1-forms, |X| and normalize — the heat method's gradient and divergence.
Every other operator on 1-forms, vectors or per-triangle values reads the mesh's own edges and
triangles, and a 1-form field is stored on them: a model that uses one is refused before any
work, in one line naming the term; so is a named definition of such a kind other than a vector
field (a run stores and draws definitions on the mesh's simplices).
"""

from __future__ import annotations

from decrun.methods.model.kinds import NUMBER, VECTOR, Kind, primal
from decrun.methods.model.language import Binary, Call, ModelError, Name, Negate, to_text
from decrun.methods.model.operators import ALIASES

__all__ = ["INTRINSIC_OPERATORS", "check_intrinsic"]

#: operator → the argument kind it takes on the intrinsic triangulation
INTRINSIC_OPERATORS = {"d": primal(0), "sharp": primal(1), "flat": VECTOR, "codifferential": primal(1),
                       "norm": VECTOR, "normalize": VECTOR}


def _on_vertices(kind: Kind) -> bool:
    return kind == NUMBER or kind == primal(0)


def check_intrinsic(compiler, dec, trees) -> None:
    """Raise :class:`ModelError` for the first term of ``trees`` ((where, tree) pairs) that
    reads the mesh's own edges or triangles while ``dec``'s variant computes on an intrinsic
    triangulation (nothing to check for the other variants)."""
    if not hasattr(dec.star_variant, "calculus"):
        return
    name = dec.star_variant.name
    allowed = ", ".join(f"{op}" for op in INTRINSIC_OPERATORS)

    def refuse(where, term, why):
        raise ModelError(f"{where}: {to_text(term)} {why}; operator={name} computes on its intrinsic triangulation, "
                         f"where the language has {allowed} (on 0-forms, 1-forms and vector fields there) — use "
                         "`operator=mixed_area` for this model")

    def walk(where, node):
        if isinstance(node, Binary):
            walk(where, node.left)
            walk(where, node.right)
        elif isinstance(node, Negate):
            walk(where, node.operand)
        elif isinstance(node, Name):
            kind = compiler.kind(node, where)
            defined = node.name in compiler.definitions or node.name in compiler.solved
            if not defined and not _on_vertices(kind):
                refuse(where, node, f"is a {kind} field, stored on the mesh's own simplices")
        elif isinstance(node, Call):
            for arg in node.args:
                walk(where, arg)
            function = ALIASES.get(node.function, node.function)
            kinds = [compiler.kind(arg, where) for arg in node.args]
            result = compiler.kind(node, where)
            if all(_on_vertices(kind) for kind in (*kinds, result)):
                return
            if function in INTRINSIC_OPERATORS and kinds == [INTRINSIC_OPERATORS[function]]:
                return
            refuse(where, node, "reads the mesh's own edges or triangles")

    for where, tree in trees:
        walk(where, tree)

    for target, node in compiler.definitions.items():  # stored and drawn on the mesh's own simplices
        kind = compiler.kind(node, f"app.equations ({target} = …)")
        if not (_on_vertices(kind) or kind == VECTOR):
            refuse(f"app.equations ({target} = …)", Name(target), f"is a {kind}, which a run stores and draws on the "
                   "mesh's own simplices (keep it inside an expression, or define a 0-form)")
