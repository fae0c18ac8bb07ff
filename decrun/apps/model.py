"""``app=<model>``: a declarative DEC model — the physics written in YAML.

A model is a config of the ``app`` group whose ``_target_`` is :class:`Model`; its options are
the model: ``fields`` (each with its ``form`` — ``0..3`` primal, ``dual0..dual3``, or ``n``,
``n-1`` … relative to the mesh dimension — an ``initial`` value and optional ``dirichlet`` border
values), ``constants``, ``equations`` (evolutions ``dt(u) = …``, definitions ``v = …``, linear
solves ``solve(lhs = rhs)`` and systems ``solve(l1 = r1, l2 = r2)``), an ``integrator`` with
``dt`` and ``t_end`` (or ``steps``), ``record_every``, ``metrics`` (numbers, by name) and
``plots`` (:class:`~decrun.apps.model_plots.PlotOptions`: a value in colour with a vector
field's arrows, a longitude–latitude map, an error map).

A model may be composed of ``parts`` (:class:`PartOptions`: fields, equations, metrics) that
share fields by name; they are merged with the model's own declarations by
:func:`decrun.methods.model.parts.compose_parts`, which refuses a conflict naming both parts.
The parts arrive already composed into this node by Hydra: a part is a config file
``conf/app/parts/<name>.yaml`` that a model selects in its defaults list
(``- parts@_here_: [halfar_dynamics, glen_law]``). That keeps a model declarative and makes a
part an ordinary config — found on ``hydra.searchpath`` like any model (a user's own
``my_conf/app/parts/``), listed with a ``did you mean`` when it does not exist, shown by
``--cfg job`` and recorded with the run — and this adapter never opens a file. A part file
puts its fields, equations, metrics, requirements and its constants' defaults under
``parts.<its name>``, where each part keeps its own and a clash can name both, and takes each
default into the model's ``constants`` by an interpolation (``A: ${..parts.glen_law.constants.A}``:
one value per name, so ``app.constants.A=1e-17`` overrides and ``-m`` sweeps a part's constant,
no ``+``). Two parts' different defaults for one constant are refused unless the model sets it
(:meth:`Model.check_node`, on the unresolved node where the interpolation names its part); the
``require`` lists of the model and its parts are checked on the constants before any mesh work
(:mod:`decrun.methods.model.require`).
Everything about the language — parsing, types, operators, integrators — is
:mod:`decrun.methods.model`; this adapter checks the model against the mesh before any work
(types, initial values, the explicit stability limit), steps it through
:func:`decrun.methods.stepping.run_steps` (progress, records, blow-up, checkpoints) and returns
the fields by their declared names, the declared metrics and figures by kind.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Dict, List, Optional

import numpy as np

from decrun.apps.base import App, Context, FieldOnEdges, Figure, Output, Result
from decrun.apps.model_checks import check_wave_limit
from decrun.apps.model_plots import PlotOptions, check_plot_names, check_plot_options, plot_figure
from decrun.core.choices import Choice
from decrun.errors import ConfigError
from decrun.methods.model import FieldSpec, ModelSpec, compile_model
from decrun.methods.model.borders import check_integrator, make_integrator
from decrun.methods.model.explain import explain
from decrun.methods.model.finite import nonfinite_lines
from decrun.methods.model.growth import GrowthWatch
from decrun.methods.model.indefinite_stars import refuse_indefinite_stars
from decrun.methods.model.integrators import FROZEN, explicit_stability_limit
from decrun.methods.model.kinds import NUMBER, VECTOR
from decrun.methods.model.language import names_in, parse_equation
from decrun.methods.model.metrics import model_metrics
from decrun.methods.model.parts import PartSpec, compose_parts
from decrun.methods.model.require import check_requirements, parse_requirement
from decrun.methods.model.stability import explicit_limit, fitted_dt, refuse_nonfinite_terms, suggested_dt
from decrun.methods.model.stepper import ModelStepper
from decrun.methods.stepping import run_steps

__all__ = ["Model", "FieldOptions", "PartOptions", "Integrator"]


class Integrator(Choice):
    """``app.integrator`` (:mod:`decrun.methods.model.integrators`)."""

    explicit_euler = "explicit_euler"
    rk4 = "rk4"
    implicit_euler = "implicit_euler"
    crank_nicolson = "crank_nicolson"
    imex = "imex"
    symplectic = "symplectic"
    bdf = "bdf"
    radau = "radau"
    rk45 = "rk45"
    semi_implicit = "semi_implicit"
    ssprk3 = "ssprk3"
    gauss_legendre = "gauss_legendre"
    radau_iia = "radau_iia"
    ark_imex = "ark_imex"


@dataclass
class FieldOptions:
    """``app.fields.<name>``: ``form`` 0 | 1 | 2 | 3 | dual0 … dual3; ``initial`` a number, an
    expression of x, y, z, a list of expressions (a vector field, for 1- and 2-forms),
    ``random``, ``vertex(i)`` or ``result:<field>``; ``dirichlet`` its values on the border
    simplices (null: natural; may read t), ``neumann`` the outward normal derivative ∂u/∂n,
    ``robin`` ``{alpha, value}``: ∂u/∂n + α u = value (:mod:`decrun.methods.model.borders`);
    ``bounds`` [lo, hi] the range an evolved field must stay in (null: only runaway growth is
    watched, :mod:`decrun.methods.model.growth`)."""

    form: str = "0"
    initial: Any = None
    dirichlet: Any = None
    neumann: Any = None
    robin: Any = None
    bounds: Optional[List[float]] = None


#: the longest plot name: its figure ``<name>.png`` is a file name (255 bytes on most file systems)
PLOT_NAME_MAX = 100


def _check_plot_name(name) -> None:
    """A plot's name becomes the file ``<name>.png`` in the run directory, so it is a name like a
    field's (a letter, then letters, digits or '_'; at most :data:`PLOT_NAME_MAX` characters):
    never a path (``../x``, ``/tmp/x``), never a line of 100k characters; ConfigError otherwise,
    echoing at most the name's first 40 characters."""
    text = str(name)
    shown = repr(text) if len(text) <= 40 else f"{text[:40]!r}…({len(text)} characters)"
    if len(text) > PLOT_NAME_MAX:
        raise ConfigError(f"app.plots: the plot name {shown} is longer than {PLOT_NAME_MAX} characters (it names "
                          "the file <name>.png); choose a shorter one")
    if not isinstance(name, str) or not name.isidentifier() or name.startswith("_"):
        raise ConfigError(f"app.plots: the plot name {shown} is not a name (a letter followed by letters, digits or "
                          "'_'; it names the file <name>.png in the run directory, never a path); rename it, "
                          "e.g. app.plots.flow")


