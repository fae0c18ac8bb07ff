"""A model's equations compiled against one mesh: the plan every step runs.

:func:`compile_model` takes the model as plain data (:class:`ModelSpec`: fields with their form,
initial and border values, constants, equations, metrics) and a :class:`decrun.core.dec.DEC`,
and returns a :class:`CompiledModel`:

1. every equation is parsed (:mod:`~decrun.methods.model.language`) and classified — evolution
   ``dt(u) = …``, definition ``v = …``, solve ``solve(lhs = rhs)`` whose unknown is the one
   declared field of its left side that nothing else computes, system ``solve(l1 = r1, l2 = r2,
   …)`` with as many unknowns as equations (one block matrix, :func:`_compile_system`);
2. definitions and solves are ordered by what they read (a cycle is refused, naming it) and
   typed in that order; every term is type-checked (:class:`~decrun.methods.model.compiler.Compiler`);
3. each solve's left side is split into a constant sparse matrix (factorized once) and terms
   moved to the right; each evolution's right side into its linear blocks and the rest (for
   the integrators, :mod:`~decrun.methods.model.integrators`).

Evaluating the model at a state (:meth:`CompiledModel.environment`) computes every definition
and solve once, in order, into one dict of values that the equations and metrics read.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.compiler import Compiler
from decrun.methods.model.finite import check_finite_numbers
from decrun.methods.model.initial import sample
from decrun.methods.model.intrinsic import check_intrinsic
from decrun.methods.model.kinds import NUMBER, Kind, form_kind
from decrun.methods.model.language import (
    Binary,
    Equation,
    ModelError,
    Name,
    Node,
    names_in,
    parse_equation,
    parse_expression,
    to_text,
)
from decrun.methods.model.lowering import Evolution
from decrun.methods.model.metrics import metric_values
from decrun.methods.model.names import check_lookalike_names, check_metric_names
from decrun.methods.model.nonlinear import compile_nonlinear_solve
from decrun.methods.model.operators import OPERATORS, Discrete, Linear, load_plugins
from decrun.methods.model.problem import ModelProblem
from decrun.methods.model.sides import refuse_unknown_on_right
from decrun.methods.model.solve import BlockSystem, IncompatibleRightHandSide, LinearSystem, constant_kernel

__all__ = ["FieldSpec", "ModelSpec", "CompiledModel", "compile_model", "border_simplices", "vertex_pieces"]

#: the built-in names and words of the language (the operators' names, plugins' included, too: :func:`reserved`)
RESERVED = {"x", "y", "z", "t", "dt", "h", "pi", "random", "solve"}
#: metric names the run itself reports (decrun.methods.model.metrics and the runner's status columns)
RESERVED_METRICS = {"status", "error", "stable", "unstable_reason", "diverged_at_step", "steps_done", "solve_seconds",
                    "steps_per_second", "step_seconds_max", "resumed_from_step", "t_final", "dt", "integrator",
                    "dt_stability_limit", "dt_over_stability_limit", "accepted_steps", "rhs_evaluations",
                    "headline_metrics", "factorizations", "total_seconds", "n_vertices", "n_faces", "warnings"}


@dataclass
class FieldSpec:
    """One field: ``form`` (``0..3`` or ``dual0..dual3``), ``initial`` (number, expression,
    list of expressions, ``result:<field>`` or None) and ``dirichlet`` (its values on the border
    simplices, None: natural)."""

    form: Any = 0
    initial: Any = None
    dirichlet: Any = None


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


def vertex_pieces(K) -> np.ndarray:
    """(n0,) label of the connected piece of each vertex (unused vertices: their own label)."""
    count, labels = K.connected_components()
    out = np.full(K.num_simplices(0), -1, dtype=np.int64)
    top = K.simplices(K.dim)
    out[top.ravel()] = np.repeat(labels, K.dim + 1)
    lonely = out < 0
    out[lonely] = count + np.arange(int(lonely.sum()))
    return out


def border_simplices(K, k: int) -> np.ndarray:
    """(b,) indices of the k-simplices (k < n) on the border: the faces of border (n−1)-simplices."""
    from itertools import combinations

    n = K.dim
    border = K.border_faces()[0]
    if k >= n or border.size == 0:
        return np.zeros(0, dtype=np.int64)
    facets = K.simplices(n - 1)[border]
    if k == n - 1:
        return np.sort(border)
    tuples = np.concatenate([facets[:, list(c)] for c in combinations(range(n), k + 1)])
    return np.unique(K.find_simplices(np.unique(tuples, axis=0)))


@dataclass
class Solve:
    """A compiled ``solve(lhs = rhs)``: the unknown's system and the weak right-hand side."""

    equation: Equation
    unknown: str
    system: LinearSystem
    rhs: Callable[[dict], np.ndarray]  # the weak right-hand side ⋆_inv (rhs − other lhs terms)
    fixed_values: np.ndarray | None


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

    @property
    def is_static(self) -> bool:
        """True when nothing evolves: the definitions and solves run once."""
        return not self.evolved

    def environment(self, state: dict[str, np.ndarray], t: float) -> dict[str, Any]:
        """Every value at ``state`` (the evolved fields) and time ``t``: built-ins, constants,
        inputs, the state, then each definition and solve in order."""
        env = dict(self.base)
        env.update(state)
        env["t"] = float(t)
        for what, item in self.order:
            if what == "definition":
                name, closure = item
                env[name] = closure(env)
            elif what == "system":
                env.update(item.solve(env))
            elif what == "newton":
                env[item.unknown] = item.solve(env)
            else:
                env[item.unknown] = item.system.solve(item.rhs(env), item.fixed_values)
        return env

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


