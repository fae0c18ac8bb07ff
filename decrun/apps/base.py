"""The application contract: :class:`App`, :class:`Context`, :class:`Result`, :class:`Figure`.

An application is a dataclass subclassing :class:`App` — its fields are the options of
``cfg.app`` (declared once; the runner type-checks the config node against them) — with a
method ``run(ctx) -> Result``. Its config file ``conf/app/<name>.yaml`` names it with
``_target_: <module>.<Class>`` and sets the defaults; that is all the runner needs.

The context ``ctx`` (:class:`Context`; the runner passes a subclass that streams to
``result.h5``, tests and notebooks use :class:`Context` itself, which keeps the series in
memory) carries:

``ctx.config``      the app instance itself (typed options)
``ctx.complex``     the :class:`decrun.core.complex.SimplicialComplex` (validated)
``ctx.dec``         ``decrun.core.dec.DEC(complex, star=<operator>, boundary=<boundary>)``
``ctx.meta``        the mesh source's metadata (``clean_vertices``, ``noise_amplitude``,
                    ``hash``, ``label``, ``path`` …; optional keys: test with ``in``)
``ctx.new_solver()`` a fresh, unfactorized solver with the configured options, for every
                    linear system the app solves (factorize once, solve many)
``ctx.progress(iterable, total=…, desc=…)``  a tqdm-like wrapper (silent when not a terminal)
``with ctx.task(desc):``  shows ``desc`` and the elapsed time around one long call that
                    cannot report steps (an eigen-solve, a factorization); silent likewise
``ctx.record(step, **values)``  appends per-step scalars or fixed-shape arrays to the
                    run's series (``series/<name>`` in result.h5, written as the run goes)
``ctx.checkpoint``  a :class:`decrun.methods.stepping.Checkpoint` or None, for
                    :func:`~decrun.methods.stepping.run_steps` (a time-stepping app passes it
                    on: a killed run continues from its last checkpoint)

Applications never open files, never import the runner, hydra or matplotlib, and never
import another application. They declare what they accept:

``boundaries``      the boundary adaptations supported (``boundary=<name>``); anything else
                    is a ConfigError before any work
``form_degrees``    the form degrees whose operators the app uses on the mesh's own
                    simplices; a Hodge-star variant that does not provide them (intrinsic
                    Delaunay: 0-forms only) is rejected before any work
``unsymmetric_systems``  why its linear systems are not SPD (empty when they are): cg and
                    amg are then rejected before any work
``dimensions``      the mesh dimensions the app runs on (2: triangle meshes, 3: tetrahedral
                    ones); any other is a TopologyError before any work, naming the apps that do
``one_piece``       why the app assumes a mesh of one piece ("" when it handles several); a
                    mesh of several pieces is then a TopologyError before any work, naming
                    `mesh.largest_component=true` (:meth:`App.check_pieces`)
``check(K, dec)``   further checks on the mesh before any work (topology)
``outputs()``       the fields it writes and where they live (:class:`Output`): an export
                    is checked against them before any work and writes each in its place

The runner runs these checks through :meth:`App.validate` (dimension, pieces, operators,
solver, ``check``; once each, in that order).

Numerical blow-up is a result (``stable: false``), never an exception; bad input is a typed
:class:`decrun.errors.DecrunError` naming the key. A metric that does not apply is absent,
never ``false``. Figures are :class:`Figure` descriptions — which drawing function of the
runner to call with which arrays — so apps stay free of matplotlib.
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, ClassVar

import numpy as np

from decrun.errors import ConfigError, TopologyError

if TYPE_CHECKING:  # types of the parameters only
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC
    from decrun.core.solvers import Solver

__all__ = ["App", "Context", "Figure", "Result", "FieldOnEdges", "Output"]


@dataclass
class Figure:
    """A figure to draw: ``draw`` is a figure kind (``before_after``, ``snapshots`` …, see
    :meth:`of_kind`) or the dotted path of a function ``draw(K, **data) ->
    matplotlib.figure.Figure`` (a plugin's own drawing), ``data`` its arrays and options. The runner draws it (unless ``figures=false``) and saves
    ``<name>.png``; a function may instead write its own file (an animation) and return
    its path."""

    draw: str
    data: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def of_kind(cls, kind: str, **data) -> "Figure":
        """A figure named by its kind (``surface``, ``snapshots``, ``animation``, ``series`` …:
        the table ``FIGURE_KINDS`` of the runner's plots package), so an app names no runner
        module."""
        return cls(kind, data)


@dataclass
class FieldOnEdges:
    """A 1-form (n1,) together with the edge list ``(n1, 2)`` that orders it; stored in
    result.h5 as ``fields/<name>`` with the attribute ``edges = "mesh/edges"``."""

    values: np.ndarray


@dataclass(frozen=True)
class Output:
    """Where a field of an app's :class:`Result` lives, as the app declares it
    (:meth:`App.outputs`), so an export is checked against it before any mesh is loaded and
    writes each field where it belongs.

    on : ``"0"`` … ``"3"`` one row per primal k-simplex (``"0"`` per vertex, ``"1"`` per
        edge; ``"n"``, ``"n-1"`` … relative to the mesh dimension n, as a model declares them); ``"dual0"`` … ``"dual3"`` per dual k-cell, i.e. per primal (n−k)-simplex
        (``"dual0"``: per top simplex — a face of a surface, a tetrahedron of a volume);
        ``"vertex_set"`` / ``"top_set"`` indices of vertices / top simplices (singularities,
        sources, strokes); ``"along:<name>"`` one row per entry of the index set ``<name>``;
        ``"connectivity"`` the top simplices as vertex indices; ``"global"`` no place on the
        mesh (eigenvalues, points off the vertices)
    width : values per row (1: a scalar; None: not known from the config alone)
    columns : each column is a field of its own (``name_j``: the eigenvectors), not the
        components of one vector
    """

    on: str
    width: int | None = 1
    columns: bool = False

    def simplex_dimension(self, n: int) -> int | None:
        """The dimension of the simplices the rows are on, for a mesh of dimension ``n``
        (None for the sets, ``along``, ``connectivity`` and ``global``)."""
        if self.on.isdigit():
            return int(self.on)
        if self.on.startswith("dual") and self.on[4:].isdigit():
            return n - int(self.on[4:])
        relative = re.fullmatch(r"(dual)?n(?:-([0-3]))?", self.on.replace(" ", ""))
        if relative:  # a model's form relative to the mesh dimension: "n" (top), "n-1", "dualn-1" …
            degree = n - int(relative.group(2) or 0)
            return n - degree if relative.group(1) else degree
        return None


@dataclass
class Result:
    """What an application returns.

    fields : dict[str, np.ndarray | FieldOnEdges]
        Named arrays on the mesh: per vertex ``(n0, ...)``, per edge (1-forms: wrap them in
        :class:`FieldOnEdges` so the file carries their edge order), per face ``(n2, ...)``,
        or any other array a figure or a later run needs (``uv``, ``vertices_final``).
    series : dict[str, np.ndarray]
        Short per-step arrays an app prefers to return at the end; long runs use
        ``ctx.record`` instead.
    metrics : dict[str, float | int | bool | str]
        Flat scalars whose names say their unit or meaning.
    figures : dict[str, Figure]
        Keyed by file stem.
    provenance : dict[str, str]
        Root attributes of result.h5 saying how the result was made.
    warnings : list[str]
        One line each: what makes a finished run's answer not the one asked for (e.g. a
        parametrization that is not an embedding), with the override that gives one. The
        runner logs each, puts them in the metric ``warnings`` and in the run's closing line;
        the run's ``status`` stays ``ok`` (it finished).
    """

    fields: dict[str, Any] = field(default_factory=dict)
    series: dict[str, np.ndarray] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)
    figures: dict[str, Figure] = field(default_factory=dict)
    #: short strings recorded as root attributes of result.h5 (how the result was made, e.g. a
    #: model's equations as resolved), not metrics
    provenance: dict[str, str] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


@dataclass
class App:
    """Base of the applications (a dataclass; subclasses add their options as fields)."""

    name: ClassVar[str] = ""
    #: mesh dimensions the app runs on (2: triangles, 3: tetrahedra)
    dimensions: ClassVar[tuple[int, ...]] = (2,)
    boundaries: ClassVar[tuple[str, ...]] = ("none",)
    #: why other adaptations are not supported (appended to the error message)
    boundary_note: ClassVar[str] = ""
    form_degrees: ClassVar[tuple[int, ...]] = (0, 1, 2)
    #: why the app's linear systems are not symmetric positive definite ("" when they are);
    #: solvers that need SPD matrices (cg, amg) are then rejected before any work (solver=iterative
    #: picks a Krylov method that fits each matrix)
    unsymmetric_systems: ClassVar[str] = ""
    #: why the app needs diagonal Hodge stars ("" when any SPD ⋆ works): a non-diagonal
    #: (Galerkin) variant is then rejected before any work, with the lumped override
    diagonal_stars: ClassVar[str] = ""
    #: the metrics a sweep table shows by default (``decrun-table --all`` shows every one)
    headline_metrics: ClassVar[tuple[str, ...]] = ()
    #: why the app assumes a mesh of one piece ("" when it handles several, e.g. a spectrum:
    #: one kernel dimension per piece); several pieces are then refused before any work
    one_piece: ClassVar[str] = ""
    #: the override a refused operator variant's message names: one that runs this app on
    #: every mesh it accepts (hodge: whitney, whose ⋆1 is SPD where the diagonal ⋆1 is zero)
    operator_hint: ClassVar[str] = "`operator=mixed_area` (or `operator=circumcentric`)"

    #: False when :meth:`outputs` may miss fields the app writes (the model app's definitions):
    #: an export then checks those after the run
    outputs_complete: ClassVar[bool] = True

    def outputs(self) -> dict[str, Output] | None:
        """The fields this app may write with this config (name → :class:`Output`), known
        before any mesh is loaded; None when the app does not say (an export then checks its
        options against the fields after the run, and places them by their shapes)."""
        return None

    def validate(self, K: SimplicialComplex, solver: Solver, operators: Callable[[], Any]) -> Any:
        """Every check of this app against the run's mesh, operators and solver, before any
        work, each once and in this order; returns the operators. The runner calls it once
        per run (:func:`decrun.runner.job.run.prepare`); apps override the checks below, not this.

        1. :meth:`check_dimension` on ``K``, before the operators are built (``operators()``,
           the ``DEC``): a Hodge-star variant may not exist in another dimension either, and
           this message names the apps that run on the mesh;
        2. :meth:`check_pieces` (apps that assume one piece);
        3. :meth:`check_operators`, the boundary adaptation and the Hodge-star variant;
        4. :meth:`check_solver` with the operators (what the config alone says of the solver
           was checked when the config was: ``check_solver(solver)`` before any mesh);
        5. :meth:`check`, the app's own checks of the mesh."""
        self.check_dimension(K)
        self.check_pieces(K)
        dec = operators()
        self.check_operators(dec)
        self.check_solver(solver, dec)
        self.check(K, dec)
        return dec

    def check_dimension(self, K: SimplicialComplex) -> None:
        """TopologyError when ``K``'s dimension is not in ``dimensions`` (before any work), naming
        the apps that run on it."""
        if K.dim in self.dimensions:
            return
        kinds = {1: "a curve (dimension 1)", 2: "a triangle mesh (dimension 2)", 3: "a tetrahedral mesh (dimension 3)"}
        wanted = " or ".join(kinds.get(d, f"dimension {d}") for d in self.dimensions)
        if K.dim == 3:
            fix = "use `app=spectrum` (app=hodge runs on tetrahedra too), or a surface mesh such as `mesh=icosphere`"
        else:
            fix = "use a mesh of that dimension"
        raise TopologyError(f"app={self.name} runs on {wanted}, but this mesh is "
                            f"{kinds.get(K.dim, f'of dimension {K.dim}')}; {fix}")

    def check_pieces(self, K: SimplicialComplex) -> None:
        """TopologyError when the app assumes one piece (``one_piece`` says why) and ``K`` has
        several (top simplices joined through shared vertices,
        :meth:`~decrun.core.complex.SimplicialComplex.connected_components`), naming the post
        step that keeps the largest."""
        if not self.one_piece:
            return
        count, label = K.connected_components()
        if count == 1:
            return
        sizes = np.sort(np.bincount(label))[::-1]
        raise TopologyError(f"mesh: app={self.name} needs one connected piece ({self.one_piece}), but this mesh has "
                            f"{count} pieces of {', '.join(map(str, sizes[:4]))}{', …' if count > 4 else ''} "
                            f"{'triangles' if K.dim == 2 else 'top simplices'}; keep the largest with "
                            "`mesh.largest_component=true`")

    def check(self, K: SimplicialComplex, dec: DEC) -> None:
        """Raise a DecrunError when the mesh does not suit the app (before any work)."""

    def run(self, ctx: "Context") -> Result:  # pragma: no cover - abstract
        raise NotImplementedError

    def check_solver(self, solver: Solver, dec: DEC | None = None) -> None:
        """Reject a solver that cannot solve this app's systems (before any work; ``dec``
        given once the operators are chosen)."""
        if getattr(solver, "needs_spd", False) and self.unsymmetric_systems:
            raise ConfigError(f"solver={solver.name}: app={self.name} solves systems that are not symmetric positive "
                              f"definite ({self.unsymmetric_systems}); use `solver=iterative` (GMRES/MINRES), "
                              "`solver=direct` (or `solver=pardiso`)")

    def check_operators(self, dec: DEC) -> None:
        """Reject a boundary adaptation or Hodge-star variant this app cannot use, with the
        override that fixes it. Called by the runner before any work."""
        if dec.boundary.name not in self.boundaries:
            note = f" ({self.boundary_note})" if self.boundary_note else ""
            raise ConfigError(f"boundary={dec.boundary.name}: app={self.name} supports "
                              f"{' | '.join(f'boundary={b}' for b in self.boundaries)}{note}")
        if self.diagonal_stars:
            nondiagonal = [k for k in self.form_degrees if k <= dec.n and not dec.star_is_diagonal(k)]
            if nondiagonal:
                raise ConfigError(f"operator={dec.star_variant.name}: ⋆_k is not diagonal for k in {nondiagonal}, "
                                  f"but app={self.name} needs diagonal stars ({self.diagonal_stars}); use "
                                  f"`operator.lumped=true` (or `operator=circumcentric`)")
        degrees = dec.star_variant.form_degrees
        if degrees is not None:
            missing = [k for k in self.form_degrees if k <= dec.n and k not in degrees]
            if missing:
                raise ConfigError(f"operator={dec.star_variant.name} provides operators on {list(degrees)}-forms "
                                  f"only, but app={self.name} needs {missing}-forms on the mesh's own simplices: "
                                  f"use {self.operator_hint}")


def _passthrough(iterable, total=None, desc=None, **_):
    return iterable


class Context:
    """What ``App.run`` receives; this base keeps recorded series in memory.

    Parameters
    ----------
    config : App
    K, dec : the simplicial complex and its operators (``ctx.complex``, ``ctx.dec``)
    new_solver : callable returning a fresh solver (default: ``auto``)
    meta : mesh metadata (default: ``complex.meta``)
    progress : tqdm-like factory (default: silent)
    """

    def __init__(self, config: App, K: SimplicialComplex, dec: DEC, new_solver: Callable | None = None, meta: dict | None = None,
                 progress: Callable | None = None):
        from decrun.core.solvers import solver_factory

        self.config = config
        self.complex = K
        self.dec = dec
        self.new_solver = solver_factory(new_solver)
        self.meta = meta if meta is not None else getattr(K, "meta", {})
        self.progress = progress or _passthrough
        self._series: dict[str, list] = {}
        self._steps: list[int] = []
        #: where :func:`decrun.methods.stepping.run_steps` keeps its state (None here: no
        #: checkpoints; the runner's context gives the run directory's checkpoint.h5)
        self.checkpoint = None

    def record(self, step: int, **values) -> None:
        """Append one record: ``step`` (int) and named scalars or fixed-shape arrays."""
        self._steps.append(int(step))
        for name, value in values.items():
            self._series.setdefault(name, []).append(np.asarray(value))

    @property
    def series(self) -> dict[str, np.ndarray]:
        """The recorded series stacked: ``step`` and each name (records, *shape)."""
        out = {name: np.stack(values) for name, values in self._series.items()}
        if self._steps:
            out["step"] = np.asarray(self._steps)
        return out

    def task(self, desc: str):
        """Context manager around one long call: the progress factory's ``task(desc)`` when
        it has one (the runner's, on a terminal), else nothing."""
        from contextlib import nullcontext

        method = getattr(self.progress, "task", None)
        return method(desc) if method is not None else nullcontext()

    def read_result(self, path: str):
        """``(Result, vertices)`` of a previous run's ``result.h5`` (``app.input_path``);
        only the runner's context can read files."""
        raise ConfigError(f"app.input_path={path!r}: reading result files needs the decrun runner "
                          "(run through the `decrun` command)")

    def log(self, message: str) -> None:
        """A progress message for the user (stderr here; the run log in the runner)."""
        print(message, file=sys.stderr)

    def betti(self, k: int) -> int | None:
        """Betti_k of the complex, or None (said in the log) when it cannot be computed here:
        a pinched border on a complex too large for the rank computation
        (:func:`decrun.core.complex.topology.betti_numbers`)."""
        if k == 0:  # the components, whatever the border
            return int(self.complex.connected_components()[0])
        try:
            return int(self.complex.betti_numbers()[k])
        except NotImplementedError as why:
            self.log(f"betti_{k} not computed: {why}")
            return None