#: the longest chain of definitions reading one another (``v2 = v1 + 1``, ``v3 = v2 + 1`` …): the
#: compiler follows a chain recursively, and Python's stack holds about 450 links (docs/models.md)
MAX_DEFINITION_CHAIN = 300


def _check_definition_chain(equations: list, keys: list) -> None:
    """ConfigError when a definition reads, through other definitions, a chain longer than
    :data:`MAX_DEFINITION_CHAIN` (counted without recursion: each definition's depth is one more
    than the deepest definition it reads). An equation that does not parse is left to the
    compiler, which names it; so is a cycle."""
    parsed = {}
    for text, where in zip(equations, keys, strict=True):
        try:
            equation = parse_equation(text, where)
        except ConfigError:
            return
        if equation.kind == "definition":
            parsed[equation.target] = (names_in(equation.rhs), where)
    depth: dict[str, int] = {}
    for start in parsed:
        stack = [start]
        while stack:
            name = stack[-1]
            if name in depth:
                stack.pop()
                continue
            waiting = [n for n in parsed[name][0] if n in parsed and n not in depth and n not in stack]
            if waiting:
                stack.extend(waiting)
                continue
            depth[name] = 1 + max((depth.get(n, 0) for n in parsed[name][0] if n in parsed), default=0)
            stack.pop()
            if depth[name] > MAX_DEFINITION_CHAIN:
                raise ConfigError(f"{parsed[name][1]}: {name} reads a chain of {depth[name]} definitions, each reading "
                                  f"the next; a chain is at most {MAX_DEFINITION_CHAIN} long: merge definitions "
                                  "into fewer (e.g. v3 = v1 + 2 instead of v2 = v1 + 1, v3 = v2 + 1)")


