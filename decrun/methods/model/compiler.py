"""Typed expression trees → numpy closures and sparse linear blocks.

:class:`Compiler` knows the kind of every name (fields, definitions, constants and the built-in
names ``x y z t dt h area pi``) and

- :meth:`~Compiler.kind` infers the kind of a tree, raising one :class:`ModelError` line that
  names the key and the offending term;
- :meth:`~Compiler.compile` turns a tree into ``f(env) -> value`` (``env``: name → array or
  float), with every maximal linear chain of operators applied to one name folded into one
  sparse matrix (``codifferential(d(u))`` is one product per evaluation);
- :meth:`~Compiler.linear_terms` splits a sum into the terms linear in a set of unknowns — as
  :class:`~decrun.methods.model.operators.Linear` blocks ``⋆⁻¹ A``, the matrices of implicit
  integrators and solves — and the remaining terms, evaluated explicitly.

The three jobs live in their own modules — kind inference in
:mod:`decrun.methods.model.kind_inference`, the evaluator in :mod:`decrun.methods.model.evaluate`,
the linear split in :mod:`decrun.methods.model.linear` — and :class:`Compiler` joins them over one
mesh's operators.
"""

from __future__ import annotations

from decrun.methods.model.evaluate import Evaluator
from decrun.methods.model.kind_inference import BUILTIN_NAMES, TIME_VARYING, KindInference
from decrun.methods.model.kinds import Kind
from decrun.methods.model.language import Node
from decrun.methods.model.linear import NOT_LINEAR, LinearSplit
from decrun.methods.model.operators import POINTWISE, Discrete
from decrun.methods.model.typed import Typed

__all__ = ["Compiler", "BUILTIN_NAMES", "NOT_LINEAR", "KindInference", "Evaluator", "LinearSplit"]


class Compiler(LinearSplit):
    """Kinds, closures and linear blocks of expressions over one mesh's operators.

    Parameters
    ----------
    ops : Discrete — the mesh's operators
    kinds : dict name → Kind of fields, definitions and constants (built-ins are added)
    definitions : dict name → tree of the definitions that may be inlined into linear terms
    varying : names whose values change from step to step (evolved fields, definitions of them,
        solve targets, ``t``)
    solved : dict name → tree of what each solve target is computed from (its equation's two
        sides), followed by :meth:`reads` but never inlined
    """

    def __init__(self, ops: Discrete, kinds: dict[str, Kind], definitions: dict[str, Node] | None = None,
                 varying: set[str] | None = None, solved: dict[str, Node] | None = None):
        self.ops, self.n = ops, ops.n
        self.kinds = {**BUILTIN_NAMES, **kinds}
        self.definitions = definitions or {}
        self.solved = solved or {}
        self.varying = set(varying or ()) | TIME_VARYING
        self._static_env: dict | None = None
        #: id(node) → its :class:`~decrun.methods.model.typed.Typed` node (which holds the node):
        #: every node typed so far (:meth:`typed`)
        self._typed: dict[int, Typed] = {}


#: the one-argument value-by-value functions (for :mod:`decrun.methods.model.initial`)
PURE = POINTWISE