def _kind_of_field(name: str, spec: FieldSpec, key: str, n: int) -> Kind:
    return form_kind(spec.form, f"{key}.fields.{name}.form", n)


@dataclass
class Resolved:
    """What the resolve pass finds: the evolved fields in order, the definitions by target, the
    solves and systems (their unknowns resolved) and which equation computes each name."""

    equations: list[Equation]
    evolved: list[str]
    definitions: dict[str, Equation]
    solves: list[Equation]
    targets: dict[str, str]


def compile_model(spec: ModelSpec, dec, new_solver: Callable, chained: dict | None = None) -> CompiledModel:
    """The :class:`CompiledModel` of ``spec`` on ``dec``'s mesh (see the module docstring);
    ``new_solver()`` gives a fresh solver for each linear system; ``chained`` is a previous run's
    field (``mesh=result mesh.field=…``) for ``initial: result:<field>``.

    The passes, in order: parse (:func:`_parse_equations`) → resolve names and unknowns
    (:func:`_resolve`) → order (:func:`_order`) → infer kinds (:func:`_type_definitions`) →
    bind values to the mesh (:func:`_bind_values`, :func:`_dirichlet`) → lower every equation
    into closures and linear blocks (:func:`_lower_equations`) → metrics → check stars."""
    key = spec.key
    load_plugins()
    ops = Discrete(dec)
    _check_names(spec)
    kinds = _declared_kinds(spec, ops.n)
    resolved = _resolve(spec, _parse_equations(spec))
    inputs = [name for name in spec.fields if name not in resolved.targets]
    _check_initial_values(spec, resolved.evolved, inputs)
    ordered = _order(resolved.definitions, resolved.solves, set(spec.fields) | set(spec.constants), key)
    compiler = _type_definitions(spec, ops, kinds, resolved, ordered)
    base, initial_values = _bind_values(spec, ops, kinds, resolved.evolved, inputs, chained)
    fixed = _dirichlet(spec, kinds, dec, key)
    compiler.static_env = dict(base)
    model = CompiledModel(spec, ops, compiler, kinds, resolved.equations, resolved.evolved, inputs, [], {}, {}, fixed,
                          base, initial_values)
    check_finite_numbers(compiler, resolved.equations, key)
    trees = _lower_equations(model, ordered, new_solver)
    trees += _compile_metrics(model)
    check_intrinsic(compiler, dec, trees)
    _check_stars(compiler, dec, trees)
    return model


def _declared_kinds(spec: ModelSpec, n: int) -> dict[str, Kind]:
    """The kinds of the declared fields (their ``form``) and of the constants (numbers)."""
    kinds = {name: _kind_of_field(name, field_spec, spec.key, n) for name, field_spec in spec.fields.items()}
    for name, value in spec.constants.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
            raise ModelError(f"{spec.key}.constants.{name}: must be a finite number, got {value!r}")
        kinds[name] = NUMBER
    return kinds


def _parse_equations(spec: ModelSpec) -> list[Equation]:
    """The parse pass: every equation string → :class:`Equation` (its key named in errors)."""
    key = spec.key
    wheres = spec.equation_keys or [f"{key}.equations[{i}]" for i in range(len(spec.equations))]
    equations = [parse_equation(text, where) for text, where in zip(spec.equations, wheres, strict=True)]
    if not equations:
        raise ModelError(f"{key}.equations: a model needs at least one equation, e.g. "
                         f"'{key}.equations=[\"dt(u) = laplacian(u)\"]'")
    return equations


def _resolve(spec: ModelSpec, equations: list[Equation]) -> Resolved:
    """The resolve pass: which field each equation computes — evolutions and definitions name
    theirs, a solve's unknown is the one declared field of its left side that nothing else
    computes, a system's are as many as its equations — each name computed once."""
    key = spec.key
    resolved = Resolved(list(equations), [], {}, [], {})
    targets = resolved.targets

    def claim(target: str, where: str):
        if target in reserved():
            raise ModelError(f"{where}: {target!r} is a built-in name; choose another name for the field")
        if target in spec.constants:
            raise ModelError(f"{where}: {target!r} is a constant (app.constants.{target}); an equation cannot set it")
        if target in targets:
            raise ModelError(f"{where}: {target!r} is already computed by {targets[target]}; a field has one equation")
        targets[target] = where

    for equation in equations:
        if equation.kind == "evolution":
            if equation.target not in spec.fields:
                raise ModelError(f"{equation.where}: dt({equation.target}) evolves a field that is not declared; add "
                                 f"{key}.fields.{equation.target} with its form and initial value")
            claim(equation.target, equation.where)
            resolved.evolved.append(equation.target)
        elif equation.kind == "definition":
            claim(equation.target, equation.where)
            resolved.definitions[equation.target] = equation
    for index, equation in enumerate(equations):
        if equation.kind == "system":
            equation = _system_unknowns(equation, spec, targets, resolved.evolved)
        elif equation.kind == "solve":
            equation = _solve_unknown(equation, spec, targets, resolved.evolved)
        else:
            continue
        resolved.equations[index] = equation
        for name in equation.targets or (equation.target,):
            claim(name, equation.where)
        resolved.solves.append(equation)
    return resolved