def _check_bounds(bounds, key: str) -> None:
    """ConfigError unless ``bounds`` is None or [lo, hi], two finite numbers with lo < hi."""
    if bounds is None:
        return
    values = list(bounds) if isinstance(bounds, (list, tuple)) or hasattr(bounds, "__len__") else [bounds]
    numbers = [value for value in values if isinstance(value, (int, float)) and not isinstance(value, bool)]
    if len(values) != 2 or len(numbers) != 2 or not all(math.isfinite(v) for v in numbers) or numbers[0] >= numbers[1]:
        raise ConfigError(f"{key}: bounds are [lo, hi], two finite numbers with lo < hi, got {list(values)!r}; e.g. "
                          f"`++{key}=[-1,1]` (or null: no bounds)")


@dataclass
class PartOptions:
    """``app.parts.<part>``: one part of a composed model (``conf/app/parts/<part>.yaml``; the
    module docstring): its ``fields`` (shared with the other parts by name), ``equations`` and
    ``metrics``. Its constants are the model's (``app.constants``)."""

    fields: Dict[str, FieldOptions] = field(default_factory=dict)
    equations: List[str] = field(default_factory=list)
    metrics: Dict[str, str] = field(default_factory=dict)
    #: the part's defaults of the constants it reads; the model's ``constants`` take them over
    #: (``A: ${..parts.glen_law.constants.A}`` in the part file, so ``app.constants.A=…`` overrides)
    constants: Dict[str, float] = field(default_factory=dict)
    #: what the part requires of the constants, e.g. ``"A > 0"`` (:mod:`decrun.methods.model.require`)
    require: List[str] = field(default_factory=list)


def _part_constants(parts: dict, set_by_model, key: str) -> tuple[dict[str, float], dict[str, str]]:
    """The parts' default constants merged — ``(name → value, name → the part it came from)`` —
    refusing a constant two parts give different defaults unless ``set_by_model(name)``: then
    the model's value wins and neither default is used."""
    defaults: dict[str, float] = {}
    owners: dict[str, str] = {}
    for name, part in parts.items():
        constants = part.get("constants") if isinstance(part, dict) else getattr(part, "constants", None)
        for constant, value in (constants or {}).items():
            if constant in defaults and defaults[constant] != value and not set_by_model(constant):
                raise ConfigError(f"{key}.parts: constant {constant} is {defaults[constant]!r} in part "
                                  f"{owners[constant]} and {value!r} in part {name}; a constant has one default: "
                                  f"set it in the model (the model's value wins), e.g. "
                                  f"`{key}.constants.{constant}={defaults[constant]!r}`")
            defaults.setdefault(constant, value)
            owners.setdefault(constant, name)
    return defaults, owners


