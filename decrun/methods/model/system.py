"""A model's equations compiled against one mesh: the plan every step runs.

:func:`compile_model` takes the model as plain data (:class:`ModelSpec`: fields with their form,
initial and border values, constants, equations, metrics) and a :class:`decrun.core.dec.DEC`,
and returns a :class:`CompiledModel`:

1. every equation is parsed (:mod:`~decrun.methods.model.language`) and classified — evolution
   ``dt(u) = …``, definition ``v = …``, solve ``solve(lhs = rhs)`` whose unknown is the one
   declared field of its left side that nothing else computes, system ``solve(l1 = r1, l2 = r2,
   …)`` with as many unknowns as equations (one block matrix,
   :func:`~decrun.methods.model.passes.systems._compile_system`);
2. definitions and solves are ordered by what they read (a cycle is refused, naming it) and
   typed in that order; every term is type-checked (:class:`~decrun.methods.model.compiler.Compiler`);
3. each solve's left side is split into a constant sparse matrix (factorized once) and terms
   moved to the right; each evolution's right side into its linear blocks and the rest (for
   the integrators, :mod:`~decrun.methods.model.integrators`).

Each pass is a module of :mod:`decrun.methods.model.passes`; this module holds the model as data
(:class:`ModelSpec`), the compiled model and :func:`compile_model`, the chain of the passes.

Evaluating the model at a state (:meth:`CompiledModel.environment`) computes every definition
and solve once, in order, into one dict of values that the equations and metrics read.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp

from decrun.methods.model import borders
from decrun.methods.model.compiler import Compiler
from decrun.methods.model.environment import environment
from decrun.methods.model.finite import check_finite_numbers
from decrun.methods.model.intrinsic import check_intrinsic
from decrun.methods.model.kinds import Kind
from decrun.methods.model.language import Equation
from decrun.methods.model.lowering import Evolution
from decrun.methods.model.metrics import metric_values
from decrun.methods.model.operators import Discrete, load_plugins
from decrun.methods.model.passes.bind import _bind_values, _dirichlet, border_simplices
from decrun.methods.model.passes.lower import _lower_equations
from decrun.methods.model.passes.metrics import _compile_metrics
from decrun.methods.model.passes.order import _order
from decrun.methods.model.passes.parse import _parse_equations, _parse_metrics
from decrun.methods.model.passes.resolve import (
    RESERVED,
    RESERVED_METRICS,
    Resolved,
    _check_initial_values,
    _check_known_names,
    _check_names,
    _resolve,
    reserved,
)
from decrun.methods.model.passes.solves import Solve, vertex_pieces
from decrun.methods.model.passes.stars import _check_stars
from decrun.methods.model.passes.systems import SystemSolve
from decrun.methods.model.passes.types import _declared_kinds, _type_definitions, _type_trees
from decrun.methods.model.problem import ModelProblem
from decrun.methods.model.typed import TypedSide

__all__ = ["FieldSpec", "ModelSpec", "CompiledModel", "compile_model", "border_simplices", "vertex_pieces",
           # importable from here as before the passes moved to decrun.methods.model.passes
           "RESERVED", "RESERVED_METRICS", "Resolved", "Solve", "SystemSolve", "reserved"]


@dataclass
class FieldSpec:
    """One field: ``form`` (``0..3`` or ``dual0..dual3``), ``initial`` (number, expression,
    list of expressions, ``result:<field>`` or None) and ``dirichlet`` (its values on the border
    simplices, None: natural; may read t), ``neumann`` (∂u/∂n) or ``robin`` ({alpha, value}):
    :mod:`decrun.methods.model.borders`."""

    form: Any = 0
    initial: Any = None
    dirichlet: Any = None
    neumann: Any = None
    robin: Any = None


@dataclass
class ModelSpec:
    """A model as data; ``key`` prefixes every config key in messages (``app``)."""

    fields: dict[str, FieldSpec]
    equations: list[str]
    constants: dict[str, float] = field(default_factory=dict)
    metrics: dict[str, str] = field(default_factory=dict)
    seed: int = 0
    key: str = "app"
    #: the time step (the name ``dt`` in expressions); NaN for models without one
    dt: float = float("nan")
    #: the config key of each equation in messages (a composed model's ``app.parts.<part>.equations[i]``);
    #: None: ``<key>.equations[i]``
    equation_keys: list[str] | None = None


@dataclass
class CompiledModel:
    """A model ready to run (see the module docstring).

    ``kinds``: every name's kind; ``evolved``: the fields with an evolution equation, in order;
    ``inputs``: declared fields nothing computes (their initial value stays); ``order``: the
    definitions and solves in evaluation order; ``rhs``: name → compiled right side of its
    evolution; ``metrics``: name → compiled number; ``fixed``: field → (border indices,
    values) of its Dirichlet condition."""

    spec: ModelSpec
    ops: Discrete
    compiler: Compiler
    kinds: dict[str, Kind]
    equations: list[Equation]
    evolved: list[str]
    inputs: list[str]
    #: ("definition", (name, closure)) | ("solve", Solve) | ("system", SystemSolve) | ("newton", NonlinearSolve)
    order: list[tuple[str, Any]]
    rhs: dict[str, Callable]
    metrics: dict[str, Callable]
    fixed: dict[str, tuple[np.ndarray, np.ndarray]]
    base: dict[str, Any]
    initial_values: dict[str, np.ndarray]
    #: the typed trees (every side of every equation and every metric, each node with its kind)
    typed: list[TypedSide] = field(default_factory=list)

    @property
    def is_static(self) -> bool:
        """True when nothing evolves: the definitions and solves run once."""
        return not self.evolved

    def environment(self, state: dict[str, np.ndarray], t: float, complete: bool = False) -> dict[str, Any]:
        """Every value at ``state`` (the evolved fields) and time ``t``: built-ins, constants,
        inputs, the state, then each definition and solve in order — those only metrics and
        records read when first read, unless ``complete`` (:mod:`~decrun.methods.model.environment`)."""
        env = dict(self.base)
        env.update(state)
        env["t"] = float(t)
        return environment(self, env, complete)

    def derivative(self, env: dict, names=None) -> dict[str, np.ndarray]:
        """dt(u) for each evolved field (or those in ``names``) at ``env``."""
        out = {}
        for name in names or self.evolved:
            value = self.rhs[name](env)
            if np.ndim(value) == 0:
                value = np.full(self.kinds[name].size(self.ops.K), float(value))
            if name in self.fixed:
                value = np.array(value, dtype=np.float64)
                constrained = self._constrained_masses().get(name)
                if constrained is not None:  # a Galerkin ⋆: the interior rows of M u' = M F, as the implicit schemes
                    M, inner, solve = constrained
                    value[inner] = solve((M @ value)[inner])
                value[self.fixed[name][0]] = 0.0  # fixed values do not move
            out[name] = value
        return out

    @property
    def evolution(self) -> Evolution:
        """The evolution equations lowered into linear blocks and explicit terms
        (:class:`~decrun.methods.model.lowering.Evolution`), made once and shared by every caller."""
        cached = getattr(self, "_evolution", None)
        if cached is None:
            cached = self._evolution = Evolution(self)
        return cached

    @property
    def problem(self) -> ModelProblem:
        """The model as M y' = f(y, t) over its free unknowns
        (:class:`~decrun.methods.model.problem.ModelProblem`), made once."""
        cached = getattr(self, "_problem", None)
        if cached is None:
            cached = self._problem = ModelProblem(self)
        return cached

    def _constrained_masses(self) -> dict:
        """field → (M, interior indices, solve with M_II) for each evolved field with fixed values
        whose evolution is weighted by a non-diagonal mass M (Whitney's ⋆): there dt(u) at the
        free values is M_II⁻¹ (M F)_I, not F_I — M⁻¹ spreads the border rows into the interior.
        Made once; empty for diagonal stars."""
        cached = getattr(self, "_constrained", None)
        if cached is None:
            from scipy.sparse.linalg import factorized

            cached = {}
            evolution = self.evolution
            for name in self.fixed:
                M = evolution.mass.get(name)
                if M is None or (M - sp.diags(M.diagonal())).count_nonzero() == 0:
                    continue
                inner = np.setdiff1d(np.arange(M.shape[0]), self.fixed[name][0])
                cached[name] = (M.tocsr(), inner, factorized(M.tocsr()[inner][:, inner].tocsc()))
            self._constrained = cached
        return cached

    def bind(self, new_solver: Callable) -> None:
        """Factorize every solve's system with ``new_solver()`` (the run's configured solver)."""
        for what, item in self.order:
            if what in ("solve", "system"):
                item.system.bind(new_solver)
            elif what == "newton":
                item.bind(new_solver)

    def check_compatibility(self) -> None:
        """Before any work: a singular solve (kernel of constants) whose right side reads only
        inputs, constants and coordinates is checked for a solution now (its right side's mean
        must be round-off), so the refusal comes before the run, not at its first step."""
        computed = set()
        for what, item in self.order:
            computed |= set(item.unknowns) if what == "system" else \
                {item.unknown if what in ("solve", "newton") else item[0]}
        for what, item in self.order:
            if what != "solve" or item.system.pieces is None:
                continue
            equation = item.equation
            reads = self.compiler.reads(equation.rhs) | self.compiler.reads(equation.lhs)
            if reads & (computed | set(self.evolved) | {"t"}) - {item.unknown}:
                continue
            item.system.solve_check(item.rhs(self.base))

    def kernel_lines(self) -> list[str]:
        """One log line per solve whose singular system had its kernel handled."""
        lines = []
        for name, report in self.solve_reports().items():
            lines.append(f"{name}: the system is singular (constants on each of {report.pieces} piece(s)); the mean "
                         f"of {name} is fixed to 0 and the right side's mean {report.mean:.6g} (a part {report.removed:.2g} of "
                         "it, relative) was subtracted")
        return lines

    def metric_values(self, env: dict) -> dict[str, float]:
        return metric_values(self, env)  # one by one: a failing metric is nan and reported, the run kept

    def solve_reports(self) -> dict[str, Any]:
        """Per solve: the pieces whose kernel was handled and the largest part of b removed."""
        out = {}
        for what, item in self.order:
            if what == "solve" and item.system.pieces is not None:
                out[item.unknown] = item.system.report
        return out

    def resolved(self) -> list[str]:
        """The equations as resolved: each with the kinds of its target (for the provenance)."""
        lines = []
        for equation in self.equations:
            target = equation.target
            if equation.kind == "system":
                unknowns = ", ".join(f"{name} : {self.kinds[name]}" for name in equation.targets)
                lines.append(f"system {unknowns} := {equation.text.strip()}")
                continue
            lines.append(f"{equation.kind} {target} : {self.kinds[target]} := {equation.text.strip()}")
        return lines


def compile_model(spec: ModelSpec, dec, new_solver: Callable, chained: dict | None = None) -> CompiledModel:
    """The :class:`CompiledModel` of ``spec`` on ``dec``'s mesh (see the module docstring);
    ``new_solver()`` gives a fresh solver for each linear system; ``chained`` is a previous run's
    field (``mesh=result mesh.field=…``) for ``initial: result:<field>``.

    The passes (:mod:`decrun.methods.model.passes`), in order: parse (:func:`_parse_equations`,
    :func:`_parse_metrics`) → resolve names and unknowns (:func:`_resolve`,
    :func:`_check_known_names`) → order (:func:`_order`) → infer kinds (:func:`_type_definitions`,
    then the typed trees :func:`_type_trees`) → bind values to the mesh (:func:`_bind_values`,
    :func:`_dirichlet`) → lower every equation into closures and linear blocks
    (:func:`_lower_equations`) → metrics (:func:`_compile_metrics`) → check stars."""
    key = spec.key
    load_plugins()
    ops = Discrete(dec)
    _check_names(spec)
    kinds = _declared_kinds(spec, ops.n)
    resolved = _resolve(spec, borders.rewrite(spec, _parse_equations(spec), kinds, ops.n, ops))
    _check_known_names(spec, resolved, borders.internal_names(spec))
    metrics = _parse_metrics(spec)
    inputs = [name for name in spec.fields if name not in resolved.targets]
    _check_initial_values(spec, resolved.evolved, inputs)
    ordered = _order(resolved.definitions, resolved.solves, set(spec.fields) | set(spec.constants), key)
    compiler = _type_definitions(spec, ops, kinds, resolved, ordered)
    typed = _type_trees(compiler, resolved.equations, metrics)
    base, initial_values = _bind_values(spec, ops, kinds, resolved.evolved, inputs, chained)
    fixed = _dirichlet(spec, kinds, dec, key)
    bound = borders.bind(spec, ops, base, resolved)
    compiler.static_env = dict(base)
    model = CompiledModel(spec, ops, compiler, kinds, resolved.equations, resolved.evolved, inputs, [], {}, {}, fixed,
                          base, initial_values, typed)
    check_finite_numbers(compiler, resolved.equations, key)
    trees = _lower_equations(model, ordered, new_solver)
    borders.finish(model, bound)
    trees += _compile_metrics(model, metrics)
    check_intrinsic(compiler, dec, trees)
    _check_stars(compiler, dec, trees)
    return model