def _solve_unknown(equation: Equation, spec: ModelSpec, targets: dict, evolved: list) -> Equation:
    """The unknown of ``solve(lhs = rhs)``: the declared field of its left side that no other
    equation computes (the one without an initial value when there are several)."""
    key = spec.key
    candidates = sorted(name for name in names_in(equation.lhs)
                        if name in spec.fields and name not in targets and name not in evolved)
    if not candidates:
        raise ModelError(f"{equation.where}: the solve has no unknown: its left side {to_text(equation.lhs)} reads "
                         f"no declared field that another equation does not compute; declare the unknown under "
                         f"{key}.fields (e.g. {key}.fields.phi.form=0)")
    if len(candidates) > 1:
        without = [name for name in candidates if spec.fields[name].initial is None]
        if len(without) != 1:
            raise ModelError(f"{equation.where}: the solve's left side reads several undetermined fields "
                             f"{candidates}; a solve has one unknown")
        candidates = without
    return Equation("solve", candidates[0], equation.lhs, equation.rhs, equation.where, equation.text)


def _check_initial_values(spec: ModelSpec, evolved: list[str], inputs: list[str]) -> None:
    """Every evolved field and every input (a field nothing computes) has an initial value."""
    key = spec.key
    for name in evolved + inputs:
        if spec.fields[name].initial is None:
            role = "dt(" + name + ") needs it" if name in evolved else "no equation computes it"
            raise ModelError(f"{key}.fields.{name}.initial: missing initial value ({role}); e.g. "
                             f"`{key}.fields.{name}.initial=0`")


def _type_definitions(spec: ModelSpec, ops: Discrete, kinds: dict[str, Kind], resolved: Resolved,
                      ordered: list[Equation]) -> Compiler:
    """The kind pass: the :class:`Compiler` of the model, every definition typed in dependency
    order (a declared field's form must agree), and the names whose values vary in a run."""
    key, n = spec.key, ops.n
    varying = set(resolved.evolved) | {"t"}
    inlinable = {name: eq.rhs for name, eq in resolved.definitions.items()}
    solved = {target: _sides(eq) for eq in resolved.solves for target in eq.targets or (eq.target,)}
    compiler = Compiler(ops, kinds, inlinable, varying, solved)
    for equation in ordered:  # type every definition in order (solve unknowns are declared)
        if equation.kind == "definition":
            kinds[equation.target] = compiler.kind(equation.rhs, equation.where)
            if equation.target in spec.fields:
                declared = _kind_of_field(equation.target, spec.fields[equation.target], key, n)
                if declared != kinds[equation.target]:
                    raise ModelError(f"{equation.where}: {to_text(equation.rhs)} is a {kinds[equation.target]} but "
                                     f"{equation.target} is declared a {declared} ({key}.fields.{equation.target}.form)")
        compiler.kinds.update(kinds)
    compiler.kinds.update(kinds)
    compiler.varying |= {name for name in resolved.targets if compiler.reads(Name(name)) & compiler.varying} | \
        {target for eq in resolved.solves for target in eq.targets or (eq.target,)
         if compiler.reads(Name(target)) & compiler.varying}
    return compiler


def _bind_values(spec: ModelSpec, ops: Discrete, kinds: dict[str, Kind], evolved: list[str], inputs: list[str],
                 chained: dict | None) -> tuple[dict, dict]:
    """The bind pass: the built-in names' values on the mesh (coordinates, h, π, t, dt), the
    constants and the inputs — ``base``, what every evaluation starts from — and the sampled
    initial values of the evolved fields and inputs."""
    dec, K = ops.dec, ops.K
    base = {"x": K.vertices[:, 0].copy(), "y": K.vertices[:, 1].copy() if K.embedding_dim > 1 else
            np.zeros(K.num_simplices(0)), "z": K.vertices[:, 2].copy() if K.embedding_dim > 2 else
            np.zeros(K.num_simplices(0)), "h": ops.mean_edge_length(), "pi": float(np.pi), "t": 0.0,
            "area": float(K.top_volumes.sum()),  # a field or constant named area takes its place
            "dt": float(spec.dt)}
    base.update({name: float(value) for name, value in spec.constants.items()})
    initial_values = {}
    for name in evolved + inputs:
        initial_values[name] = sample(spec.fields[name].initial, kinds[name], dec, f"{spec.key}.fields.{name}.initial",
                                      constants=spec.constants, seed=spec.seed, name=name, chained=chained)
    base.update({name: initial_values[name] for name in inputs})
    return base, initial_values