@dataclass
class Model(App):
    """Options of a model (``conf/app/heat.yaml`` and the other models; module docstring)."""

    name = "model"
    dimensions = (2, 3)
    boundaries = ("none", "flux")
    boundary_note = "boundary=flux replaces δ1 by the thesis' adapted matrix (§6.4.4)"
    form_degrees = (0,)
    headline_metrics = ("stable", "steps_done")
    #: a title for figures and logs
    model: str = "model"
    fields: Dict[str, FieldOptions] = field(default_factory=dict)
    constants: Dict[str, float] = field(default_factory=dict)
    equations: List[str] = field(default_factory=list)
    integrator: Integrator = Integrator.implicit_euler
    dt: float = 0.01
    t_end: Optional[float] = None  # with dt: steps = t_end / dt (a whole number)
    steps: Optional[int] = None  # used when t_end is null
    record_every: int = 1
    metrics: Dict[str, str] = field(default_factory=dict)
    seed: int = 0  # for `random` initial values
    rtol: float = 1e-6  # bdf | radau | rk45
    atol: float = 1e-9
    stability_check: bool = True  # refuse an explicit dt beyond 2/λ_max (one eigen-solve)
    snapshots: int = 6
    animation: bool = True
    #: the parts this model is composed of (name → PartOptions), merged with its own declarations
    parts: Dict[str, PartOptions] = field(default_factory=dict)
    #: extra figures: name → a value in colour with a vector field's arrows, a map or an error map (PlotOptions)
    plots: Dict[str, PlotOptions] = field(default_factory=dict)
    #: what the model requires of its constants and dt, e.g. ``"Du > 0"``, checked before any
    #: mesh work (:mod:`decrun.methods.model.require`)
    require: List[str] = field(default_factory=list)
    #: print the typed trees and the block structure of the compiled model and run nothing
    #: (:func:`decrun.methods.model.explain.explain`): no step, no solve, no output field
    explain: bool = False

    @classmethod
    def check_node(cls, node: dict, key: str) -> None:
        """On the unresolved config (plain containers, interpolations as their ``${…}`` text): a
        constant two parts give different defaults is refused unless the model sets it — in its
        own file or on the command line, not through a part's interpolation
        ``${..parts.<part>.constants.<name>}`` (Hydra merges the parts' ``constants`` silently,
        last wins; here the provenance is still visible)."""
        constants = node.get("constants") if isinstance(node, dict) else None
        parts = node.get("parts") if isinstance(node, dict) else None
        if not parts:
            return

        def interpolated(value) -> bool:
            return isinstance(value, str) and value.strip().startswith("${")

        def set_by_model(name: str) -> bool:
            return isinstance(constants, dict) and name in constants and not interpolated(constants[name])

        plain = {}
        for name, part in parts.items():
            given = part.get("constants") if isinstance(part, dict) else None
            plain[name] = {"constants": dict(given) if isinstance(given, dict) else {}}
        _part_constants(plain, set_by_model, key)

    def __post_init__(self):
        self.integrator = Integrator.of(self.integrator, "app.integrator")
        if not (self.dt > 0 and math.isfinite(self.dt)):
            raise ConfigError(f"app.dt: must be > 0, got {self.dt}")
        if self.t_end is not None and not (self.t_end > 0 and math.isfinite(self.t_end)):
            raise ConfigError(f"app.t_end: must be > 0 or null, got {self.t_end}")
        if self.steps is not None and self.steps < 0:
            raise ConfigError(f"app.steps: must be >= 0, got {self.steps}")
        if self.record_every < 1:
            raise ConfigError(f"app.record_every: must be >= 1, got {self.record_every}")
        if not (self.rtol > 0 and self.atol > 0):
            raise ConfigError(f"app.rtol, app.atol: must be > 0, got {self.rtol}, {self.atol}")
        for name, options in self.fields.items():
            if isinstance(options, dict):  # Python callers
                self.fields[name] = FieldOptions(**options)
            _check_bounds(self.fields[name].bounds, f"app.fields.{name}.bounds")
        for name, plot in self.plots.items():
            _check_plot_name(name)
            if isinstance(plot, dict):  # Python callers
                self.plots[name] = plot = PlotOptions(**plot)
            check_plot_options(name, plot)
        for name, part in self.parts.items():
            if isinstance(part, dict):  # Python callers
                part = self.parts[name] = PartOptions(**part)
            for field_name, options in part.fields.items():
                if isinstance(options, dict):
                    part.fields[field_name] = FieldOptions(**options)
                _check_bounds(part.fields[field_name].bounds, f"app.parts.{name}.fields.{field_name}.bounds")
        defaults, owners = _part_constants(self.parts, lambda name: name in self.constants, "app")
        for name, value in defaults.items():  # a Python caller's parts: their defaults become the model's
            self.constants.setdefault(name, value)
        requirements = [parse_requirement(text, f"app.require[{i}]") for i, text in enumerate(self.require)]
        for name, part in self.parts.items():
            requirements += [parse_requirement(text, f"app.parts.{name}.require[{i}]")
                             for i, text in enumerate(part.require)]
        for name, value in self.constants.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError(f"app.constants.{name}: must be a finite number, got {value!r}")
        check_requirements(requirements, {**self.constants, "dt": self.dt}, "app", owners, {"dt": "app.dt"})
        own = PartSpec(dict(self.fields), list(self.equations), dict(self.metrics))
        parts = {name: PartSpec(dict(part.fields), list(part.equations), dict(part.metrics))
                 for name, part in self.parts.items()}
        self._composed = compose_parts(own, parts, key="app", own_name=f"the model's own (app={self.model})")
        _check_definition_chain(self._composed.equations, self._composed.equation_keys)
        self._compiled = None

    # ------------------------------------------------------------------ options → method
    def spec(self) -> ModelSpec:
        """The model as data, its parts merged (:func:`~decrun.methods.model.parts.compose_parts`)."""
        composed = self._composed
        fields = {name: FieldSpec(*values) for name, values in composed.fields.items()}
        keys = composed.equation_keys if self.parts else None
        return ModelSpec(fields=fields, equations=list(composed.equations), constants=dict(self.constants),
                         metrics=dict(composed.metrics), seed=int(self.seed), key="app", dt=float(self.dt),
                         equation_keys=keys)

    def total_steps(self) -> int:
        """Steps to run: t_end / dt (refused unless a whole number), else ``steps`` (default 1)."""
        if self.t_end is None:
            return int(self.steps) if self.steps is not None else 1
        ratio = self.t_end / self.dt
        count = int(round(ratio))
        if count < 1 or abs(ratio - count) > 1e-9 * max(1.0, ratio):
            fitted = self.t_end / max(1, math.ceil(ratio))
            # `++`: a model's YAML need not list `steps`, and Hydra refuses `app.steps=` for a key it lacks
            raise ConfigError(f"app.t_end={self.t_end:g} is not a whole number of steps of app.dt={self.dt:g} "
                              f"({ratio:.6g}); use `app.dt={fitted:.12g}` (or `app.steps={max(1, round(ratio))} "
                              "app.t_end=null`)")
        return count

    def compiled(self, dec, new_solver=None):
        """The model compiled on ``dec``'s mesh (once per run: :meth:`check` makes it)."""
        if self._compiled is None or self._compiled.ops.dec is not dec:
            self._compiled = compile_model(self.spec(), dec, new_solver, chained=getattr(dec.K, "meta", {}).get("field"))
        if new_solver is not None:
            self._compiled.bind(new_solver)
        return self._compiled

    def check(self, K, dec) -> None:
        """Before any work: the whole model type-checked and its initial and border values
        sampled on this mesh, the step count, and for explicit integrators dt against the
        stability limit of the diffusion blocks (of a nonlinear diffusion, with its
        coefficients frozen at the initial values)."""
        model = self.compiled(dec)
        if self.explain:  # only what compiling checks: the typed trees and blocks are the point
            return
        model.check_compatibility()
        self._check_plots(model)
        self._bounds(model)  # declared bounds name evolved fields
        steps = self.total_steps()
        if not model.is_static:
            check_integrator(model, str(self.integrator), self.dt)
            refuse_indefinite_stars(model, str(self.integrator))
        if model.is_static or not self.stability_check or steps == 0:
            return
        refuse_nonfinite_terms(model)
        limit, source = explicit_stability_limit(model, str(self.integrator), model.initial_values)
        if not np.isfinite(limit):  # no diffusion block: the fastest oscillation (waves) at t = 0
            limit = check_wave_limit(model, str(self.integrator), self.dt, self.t_end)
        if self.dt > limit:
            safe = fitted_dt(0.9 * limit, self.t_end)  # a whole number of steps to t_end, each below 0.9 × the limit
            frozen = source.endswith(FROZEN)
            name = source[: -len(FROZEN)] if frozen else source
            part = "its linear part with the coefficients frozen at t = 0" if frozen else "its linear part"
            implicit = "semi_implicit" if frozen else "implicit_euler"
            raise ConfigError(f"app.dt={self.dt:g} exceeds the stability limit {limit:.3g} of "
                              f"integrator={self.integrator} for dt({name}) on this mesh (2.785/λ_max for rk4, "
                              f"2/λ_max for Euler, λ_max of {part}); use `app.dt={safe}` or "
                              f"`app.integrator={implicit}`")
        explicit_limit(model, str(self.integrator), self.dt, steps, self.t_end)  # every explicit term, not diffusion only
        self._stability_limit = limit

    def _bounds(self, model) -> dict[str, tuple[float, float]]:
        """field → (lo, hi) of every declared ``bounds`` (the model's own and its parts'); ConfigError
        for bounds on a field that no ``dt(…)`` evolves (only evolved fields are watched)."""
        declared = [(f"app.fields.{name}.bounds", name, options.bounds) for name, options in self.fields.items()]
        declared += [(f"app.parts.{part}.fields.{name}.bounds", name, options.bounds)
                     for part, options_of in self.parts.items() for name, options in options_of.fields.items()]
        out = {}
        for key, name, bounds in declared:
            if bounds is None:
                continue
            if name not in model.evolved:
                raise ConfigError(f"{key}: {name} is not evolved (no dt({name}) equation), and bounds watch the evolved "
                                  f"fields; drop it (`{key}=null`)")
            out[name] = (float(bounds[0]), float(bounds[1]))
        return out

    def _check_plots(self, model) -> None:
        """Every ``app.plots`` entry names a value to colour (a primal or dual 0-form) and a vector
        field the model computes."""
        for name, plot in self.plots.items():
            if check_plot_names(name, plot, model.kinds, model.ops.K):  # a map: checked there
                continue
            for key, wanted in (("color", "a primal or dual 0-form (per vertex or per top simplex)"),
                                ("arrows", "a vector field (e.g. a definition velocity = flux_field(u))")):
                value = getattr(plot, key)
                kind = model.kinds.get(value)
                ok = kind is not None and (kind == VECTOR if key == "arrows" else
                                           kind.is_form and kind.degree == 0)
                if not ok:
                    got = f"a {kind}" if kind is not None else "not a name of the model"
                    names = sorted(n for n, k in model.kinds.items() if (k == VECTOR if key == "arrows" else
                                   k.is_form and k.degree == 0) and n not in ("x", "y", "z"))
                    hint = f"`app.plots.{name}.{key}={names[0]}`" if names else f"define {wanted} in app.equations"
                    raise ConfigError(f"app.plots.{name}.{key}: {value!r} is {got}, but a plot's {key} is {wanted}; "
                                      f"e.g. {hint}")

    #: the definitions (derived quantities) are fields too, their places known once compiled
    outputs_complete = False

    def outputs(self) -> dict[str, Output]:
        """The declared fields by their names, each on the simplices its form says (``0`` per
        vertex, ``1`` per edge, ``dual0`` per top simplex …)."""
        return {name: Output(str(options.form)) for name, options in self.fields.items()
                if isinstance(options, FieldOptions)}

    def run(self, ctx: Context) -> Result:
        """Run the model; see the module docstring. Metrics: the declared ones (at the end),
        and :func:`decrun.methods.model.metrics.model_metrics`'s."""
        model = self.compiled(ctx.dec, ctx.new_solver)
        if self.explain:
            text = explain(model)
            for line in text.splitlines():  # on the console and in the run's log
                ctx.log(line)
            return Result(fields={}, metrics={"steps_done": 0}, figures={},
                          provenance={"model_explain": text, "model_equations_resolved": "\n".join(model.resolved())})
        steps = 0 if model.is_static else self.total_steps()
        integrator = None
        report = None
        if model.is_static:
            with ctx.task(f"{self.model}: definitions and solves"), np.errstate(all="ignore"):
                env = model.environment({}, 0.0, complete=True)  # a non-finite definition: reported by name, below
            stepper = None
        else:
            with ctx.task(f"{self.model}: {self.integrator} set-up"):
                integrator = make_integrator(model, str(self.integrator), self.dt, ctx.new_solver, self.rtol, self.atol)
            stepper = ModelStepper(model, integrator, self.dt, watch=GrowthWatch(model, self._bounds(model), self.dt * steps))
            report = run_steps(stepper, steps, progress=ctx.progress, record=ctx.record, record_every=self.record_every,
                               checkpoint=ctx.checkpoint, desc=self.model)
            env = stepper.environment()
        metrics = model_metrics(model, env, report, integrator=integrator, dt=self.dt,
                                integrator_name=str(self.integrator),
                                stability_limit=getattr(self, "_stability_limit", None))
        if report is not None and not report.stable:  # the runner's verdict line names it (app.dt=…)
            metrics["dt_suggested"] = suggested_dt(model, str(self.integrator), self.dt, steps, self.t_end,
                                                   getattr(self, "_stability_limit", None))
        for line in model.kernel_lines():
            ctx.log(line)
        newton = {f"{item.unknown}_newton_residuals": np.asarray(item.residual_norms, dtype=np.float64)
                  for what, item in model.order if what == "newton" and item.residual_norms}
        return Result(fields=self._fields(model, env), series=newton, metrics=metrics,
                      figures=self._figures(model, env), warnings=nonfinite_lines(model, env),
                      provenance={"model_equations_resolved": "\n".join(model.resolved()),
                                  "model_operator": ctx.dec.star_variant.describe()})

    # ------------------------------------------------------------------ outputs
    def _fields(self, model, env) -> dict:
        """Every field and definition by its name: forms (1-forms with their edge list) and
        vector fields (n_n, d); numbers are metrics, not fields."""
        out = {}
        K = model.ops.K
        for name, kind in model.kinds.items():
            if name not in env or kind == NUMBER or name in self.constants:
                continue
            value = np.asarray(env[name], dtype=np.float64)
            if kind != VECTOR and kind.simplex_dimension(K.dim) == 1 and K.dim > 1:
                out[name] = FieldOnEdges(value)
            else:
                out[name] = value
        return out

    def _figures(self, model, env) -> dict:
        """By kind: the final value of every 0-form and dual 0-form on the mesh; for a
        time-dependent model the first evolved field's snapshots and animation, and the
        declared metrics over time."""
        K = model.ops.K
        figures = {}
        shown = [name for name, kind in model.kinds.items()
                 if name in env and kind.is_form and kind.simplex_dimension(K.dim) in (0, K.dim)
                 and name not in ("x", "y", "z")]
        if K.dim == 2:
            for name in shown:
                figures[name] = Figure.of_kind("surface", values=np.asarray(env[name], dtype=np.float64),
                                               title=f"{self.model}: {name} ({model.kinds[name]})", colorbar_label=name,
                                               cmap="auto")
        if model.evolved and K.dim == 2:
            first = model.evolved[0]
            if model.kinds[first].simplex_dimension(K.dim) in (0, K.dim):
                # the whole range, coloured by sign: a model's field has no thin layers to wash out
                figures[f"{first}_snapshots"] = Figure.of_kind("snapshots", name=first, count=int(self.snapshots),
                                                               title=f"{self.model}: {first}", cmap="auto",
                                                               percentile=100.0)
                if self.animation:
                    figures[f"{first}_animation"] = Figure.of_kind("animation", name=first, title=first,
                                                                   cmap="auto", percentile=100.0)
            if self._composed.metrics:
                figures["metrics"] = Figure.of_kind("recorded_series", names=list(self._composed.metrics),
                                                    title=self.model)
        for name, plot in self.plots.items():
            if not plot.color:  # a map or an error map (decrun.apps.model_plots)
                time = None if model.is_static else float(env.get("t", 0.0))
                data = plot_figure(plot, model.kinds, env, model.ops.dec, self.model, time)
                figures[name] = Figure.of_kind("error_map", **data) if plot.error_map else \
                    Figure.of_kind("sphere_map", **data)
                continue
            figures[name] = Figure.of_kind("values_arrows", values=np.asarray(env[plot.color], dtype=np.float64),
                                           vectors=np.asarray(env[plot.arrows], dtype=np.float64),
                                           title=f"{self.model}: {plot.color}, arrows: {plot.arrows}",
                                           colorbar_label=plot.color)
        return figures
