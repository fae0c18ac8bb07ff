"""Border conditions of a model's 0-forms in the language: moving Dirichlet values, Neumann and
Robin borders (issue #47, item 4). The numerics are :mod:`decrun.core.boundary.conditions`
(Green's identity in DEC, ⋆0 Δu = −S u + b with b_i = ∫_{Γ_i} ∂u/∂n); this module wires them into
the compiled model.

``app.fields.<u>`` takes at most one of

- ``dirichlet: g(x, y, z, t)`` — u = g on the border vertices; with ``t`` the values move: every
  integrator steps the condensed system M_FF y' = f_F(y, t) whose border columns hold g(t) and,
  for a non-diagonal mass, − M_FD ∂g/∂t (:class:`MovingProblem`); every solve of u reads g at its
  ``t`` — a linear solve, a Newton solve and a block system (:mod:`~decrun.methods.model.moving_solves`;
  factorizations stay done once, only the fixed values change);
- ``neumann: g(x, y, z, t)`` — the outward normal derivative ∂u/∂n = g: every ``laplacian(u)``
  of the equations becomes ⋆0⁻¹(−S u + b(t)), b = ``border_load(g)`` (written into the tree as
  ``laplacian(u) + inv_star(_neumann_u)``, ``_neumann_u`` the dual n-form b);
- ``robin: {alpha: α(x, y, z, t), value: v(x, y, z, t)}`` — ∂u/∂n + α u = v: ``laplacian(u)``
  becomes ⋆0⁻¹(−(S + R) u + b(v)), R = ``robin_matrix(α)`` (``laplacian(u) - _robin_alpha_u*u +
  inv_star(_robin_value_u)``, ``_robin_alpha_u`` = diag(R)/⋆0, a constant coefficient: R joins the
  linear block of the implicit integrators and solves; α reading t and a Galerkin ⋆0:
  :mod:`decrun.methods.model.robin`).

Border expressions are value-by-value expressions of ``x y z t pi`` and ``app.constants``,
evaluated at the border quadrature points (:func:`~decrun.core.boundary.conditions.border_quadrature`)
or the border vertices; ∂g/∂t is exact (forward-mode, each function's derivative rule). Every
refusal is one line naming ``app.fields.<u>.<key>`` and the override that fixes it.
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp

from decrun.core.boundary.conditions import border_load
from decrun.methods.model import robin
from decrun.methods.model.kinds import Kind, dual, primal
from decrun.methods.model.language import (
    Binary,
    Call,
    Equation,
    ModelError,
    Name,
    Negate,
    Node,
    Number,
    names_in,
    parse_expression,
    to_text,
)
from decrun.methods.model.operators import ALIASES, OPERATORS, POINTWISE_DERIVATIVES
from decrun.methods.model.problem import ModelProblem

__all__ = ["BorderExpression", "rewrite", "moving_names", "dirichlet_at_start", "bind", "finish", "MovingProblem",
           "check_integrator", "make_integrator", "KEYS"]

#: the border condition keys of ``app.fields.<u>``, at most one per field
KEYS = ("dirichlet", "neumann", "robin")
#: the second-order operators whose border term a Neumann or Robin condition gives
_LAPLACIANS = ("laplacian", "laplace_de_rham", "codifferential")


# ---------------------------------------------------------------------- expressions of x, y, z, t
class BorderExpression:
    """A value-by-value expression of ``x y z t pi`` and constants (``where`` its config key):
    :meth:`at` its values at points and time t, :meth:`rate` ∂/∂t there (exact)."""

    def __init__(self, value, where: str, constants: dict[str, float], field: str):
        self.where, self.constants = where, {k: float(v) for k, v in constants.items()}
        if isinstance(value, bool) or not isinstance(value, (int, float, str)):
            raise ModelError(f"{where}: a border value is a number or an expression of x, y, z, t (got "
                             f"{type(value).__name__} {value!r}); e.g. `{where}=0`")
        self.tree = parse_expression(str(value), where)
        self.reads_time = False
        self._check(self.tree, field)

    def _check(self, node: Node, field: str) -> None:
        if isinstance(node, Number):
            return
        if isinstance(node, Name):
            known = ["x", "y", "z", "t", "pi", *self.constants]
            if node.name not in known:
                close = difflib.get_close_matches(node.name, known, n=1)
                hint = f"did you mean {close[0]!r}? " if close else ""
                raise ModelError(f"{self.where}: unknown name {node.name!r} in a border value ({hint}it reads x, y, z, "
                                 f"t, pi and app.constants); declare it, e.g. `+app.constants.{node.name}=1`")
            self.reads_time |= node.name == "t"
            return
        if isinstance(node, Negate):
            return self._check(node.operand, field)
        if isinstance(node, Binary) and node.op != "^":
            self._check(node.left, field)
            self._check(node.right, field)
            return
        operator = OPERATORS.get(node.function) if isinstance(node, Call) else None
        if not isinstance(node, Call) or operator is None or not operator.pointwise or \
                len(node.args) not in operator.arity:
            raise ModelError(f"{self.where}: {to_text(node)}: a border value is an expression of x, y, z, t (exp, sin, "
                             f"sqrt … of them); operators belong in app.equations, e.g. `{self.where}=0`")
        for arg in node.args:
            self._check(arg, field)

    def _env(self, points: np.ndarray, t: float) -> dict:
        points = np.asarray(points, dtype=np.float64)
        zeros = np.zeros(len(points))
        return {"x": points[:, 0], "y": points[:, 1] if points.shape[1] > 1 else zeros,
                "z": points[:, 2] if points.shape[1] > 2 else zeros, "t": float(t), "pi": np.pi, **self.constants}

    def at(self, points: np.ndarray, t: float) -> np.ndarray:
        """(N,) g at ``points`` (N, d) and time ``t``; one ModelError line where it is not finite."""
        with np.errstate(all="ignore"):
            value, _ = _evaluate(self.tree, self._env(points, t), rate=False)
        return self._finite(value, points, t)

    def rate(self, points: np.ndarray, t: float) -> np.ndarray:
        """(N,) ∂g/∂t at ``points`` and ``t`` (zeros when g does not read t)."""
        if not self.reads_time:
            return np.zeros(len(points))
        with np.errstate(all="ignore"):
            _, rate = _evaluate(self.tree, self._env(points, t), rate=True)
        return self._finite(rate, points, t, "∂/∂t of ")

    def _finite(self, value, points, t: float, what: str = "") -> np.ndarray:
        out = np.broadcast_to(np.asarray(value, dtype=np.float64), (len(points),)).copy()
        bad = ~np.isfinite(out)
        if bad.any():
            at = np.round(np.asarray(points)[int(np.flatnonzero(bad)[0])], 6).tolist()
            raise ModelError(f"{self.where}: {what}the border value {to_text(self.tree)} is not finite at "
                             f"{int(bad.sum())} border point(s) (e.g. {at}, t = {t:g}); change the expression there, e.g. "
                             f"`{self.where}=0`")
        return out


def _evaluate(node: Node, env: dict, rate: bool) -> tuple[Any, Any]:
    """(value, ∂value/∂t) of a checked border expression (the rate 0.0 when ``rate`` is False)."""
    if isinstance(node, Number):
        return node.value, 0.0
    if isinstance(node, Name):
        return env[node.name], (1.0 if node.name == "t" and rate else 0.0)
    if isinstance(node, Negate):
        value, derivative = _evaluate(node.operand, env, rate)
        return -value, -derivative
    if isinstance(node, Binary):
        (a, da), (b, db) = _evaluate(node.left, env, rate), _evaluate(node.right, env, rate)
        if node.op == "+":
            return a + b, da + db
        if node.op == "-":
            return a - b, da - db
        if node.op == "*":
            return a * b, da * b + a * db
        if node.op == "/":
            return a / b, (da * b - a * db) / b ** 2
        power = np.power(a, b)
        log_term = np.where(np.asarray(db) != 0, np.log(np.abs(a) + (np.asarray(a) == 0)), 0.0) if rate else 0.0
        return power, b * np.power(a, b - 1.0) * da + power * log_term * db
    assert isinstance(node, Call)
    parts = [_evaluate(arg, env, rate) for arg in node.args]
    evaluate = OPERATORS[node.function].evaluate
    assert evaluate is not None  # a value-by-value operator
    value = evaluate(None, [primal(0)] * len(parts), *(p[0] for p in parts))
    if not rate or not any(np.any(p[1]) for p in parts):
        return value, 0.0
    if len(parts) == 2:  # min / max: the derivative of the argument taken
        (a, da), (_, db) = parts
        taken = np.asarray(value) == np.asarray(a)
        return value, np.where(taken, da, db)
    return value, POINTWISE_DERIVATIVES[node.function](parts[0][0]) * parts[0][1]


# ---------------------------------------------------------------------- the rewrite of laplacian(u)
def _given(spec) -> dict[str, str]:
    """field → the one condition key it has among neumann / robin (refusing two conditions)."""
    out = {}
    for name, field_spec in spec.fields.items():
        given = [key for key in KEYS if getattr(field_spec, key, None) is not None]
        if len(given) > 1:
            raise ModelError(f"{spec.key}.fields.{name}: give one border condition, not {' and '.join(given)}; drop "
                             f"one, e.g. `{spec.key}.fields.{name}.{given[-1]}=null`")
        if given and given[0] != "dirichlet":
            out[name] = given[0]
    return out


def _load_name(name: str, key: str) -> str:
    return f"_{key}_{name}" if key == "neumann" else f"_robin_value_{name}"


def _coefficient_name(name: str) -> str:
    return f"_robin_alpha_{name}"  # never a load's name: `_robin_value_u` is u's load, not value_u's α


def rewrite(spec, equations: list[Equation], kinds: dict[str, Kind], n: int, ops=None) -> list[Equation]:
    """The equations with every ``laplacian(u)`` of a field u with a Neumann or Robin condition
    replaced by its border form (module docstring; a Robin term over a Galerkin ⋆0 of ``ops`` in
    the form of :mod:`decrun.methods.model.robin`); the new names' kinds added to ``kinds``.
    A condition whose field no ``laplacian(u)`` reads, or a second-order term of u written
    otherwise, is refused (one line)."""
    given = _given(spec)
    if not given:
        return equations
    galerkin = ops is not None and "robin" in given.values() and ops.diagonal(0) is None
    for name, key in given.items():
        where = f"{spec.key}.fields.{name}.{key}"
        kind = kinds[name]
        if kind != primal(0):
            raise ModelError(f"{where}: a border flux is given for primal 0-forms (values at vertices); {name} is a "
                             f"{kind}: drop it with `{where}=null`")
        kinds[_load_name(name, key)] = dual(n)
        if key == "robin":
            kinds[_coefficient_name(name)] = primal(0)
    found: set[str] = set()

    def walk(node: Node, where: str) -> Node:
        if isinstance(node, Call):
            function = ALIASES.get(node.function, node.function)
            args = node.args
            if function in _LAPLACIANS and len(args) == 1 and isinstance(args[0], Name) and args[0].name in given \
                    and function == "laplacian":
                found.add(args[0].name)
                return _border_form(node, args[0].name, given[args[0].name], galerkin)
            if function in _LAPLACIANS and len(args) == 1:
                inner = names_in(args[0]) & set(given)
                if inner:
                    u = sorted(inner)[0]
                    key = f"{spec.key}.fields.{u}.{given[u]}"
                    raise ModelError(f"{where}: {to_text(node)}: the border condition {key} enters through "
                                     f"laplacian({u}) alone; write this term with laplacian({u}) (or drop `{key}=null`)")
            return Call(node.function, tuple(walk(arg, where) for arg in args))
        if isinstance(node, Binary):
            return Binary(node.op, walk(node.left, where), walk(node.right, where))
        if isinstance(node, Negate):
            return Negate(walk(node.operand, where))
        return node

    out = []
    for equation in equations:
        def side(tree, where=equation.where):
            return None if tree is None else walk(tree, where)
        pairs = tuple((side(lhs), side(rhs)) for lhs, rhs in equation.pairs) if equation.pairs else equation.pairs
        out.append(Equation(equation.kind, equation.target, side(equation.lhs), side(equation.rhs), equation.where,
                            equation.text, pairs, equation.targets))
    for name, key in given.items():
        if name not in found:
            where = f"{spec.key}.fields.{name}.{key}"
            raise ModelError(f"{where}: no equation reads laplacian({name}), through which the border flux enters; "
                             f"write the diffusion of {name} as laplacian({name}) or drop `{where}=null`")
    return out


def _border_form(node: Call, name: str, key: str, galerkin: bool = False) -> Node:
    """laplacian(u) + inv_star(b) (Neumann) or laplacian(u) − c u + inv_star(b) (Robin; over a
    Galerkin ⋆0 laplacian(u) − inv_star(border_mass(c u)) + inv_star(b))."""
    load = Call("inv_star", (Name(_load_name(name, key)),))
    flux: Node = node
    if key == "robin":
        term: Node = Binary("*", Name(_coefficient_name(name)), Name(name))
        if galerkin:
            term = Call("inv_star", (Call("border_mass", (term,)),))
        flux = Binary("-", node, term)
    return Binary("+", flux, load)


def internal_names(spec) -> set[str]:
    """The names the rewrite of ``laplacian(u)`` introduces (bound by :func:`bind`, never the user's):
    ``_neumann_u`` for a Neumann field, ``_robin_alpha_u`` and ``_robin_value_u`` for a Robin one."""
    out = set()
    for name, key in _given(spec).items():
        out.add(_load_name(name, key))
        if key == "robin":
            out.add(_coefficient_name(name))
    return out


def internal_roles(spec) -> dict[str, tuple[str, str]]:
    """``{internal name: (field, part)}`` for the names of :func:`internal_names`: part
    ``neumann`` (the Neumann load), ``robin.value`` (the Robin load) or ``robin.alpha`` (the Robin
    coefficient) — what ``app.explain`` shows them as (:mod:`decrun.methods.model.border_labels`)."""
    out = {}
    for name, key in _given(spec).items():
        out[_load_name(name, key)] = (name, "neumann" if key == "neumann" else "robin.value")
        if key == "robin":
            out[_coefficient_name(name)] = (name, "robin.alpha")
    return out


def moving_names(spec) -> set[str]:
    """The names whose values change in a run through a border condition that reads t (never
    cached as static): the border loads, and the fields with moving Dirichlet values (a solve's
    unknown among them)."""
    out = set()
    for name, field_spec in spec.fields.items():
        text = field_spec.dirichlet
        if isinstance(text, str) and "t" in names_in(parse_expression(text, f"{spec.key}.fields.{name}.dirichlet")):
            out.add(name)
    for name, key in _given(spec).items():
        value = getattr(spec.fields[name], key)
        text = value.get("value") if key == "robin" and isinstance(value, Mapping) else value
        if isinstance(text, str) and "t" in names_in(parse_expression(text, f"{spec.key}.fields.{name}.{key}")):
            out.add(_load_name(name, key))
        alpha = value.get("alpha") if key == "robin" and isinstance(value, Mapping) else None
        if isinstance(alpha, str) and "t" in names_in(parse_expression(alpha, f"{spec.key}.fields.{name}.robin.alpha")):
            out.add(_coefficient_name(name))
    return out


# ---------------------------------------------------------------------- binding to the mesh
def _robin_parts(value, where: str) -> tuple[Any, Any]:
    if not isinstance(value, Mapping) or set(value) != {"alpha", "value"}:
        got = sorted(value) if isinstance(value, Mapping) else repr(value)
        raise ModelError(f"{where}: Robin's ∂u/∂n + α u = value takes a mapping with the keys alpha and value (got "
                         f"{got}); e.g. `{where}={{alpha: 1, value: 0}}`")
    return value["alpha"], value["value"]


def _no_border(dec, where: str) -> None:
    if dec.K.border_faces()[0].size == 0:
        raise ModelError(f"{where}: this mesh has no border (a closed surface); drop the condition with `{where}=null`")


def dirichlet_at_start(spec, name: str, kind: Kind, dec, where: str) -> np.ndarray | None:
    """The vertex values at t = 0 of a Dirichlet value that reads t, or None when it does not (the
    static sampling applies). Moving values are for primal 0-forms."""
    text = spec.fields[name].dirichlet
    if not isinstance(text, str) or "t" not in names_in(parse_expression(text, where)):
        return None
    if kind != primal(0):
        raise ModelError(f"{where}: border values that move in time (read t) are for primal 0-forms; {name} is a "
                         f"{kind}: write them without t")
    return BorderExpression(text, where, spec.constants, name).at(dec.K.vertices, 0.0)


def at_each_time(compute: Callable[[float], np.ndarray]) -> Callable[[dict], np.ndarray]:
    """``env ↦ compute(env["t"])``, each time computed once: the stages of one step read a moving
    border term a few times (the last few times are kept)."""
    values: dict[float, np.ndarray] = {}

    def at(env: dict) -> np.ndarray:
        t = float(env["t"])
        if t not in values:
            if len(values) > 8:
                values.clear()
            values[t] = compute(t)
        return values[t]
    return at


def _load_at(K, quadrature, expression: BorderExpression) -> Callable[[float], np.ndarray]:
    """t ↦ (n0,) b(t), b_i = ∫_{Γ_i} g(·, t): the load of a border value that reads t."""
    def load(t: float) -> np.ndarray:
        return border_load(K, quadrature, expression.at(quadrature.points, t))
    return load


@dataclass
class Borders:
    """What :func:`bind` made: the definitions of the moving border loads (``order`` entries,
    evaluated first in every environment) and the moving Dirichlet expressions by field."""

    order: list
    moving: dict[str, BorderExpression]


def bind(spec, ops, base: dict, resolved) -> Borders:
    """The border loads and Robin coefficients on the mesh: static ones into ``base``, moving
    ones as definitions; every condition checked (one line each, naming its key)."""
    dec, K, key = ops.dec, ops.K, spec.key
    computed = set(resolved.evolved) | {t for eq in resolved.solves for t in (eq.targets or (eq.target,))}
    order, moving = [], {}
    quadrature = None
    for name, field_spec in spec.fields.items():
        for condition in KEYS:
            value = getattr(field_spec, condition, None)
            if value is None:
                continue
            where = f"{key}.fields.{name}.{condition}"
            static = condition == "dirichlet" and not (isinstance(value, str) and "t" in names_in(parse_expression(value,
                                                                                                            where)))
            if name not in computed and not static:
                raise ModelError(f"{where}: {name} is neither evolved (dt({name}) = …) nor solved for, so a border "
                                 f"condition has nothing to act on; drop it with `{where}=null`")
            if condition == "dirichlet":
                if not static:
                    moving[name] = BorderExpression(value, where, spec.constants, name)
                continue
            _no_border(dec, where)
            quadrature = robin.quadrature(ops) if quadrature is None else quadrature
            if condition == "robin":
                alpha_text, value = _robin_parts(value, where)
                order += _robin_coefficient(spec, ops, name, alpha_text, quadrature, where, base)
            expression = BorderExpression(value, where + (".value" if condition == "robin" else ""), spec.constants,
                                          name)
            load = _load_name(name, condition)
            base[load] = border_load(K, quadrature, expression.at(quadrature.points, 0.0))
            if expression.reads_time:
                order.append(("definition", (load, at_each_time(_load_at(K, quadrature, expression)))))
    return Borders(order, moving)


def _robin_coefficient(spec, ops, name: str, alpha_text, quadrature, where: str, base: dict) -> list:
    """``_robin_u`` (:mod:`decrun.methods.model.robin`) at t = 0 into ``base``; for α reading t also
    its moving definition (returned as ``order`` entries). α(t) with a Galerkin ⋆0 is refused."""
    alpha = BorderExpression(alpha_text, where + ".alpha", spec.constants, name)
    coefficient = _coefficient_name(name)
    base[coefficient] = robin.static_coefficient(ops, quadrature, alpha, where + ".alpha")
    if not alpha.reads_time:
        return []
    if ops.diagonal(0) is None:
        raise ModelError(f"{where}.alpha: α reading t makes the Robin term a moving coefficient, whose exact Jacobian "
                         f"through the Galerkin ⋆0⁻¹ of operator={ops.dec.star_variant.name} is dense; use "
                         "`operator=circumcentric`")
    return [("definition", (coefficient, at_each_time(robin.moving_coefficient(ops, quadrature, alpha,
                                                                                where + ".alpha"))))]


def finish(model, borders: Borders) -> None:
    """After the lowering: the moving loads evaluated first in every environment, and each solve
    whose unknown has moving Dirichlet values reading them at its t — a linear solve through its
    right side, a Newton or block-system solve through :mod:`~decrun.methods.model.moving_solves`."""
    from decrun.methods.model.moving_solves import take_moving_values

    model.order[:0] = borders.order
    model._moving_borders = borders.moving
    K = model.ops.K
    for what, item in model.order:
        unknowns = set(item.unknowns) if what == "system" else {item.unknown} if what in ("solve", "newton") else set()
        moving_unknowns = sorted(unknowns & set(borders.moving))
        if moving_unknowns and what == "solve":
            item.rhs = _moving_rhs(item, borders.moving[item.unknown], K.vertices[model.fixed[item.unknown][0]])
        elif moving_unknowns:
            take_moving_values(what, item, model, borders.moving)


def _moving_rhs(item, expression: BorderExpression, points: np.ndarray) -> Callable[[dict], np.ndarray]:
    """The solve's right side, which also sets its fixed values to g at the environment's t (the
    caller, :meth:`CompiledModel.environment`, reads them right after)."""
    original = item.rhs

    def rhs(env: dict) -> np.ndarray:
        item.fixed_values = expression.at(points, float(env["t"]))
        return original(env)
    return rhs


def moving(model) -> dict[str, BorderExpression]:
    """The evolved fields whose Dirichlet values read t, with their expressions."""
    return {u: g for u, g in getattr(model, "_moving_borders", {}).items() if u in model.evolved}


# ---------------------------------------------------------------------- evolutions with moving borders
class MovingProblem(ModelProblem):
    """The model's ``Problem`` (:class:`~decrun.methods.model.problem.ModelProblem`) with border
    values g(t): f(y, t) = (L x + M R(x, t))_F − M_FD ∂g/∂t(t) with x = y and g(t) at the border."""

    def __init__(self, model, expressions: dict[str, BorderExpression]):
        super().__init__(model)
        evolution, K = model.evolution, model.ops.K
        self._parts = []  # per field with fixed values, in evolution.fixed()'s order: (expression or None, points, static)
        for name in evolution.names:
            if name in model.fixed:
                border, values = model.fixed[name]
                self._parts.append((expressions.get(name), K.vertices[border], np.asarray(values, dtype=np.float64)))
        coupling = self._mass_full[self.free][:, self.fixed_index]
        self._mass_coupling = coupling.tocsr() if coupling.count_nonzero() else None

    def values(self, t: float) -> np.ndarray:
        """(c,) the border values at t, in the order of ``fixed_index``."""
        parts = [static if g is None else g.at(points, t) for g, points, static in self._parts]
        return np.concatenate(parts) if parts else np.zeros(0)

    def rates(self, t: float) -> np.ndarray:
        parts = [np.zeros(len(static)) if g is None else g.rate(points, t) for g, points, static in self._parts]
        return np.concatenate(parts) if parts else np.zeros(0)

    def at_time(self, t: float) -> None:
        """Border values of g(t) for :meth:`full`, :meth:`state` (the parent's)."""
        self.fixed_values = self.values(t)

    def f(self, y: np.ndarray, t: float) -> np.ndarray:
        self.at_time(t)
        out = super().f(y, t)
        if self._mass_coupling is not None:
            out = out - self._mass_coupling @ self.rates(t)
        return out

    def jacobian(self, y: np.ndarray, t: float) -> sp.csr_matrix:
        self.at_time(t)
        return super().jacobian(y, t)


class _MovingStepper:
    """A Runge–Kutta stepper of :class:`MovingProblem` stepping the model's state (border values at
    t + dt after the step)."""

    def __init__(self, problem: MovingProblem, stepper, dt: float):
        self.problem, self.stepper, self.dt = problem, stepper, float(dt)

    def step(self, state: dict, t: float) -> dict:
        y = self.problem.free_values(state)
        y = self.stepper.step(y, t)
        self.problem.at_time(t + self.dt)
        return self.problem.state(y)

    def state_dict(self) -> dict:
        return self.stepper.state_dict()

    def load_state(self, state: dict) -> None:
        self.stepper.load_state(state)


def _imex_euler():
    """ARS(1,1,1): (M − dt L) y⁺ = M y + dt g(y, t) — ``imex`` as an additive pair."""
    from decrun.methods.model.tableaux import Tableau

    return Tableau("imex", np.array([[0.0, 0.0], [0.0, 1.0]]), np.array([0.0, 1.0]), np.array([0.0, 1.0]), order=1,
                   explicit_A=np.array([[0.0, 0.0], [1.0, 0.0]]), explicit_b=np.array([1.0, 0.0]))


_EXPLICIT = {"explicit_euler", "rk4", "ssprk3"}
_IMPLICIT = {"implicit_euler", "crank_nicolson", "gauss_legendre", "radau_iia"}
_ADDITIVE = {"imex", "ark_imex"}
_SCIPY = {"bdf", "radau", "rk45"}


def check_integrator(model, scheme: str, dt: float) -> None:
    """:func:`decrun.methods.model.integrators.check_integrator`, and for moving Dirichlet values
    the same checks of the schemes that step them (an exact Jacobian for the implicit tableaux)."""
    from decrun.methods.model import integrators

    fields = moving(model)
    if not fields:
        return integrators.check_integrator(model, scheme, dt)
    if scheme in ("symplectic", "bdf", "radau"):  # the structural checks of fixed borders: pairs, a Jacobian pattern
        return integrators.check_integrator(model, scheme, dt)
    if scheme in _IMPLICIT:
        model.problem.check_jacobian()


def make_integrator(model, scheme: str, dt: float, new_solver, rtol: float = 1e-6, atol: float = 1e-9):
    """The integrator ``scheme`` for ``model``: :func:`decrun.methods.model.integrators.make_integrator`,
    or, when an evolved field's border values read t, the same method stepping :class:`MovingProblem`
    (explicit_euler, rk4, ssprk3: explicit tableaux; implicit_euler, crank_nicolson, gauss_legendre,
    radau_iia: implicit tableaux by Newton; imex, ark_imex: additive pairs; symplectic,
    semi_implicit, bdf, radau, rk45: :mod:`decrun.methods.model.moving_steppers`)."""
    from decrun.methods.model import integrators, moving_steppers
    from decrun.methods.model.runge_kutta import AdditiveRungeKutta, ExplicitRungeKutta, ImplicitRungeKutta
    from decrun.methods.model.tableaux import TABLEAUX

    fields = moving(model)
    if not fields:
        return integrators.make_integrator(model, scheme, dt, new_solver, rtol, atol)
    check_integrator(model, scheme, dt)
    problem = MovingProblem(model, fields)
    if scheme == "symplectic":
        return moving_steppers.MovingSymplectic(model, dt, fields, new_solver)
    if scheme == "semi_implicit":
        return moving_steppers.MovingSemiImplicit(model, dt, new_solver, problem)
    if scheme in _EXPLICIT:
        stepper: Any = ExplicitRungeKutta(TABLEAUX[scheme], problem, dt, new_solver)
    elif scheme in _IMPLICIT:
        problem.check_jacobian()
        stepper = ImplicitRungeKutta(TABLEAUX[scheme], problem, dt, new_solver, where=f"app.integrator={scheme}",
                                     fix=f"take smaller steps: `app.dt={dt / 4:.6g}`")
    elif scheme in _ADDITIVE:
        tableau = TABLEAUX["ark_imex"] if scheme == "ark_imex" else _imex_euler()
        stepper = AdditiveRungeKutta(tableau, problem, dt, new_solver, key="app.integrator")
    elif scheme in _SCIPY:
        stepper = moving_steppers.MovingSciPy(model, problem, scheme, dt, rtol, atol, new_solver)
    else:
        raise ModelError(f"app.integrator: unknown integrator {scheme!r}; choose one of "
                         f"{' | '.join(integrators.INTEGRATORS)}")
    return _MovingStepper(problem, stepper, dt)