def _lower_equations(model: CompiledModel, ordered: list[Equation], new_solver: Callable) -> list[tuple[str, Node]]:
    """The lowering pass: definitions into closures, solves and systems into factorized linear
    systems, evolutions' right sides into closures (their kinds checked against the fields).
    Returns every tree of the equations with its key (for :func:`_check_stars`)."""
    compiler, kinds, equations = model.compiler, model.kinds, model.equations
    for equation in ordered:
        refuse_unknown_on_right(equation, compiler)
        if equation.kind == "definition":
            model.order.append(("definition", (equation.target, compiler.compile(equation.rhs, equation.where))))
        elif equation.kind == "system":
            model.order.append(("system", _compile_system(equation, model, new_solver)))
        elif _nonlinear(equation, model):
            model.order.append(("newton", compile_nonlinear_solve(equation, model, new_solver)))
        else:
            model.order.append(("solve", _compile_solve(equation, model, new_solver)))
    for equation in equations:
        if equation.kind != "evolution":
            continue
        kind = compiler.kind(equation.rhs, equation.where)
        target_kind = kinds[equation.target]
        if kind != target_kind and kind != NUMBER:
            raise ModelError(f"{equation.where}: {to_text(equation.rhs)} is a {kind} but dt({equation.target}) is a "
                             f"{target_kind}")
        model.rhs[equation.target] = compiler.compile(equation.rhs, equation.where)
    trees: list[tuple[str, Node]] = [(eq.where, eq.rhs) for eq in equations]
    trees += [(eq.where, eq.lhs) for eq in equations if eq.kind == "solve" and eq.lhs is not None]
    trees += [(eq.where, side) for eq in equations if eq.kind == "system" for pair in eq.pairs for side in pair]
    return trees


def _nonlinear(equation: Equation, model: CompiledModel) -> bool:
    """True when a solve's left side is not a constant sparse matrix times its unknown plus terms
    without it: Newton's method solves it (:mod:`decrun.methods.model.nonlinear`)."""
    compiler, unknown, lhs = model.compiler, equation.target, equation.lhs
    assert lhs is not None  # a solve has a left side
    if compiler.kind(lhs, equation.where) != model.kinds[unknown]:
        return False  # refused by _compile_solve, naming both kinds
    blocks, rest = compiler.split(lhs, {unknown})
    return unknown not in blocks or any(compiler.depends_on(term, {unknown}) for _sign, term in rest)


def _compile_metrics(model: CompiledModel) -> list[tuple[str, Node]]:
    """Every declared metric parsed, checked to be a number and compiled; returns their trees."""
    trees = []
    for name, text in model.spec.metrics.items():
        where = f"{model.spec.key}.metrics.{name}"
        tree = parse_expression(text, where)
        kind = model.compiler.kind(tree, where)
        if kind != NUMBER:
            raise ModelError(f"{where}: {to_text(tree)} is a {kind}; a metric is a number: e.g. integral(...), "
                             "norm(...), max(...) or inner(..., ...)")
        model.metrics[name] = model.compiler.compile(tree, where)
        trees.append((where, tree))
    return trees


def _check_stars(compiler: Compiler, dec, trees) -> None:
    """Every ⋆_k the model reads exists for the configured variant (before any work)."""
    degrees = dec.star_variant.form_degrees
    if degrees is None:
        return
    if hasattr(dec.star_variant, "calculus"):  # ⋆1 of its intrinsic triangulation (check_intrinsic)
        degrees = (*degrees, 1)
    for where, tree in trees:
        for k, term in compiler.star_degrees(tree, where).items():
            if k not in degrees:
                raise ModelError(f"{where}: {to_text(term)} needs ⋆_{k}, but operator={dec.star_variant.name} provides "
                                 f"⋆ on {list(degrees)}-forms only; use `operator=mixed_area` (or leave that term out)")


def reserved() -> set[str]:
    """The names a field, constant or definition may not take: :data:`RESERVED` and every
    operator's name (the built-in ones and those of installed plugins)."""
    return RESERVED | set(OPERATORS)


def _check_names(spec: ModelSpec) -> None:
    key = spec.key
    for group, names in (("fields", spec.fields), ("constants", spec.constants), ("metrics", spec.metrics)):
        for name in names:
            if not isinstance(name, str) or not name.isidentifier() or name.startswith("_"):
                raise ModelError(f"{key}.{group}.{name}: a name is a letter followed by letters, digits or '_'")
            if group == "metrics" and name in RESERVED_METRICS:
                raise ModelError(f"{key}.metrics.{name}: {name!r} is a metric every model run reports (or a column of "
                                 f"the sweep table); name yours otherwise, e.g. {name}_value")
            if group != "metrics" and name in reserved():
                raise ModelError(f"{key}.{group}.{name}: {name!r} is a built-in name of the model language "
                                 "(x y z t dt h pi random and the operators); choose another")
    check_lookalike_names(key, {"fields": spec.fields, "constants": spec.constants})
    check_metric_names(key, spec.metrics, spec.fields)
    both = set(spec.fields) & set(spec.constants)
    if both:
        name = sorted(both)[0]
        raise ModelError(f"{key}.constants.{name}: {name!r} is also a field ({key}.fields.{name}); rename one")


def _order(definitions: dict[str, Equation], solves: list[Equation], known: set[str], key: str) -> list[Equation]:
    """Definitions and solves in an order where each reads only what comes before it (or
    fields, constants and built-ins); a cycle is a ModelError naming it."""
    computed = {**definitions, **{target: eq for eq in solves for target in eq.targets or (eq.target,)}}

    def needs(equation: Equation) -> set[str]:
        if equation.kind == "system":  # a system reads its own unknowns
            return {name for name in names_in(_sides(equation)) if name in computed and name not in equation.targets}
        reads = names_in(equation.rhs) | (names_in(equation.lhs) if equation.kind == "solve" else set())
        # a solve reads its own unknown; a definition that reads itself is a cycle of one
        return {name for name in reads if name in computed and (name != equation.target or equation.kind != "solve")}

    order, state = [], {}

    def visit(name: str, path: list[str]):
        if state.get(name) == "done":
            return
        if state.get(name) == "active":
            cycle = path[path.index(name):] + [name]
            raise ModelError(f"{key}.equations: the equations for {' → '.join(cycle)} form a cycle; a definition may "
                             "read only what is computed before it (break the cycle with an evolved field or a solve)")
        state[name] = "active"
        for other in sorted(needs(computed[name])):
            visit(other, path + [name])
        state[name] = "done"
        if computed[name] not in order:  # a system is computed once for all its unknowns
            order.append(computed[name])

    for name in computed:  # in the order they were written, dependencies first
        visit(name, [])
    return order


def _dirichlet(spec: ModelSpec, kinds: dict[str, Kind], dec, key: str) -> dict:
    fixed = {}
    K = dec.K
    for name, field_spec in spec.fields.items():
        if field_spec.dirichlet is None:
            continue
        where = f"{key}.fields.{name}.dirichlet"
        kind = kinds[name]
        if kind.dual or kind.degree >= K.dim:
            raise ModelError(f"{where}: border values fix primal forms of degree < {K.dim} on the border simplices; "
                             f"{name} is a {kind}")
        border = border_simplices(K, kind.degree)
        if border.size == 0:
            raise ModelError(f"{where}: this mesh has no border (a closed surface); drop the condition with "
                             f"`{key}.fields.{name}.dirichlet=null`")
        text = field_spec.dirichlet
        if isinstance(text, str) and "t" in names_in(parse_expression(text, where)):
            raise ModelError(f"{where}: border values are fixed in time here; write them without t")
        values = sample(text, kind, dec, where, constants=spec.constants, seed=spec.seed, name=name)
        fixed[name] = (border, values[border])
    return fixed


def _compile_solve(equation: Equation, model: CompiledModel, new_solver: Callable) -> Solve:
    compiler, ops, K = model.compiler, model.ops, model.ops.K
    unknown, where = equation.target, equation.where
    kind = model.kinds[unknown]
    lhs_kind = compiler.kind(equation.lhs, where)
    rhs_kind = compiler.kind(equation.rhs, where)
    if lhs_kind != kind:
        raise ModelError(f"{where}: the left side {to_text(equation.lhs)} is a {lhs_kind} but the unknown {unknown} is "
                         f"a {kind}")
    if rhs_kind != kind and rhs_kind != NUMBER:
        raise ModelError(f"{where}: {to_text(equation.lhs)} is a {lhs_kind} but {to_text(equation.rhs)} is a "
                         f"{rhs_kind}")
    blocks, rest = compiler.split(equation.lhs, {unknown})
    if unknown not in blocks:
        raise ModelError(f"{where}: the left side {to_text(equation.lhs)} is not linear in {unknown} with constant "
                         "coefficients (a solve is linear); move nonlinear terms to an evolution equation")
    for _sign, term in rest:
        if compiler.depends_on(term, {unknown}):
            raise ModelError(f"{where}: the term {to_text(term)} of the left side is not linear in {unknown}; a solve "
                             "is linear in its unknown")
    linear: Linear = blocks[unknown]
    rhs_closure = compiler.compile(equation.rhs, where)
    rest_closures = [(sign, compiler.compile(term, where)) for sign, term in rest]
    star = ops.dec.star(linear.inv) if linear.inv is not None else None
    size = kind.size(K)

    def weak_rhs(env):
        value = rhs_closure(env)
        for sign, closure in rest_closures:
            value = value - sign * closure(env)
        value = np.broadcast_to(np.asarray(value, dtype=np.float64), (size,))
        return star @ value if star is not None else np.array(value)

    border, values = model.fixed.get(unknown, (np.zeros(0, dtype=np.int64), None))
    pieces = mass = None
    if not border.size and not kind.dual and kind.degree == 0:
        labels = vertex_pieces(K)
        if constant_kernel(linear.A, labels):
            pieces = labels
            mass = np.asarray(ops.dec.star(0).sum(axis=1)).ravel()
    elif not border.size and kind.degree >= 1 and not kind.dual and _pure_laplacian(equation.lhs):
        betti = K.betti_numbers()[kind.degree]
        if betti:
            raise ModelError(f"{where}: {to_text(equation.lhs)} = … is singular on this mesh: the harmonic "
                             f"{kind.degree}-forms (Betti_{kind.degree} = {betti}) are its kernel; add a term such as "
                             f"'{unknown} - t0*laplacian({unknown})' or fix border values")
    try:
        system = LinearSystem(linear.A, new_solver, border, pieces, mass)
    except Exception as error:  # noqa: BLE001 - a solver refusing the matrix: say which equation
        if isinstance(error, ModelError):
            raise
        raise ModelError(f"{where}: the system of {to_text(equation.lhs)} could not be factorized "
                         f"({str(error).splitlines()[0]}); try `solver=direct`") from None
    solve = Solve(equation, unknown, system, weak_rhs, values)
    original = system.solve

    def checked(b, fixed_values):
        try:
            return original(b, fixed_values)
        except IncompatibleRightHandSide as error:
            raise ModelError(_incompatible_message(where, equation, error.relative)) from None

    def check_only(b):
        try:
            system._compatible(system.sign * np.asarray(b, dtype=np.float64))
        except IncompatibleRightHandSide as error:
            checked_error = error
        else:
            return
        raise ModelError(_incompatible_message(where, equation, checked_error.relative)) from None

    system.solve = checked
    system.solve_check = check_only
    return solve


def _sides(equation: Equation) -> Node:
    """One tree reading everything a solve or system reads (both sides of every equation):
    what its unknowns are computed from, for the dependency order."""
    pairs = equation.pairs or ((equation.lhs, equation.rhs),)
    terms = [Binary("-", lhs, rhs) for lhs, rhs in pairs]
    tree: Node = terms[0]
    for term in terms[1:]:
        tree = Binary("+", tree, term)
    return tree


def _system_unknowns(equation: Equation, spec: ModelSpec, targets: dict, evolved: list) -> Equation:
    """The unknowns of ``solve(l1 = r1, l2 = r2, …)``: the declared fields its left sides read
    that no other equation computes (those without an initial value when there are more), as
    many as equations, in their declaration order."""
    key, count = spec.key, len(equation.pairs)
    read = set().union(*(names_in(lhs) for lhs, _ in equation.pairs))
    candidates = [name for name in spec.fields if name in read and name not in targets and name not in evolved]
    if len(candidates) > count:
        without = [name for name in candidates if spec.fields[name].initial is None]
        if len(without) == count:
            candidates = without
    if len(candidates) != count:
        example = f"{key}.fields.p.form=0" if "p" not in spec.fields else f"{key}.fields.q.form=0"
        raise ModelError(f"{equation.where}: the system has {count} equations but its left sides read "
                         f"{len(candidates)} undetermined field(s) {candidates}; a system solves for one unknown per "
                         f"equation (declare each unknown without an initial value under {key}.fields, e.g. "
                         f"`+{example}`)")
    return Equation("system", candidates[0], equation.lhs, equation.rhs, equation.where, equation.text,
                    equation.pairs, tuple(candidates))


@dataclass
class SystemSolve:
    """A compiled ``solve(l1 = r1, …)``: the block system of its unknowns (one
    :class:`LinearSystem`, factorized once) and each row's weak right-hand side."""

    equation: Equation
    unknowns: tuple
    system: LinearSystem
    rows: list  # per equation: env ↦ its weak right-hand side
    offsets: np.ndarray  # (m + 1,) where each unknown's values start in the stacked vector
    fixed_values: np.ndarray | None

    def solve(self, env: dict) -> dict[str, np.ndarray]:
        """Every unknown's values at ``env`` (one solve of the block system)."""
        x = self.system.solve(np.concatenate([row(env) for row in self.rows]), self.fixed_values)
        return {name: x[self.offsets[i]:self.offsets[i + 1]] for i, name in enumerate(self.unknowns)}


def _system_row_kinds(equation: Equation, compiler: Compiler, unknowns, kinds: list[Kind]) -> list[Kind]:
    """The kind of each equation of a system (its left side's; the right side a number or the
    same kind), refused unless they are the unknowns' kinds, as a multiset (a square system)."""
    where = equation.where
    row_kinds = []
    for lhs, rhs in equation.pairs:
        lhs_kind, rhs_kind = compiler.kind(lhs, where), compiler.kind(rhs, where)
        if rhs_kind != lhs_kind and rhs_kind != NUMBER:
            raise ModelError(f"{where}: {to_text(lhs)} is a {lhs_kind} but {to_text(rhs)} is a {rhs_kind}")
        row_kinds.append(lhs_kind)
    if sorted(map(str, row_kinds)) != sorted(map(str, kinds)):
        given = ", ".join(f"{to_text(lhs)} : {kind}" for (lhs, _), kind in zip(equation.pairs, row_kinds, strict=True))
        wanted = ", ".join(f"{name} : {kind}" for name, kind in zip(unknowns, kinds, strict=True))
        missing = list((Counter(map(str, kinds)) - Counter(map(str, row_kinds))).elements())
        raise ModelError(f"{where}: the system's equations ({given}) do not match its unknowns ({wanted}): each unknown "
                         f"needs one equation of its kind, and one more left side should be a {missing[0]}; "
                         "write that equation in its unknown's kind (e.g. d(u) = f for a top-form pressure)")
    return row_kinds


def _compile_system(equation: Equation, model: CompiledModel, new_solver: Callable) -> SystemSolve:
    """The block system of ``solve(l1 = r1, …, lm = rm)`` in its m unknowns u_1 … u_m.

    Row i is equation i in weak form: its left side split into Σ_j ⋆_k⁻¹ A_ij u_j (+ terms that
    read no unknown, moved to the right), multiplied by the row's one ⋆_k (``u - codifferential(p)``
    is ⋆_{n−1}⁻¹(⋆_{n−1} u − d_{n−1}ᵀ ⋆_n p): the row ⋆_{n−1} u − d_{n−1}ᵀ ⋆_n p = ⋆_{n−1} r), so a
    Galerkin ⋆ is never inverted. Row i must have the kind of one unknown: the left sides' kinds
    and the unknowns' kinds are the same multiset, so that the block matrix [A_ij] is square
    (Σ sizes of the rows = Σ sizes of the unknowns). The matrix is assembled once (``sp.bmat``)
    and factorized once; it is in general indefinite (a saddle point has a zero block), so a
    solver that needs SPD matrices is refused."""
    compiler, ops, K = model.compiler, model.ops, model.ops.K
    where, unknowns = equation.where, equation.targets
    kinds = [model.kinds[name] for name in unknowns]
    row_kinds = _system_row_kinds(equation, compiler, unknowns, kinds)
    sizes = [kind.size(K) for kind in kinds]
    offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    grid, rows = [], []
    for (lhs, rhs), row_kind in zip(equation.pairs, row_kinds, strict=True):
        if compiler.depends_on(rhs, set(unknowns)):
            read = sorted(compiler.reads(rhs) & set(unknowns))
            raise ModelError(f"{where}: the right side {to_text(rhs)} reads the unknown {read[0]}; move the terms of "
                             "the unknowns to the left side")
        blocks, rest = compiler.split(lhs, set(unknowns))
        for _sign, term in rest:
            if compiler.depends_on(term, set(unknowns)):
                raise ModelError(f"{where}: the term {to_text(term)} of {to_text(lhs)} is not linear in the unknowns "
                                 f"{', '.join(unknowns)} with constant coefficients (a system is linear)")
        if not blocks:
            raise ModelError(f"{where}: the left side {to_text(lhs)} reads none of the unknowns {', '.join(unknowns)} "
                             "linearly; every equation of a system is linear in its unknowns")
        stars = sorted({block.inv for block in blocks.values() if block.inv is not None})
        if len(stars) > 1:
            raise ModelError(f"{where}: the terms of {to_text(lhs)} carry different inverse stars "
                             f"(⋆_{stars[0]}⁻¹ and ⋆_{stars[1]}⁻¹): no one weak form; write the equation over one ⋆")
        star = ops.dec.star(stars[0]) if stars else None
        line: list = []
        for name in unknowns:
            block = blocks.get(name)
            if block is None:
                line.append(None)
            elif block.inv is None and star is not None:
                line.append(sp.csr_matrix(star @ block.A))
            else:
                line.append(block.A)
        grid.append(line)
        rows.append(_weak_row(compiler, rhs, rest, star, stars[0] if stars else None, row_kind.size(K), where))
    for j, name in enumerate(unknowns):
        if all(line[j] is None for line in grid):
            raise ModelError(f"{where}: no equation of the system reads {name} linearly; it cannot be solved for")
    # rows in the order of the unknowns whose kind they have (a square block matrix with its
    # diagonal blocks on the unknowns)
    order, free = [], list(range(len(grid)))
    for kind in kinds:
        match = next(i for i in free if str(row_kinds[i]) == str(kind))
        free.remove(match)
        order.append(match)
    grid = [grid[i] for i in order]
    rows = [rows[i] for i in order]
    for i, line in enumerate(grid):  # bmat needs each row's height: an all-None row cannot occur
        for j, block in enumerate(line):
            if block is not None and block.shape != (sizes[i], sizes[j]):
                raise ModelError(f"{where}: block ({i}, {j}) of the system has shape {block.shape}, expected "
                                 f"{(sizes[i], sizes[j])}")
    matrix = sp.bmat(grid, format="csr")
    fixed, values = [], []
    for j, name in enumerate(unknowns):
        if name in model.fixed:
            border, fixed_values = model.fixed[name]
            fixed.append(border + offsets[j])
            values.append(fixed_values)
    fixed_index = np.concatenate(fixed).astype(np.int64) if fixed else np.zeros(0, dtype=np.int64)
    system = BlockSystem(matrix, new_solver, fixed_index, where=where, unknowns=tuple(unknowns))
    _refuse_constant_kernel(system, unknowns, kinds, offsets, K, where,
                            [f"{model.spec.key}.fields.{name}.dirichlet" for name in unknowns if name in model.fixed])
    return SystemSolve(equation, tuple(unknowns), system, rows, offsets,
                       np.concatenate(values) if values else None)


def _refuse_constant_kernel(system: BlockSystem, unknowns, kinds, offsets, K, where: str, fixed: list) -> None:
    """Before any work: an unknown determined only up to a constant — the block matrix (its free
    rows and columns) maps the constant of one unknown to zero, e.g. a pressure when every border
    flux is fixed (``fields.u.dirichlet``) and no border value enters — is refused; a factorization
    of a singular matrix would give a quiet wrong answer. The constant of a 0-form or dual 0-form
    is 1 everywhere; of a top form, the integral of the density 1 over each top simplex."""
    A = system.A_full[system.free][:, system.free]
    scale = abs(A).max() if A.nnz else 0.0
    for j, (name, kind) in enumerate(zip(unknowns, kinds, strict=True)):
        if kind.is_form and kind.degree == K.dim and not kind.dual:
            constant = K.top_volumes
        elif kind.is_form and kind.simplex_dimension(K.dim) in (0, K.dim):
            constant = np.ones(kind.size(K))
        else:
            continue
        full = np.zeros(system.A_full.shape[0])
        full[offsets[j]:offsets[j + 1]] = constant
        vector = full[system.free]
        if scale and np.abs(A @ vector).max() <= 1e-10 * scale * np.abs(vector).max():
            given = f"drop {' and '.join(fixed)} and " if fixed else ""
            raise ModelError(f"{where}: the block system of {', '.join(unknowns)} is singular: {name} is determined "
                             "only up to a constant (no border value fixes it, as when every border flux is given); "
                             f"{given}let border values of {name} enter the weak form (a term border(q), as in "
                             "app=darcy)")


def _weak_row(compiler: Compiler, rhs: Node, rest: list, star, degree, size: int, where: str) -> Callable:
    """env ↦ ⋆_k (rhs − the left side's terms without unknowns) of one row of a system, k =
    ``degree`` (None: no ⋆). A term linear in a form with a constant ⋆_k⁻¹ A matrix
    (``border(pb)``, ``codifferential(q)``) contributes A·value: the ⋆_k⁻¹ it carries is not
    applied only to be multiplied back (for a Galerkin ⋆, a factorization saved)."""
    terms = [(1.0, term) for term in [rhs]] + [(-sign, term) for sign, term in rest]
    split = []
    for sign, tree in terms:
        names = {name for name in compiler.reads(tree) if name not in compiler.definitions and name in compiler.kinds
                 and compiler.kinds[name].is_form}
        blocks, others = compiler.split(tree, names) if names else ({}, compiler.terms(tree))
        for name, block in blocks.items():
            if block.inv == degree and degree is not None:
                split.append(("weak", name, (sign * block.A).tocsr()))
            elif block.inv is None:
                split.append(("weak", name, (sign * (star @ block.A if star is not None else block.A)).tocsr()))
            else:
                apply = compiler.ops.matrix(block)
                split.append(("strong", name, lambda x, apply=apply, sign=sign: sign * apply(x)))
        for inner_sign, term in others:
            closure = compiler.compile(term, where)
            split.append(("value", None, (sign * inner_sign, closure)))

    def weak(env):
        strong = np.zeros(size)
        total = np.zeros(size)
        for what, name, item in split:
            if what == "weak":
                total += item @ env[name]
            elif what == "strong":
                strong += item(env[name])
            else:
                factor, closure = item
                strong += factor * np.broadcast_to(np.asarray(closure(env), dtype=np.float64), (size,))
        return total + (star @ strong if star is not None else strong)
    return weak


def _incompatible_message(where: str, equation: Equation, relative: float) -> str:
    return (f"{where}: on this mesh {to_text(equation.lhs)} is singular (constants are its kernel, no border value "
            f"fixes them) and the right side's integral is {relative:.2g} of its size, not zero: no solution exists; "
            "subtract its mean (a right side f becomes f - integral(f)/integral(1 + 0*x)) or fix border values "
            "(fields.<name>.dirichlet)")


def _pure_laplacian(node: Node) -> bool:
    """True when ``node`` is c·laplacian(u) or c·laplace_de_rham(u) alone (no shift)."""
    from decrun.methods.model.language import Call, Negate, Number

    while isinstance(node, (Negate, Binary)):
        if isinstance(node, Negate):
            node = node.operand
        elif node.op in "*/" and isinstance(node.left, Number):
            node = node.right
        elif node.op in "*/" and isinstance(node.right, Number):
            node = node.left
        else:
            return False
    return isinstance(node, Call) and node.function in ("laplacian", "laplace_de_rham", "laplace")

