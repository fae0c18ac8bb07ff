"""One run of the ``decrun`` command, without Hydra's machinery (also used by the tests).

:func:`run` is what the Hydra task of :mod:`decrun.runner.cli` calls with the composed
config and the run directory. Data flow (:func:`run_experiment`): validate the config nodes
(:class:`Experiment`) → load the mesh (:mod:`decrun.runner.mesh`) → ``SimplicialComplex`` →
``DEC`` → solver → ``app.run`` → ``result.h5`` (atomic) + ``metrics.json`` + figures
(:func:`write_run`).
"""

from __future__ import annotations

import dataclasses
import json
import logging
import sys
import time
from pathlib import Path
from typing import Any, Callable

from omegaconf import DictConfig, OmegaConf

from decrun.apps.base import App, Result
from decrun.core import jit
from decrun.core.boundary import BoundaryAdaptation
from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.solvers import Solver
from decrun.core.stars import HodgeStar
from decrun.errors import ConfigError, DecrunError, MeshError, SolverError, TopologyError
from decrun.runner.config import CheckpointConfig, DecrunConfig, OptimizeConfig
from decrun.runner.context import RunContext
from decrun.runner.failures import (exit_code, file_identity, find_memory_error, find_os_error, interrupt_cause,
                                    memory_error_text, os_error_message, record_status, set_aside_stale)
from decrun.runner.hints import cli_message, memory_hint, plugin_name
from decrun.runner.locks import LockedError, acquire, release
from decrun.runner.mesh import MeshSource
from decrun.runner.plugins import Rebuilt, build
from decrun.runner.progress import make_progress, task
from decrun.runner.results import write_metrics_json, write_result
from decrun.runner.results.checked import RESULT_RECORD, file_record
from decrun.runner.results.checkpoint import CHECKPOINT, RunCheckpoint
from decrun.runner.results.export import Export
from decrun.runner.results.recorder import ResultRecorder
from decrun.runner.sweep.job_cache import mesh_and_dec
from decrun.runner.sweep.manifest import config_hash

__all__ = ["Experiment", "validate", "run_experiment", "write_run", "run"]

log = logging.getLogger("decrun")


class Experiment:
    """The plugins of one run, built and checked from ``cfg`` before any work.

    Attributes: ``mesh_source``, ``operator`` (Hodge-star variant), ``boundary``, ``app``,
    ``solver`` — instances of the classes named by the config's ``_target_`` keys;
    ``checkpoint`` the :class:`~decrun.runner.config.CheckpointConfig`.
    """

    def __init__(self, cfg: DictConfig, make: Callable[[Any, str, type], Any] = build):
        check_root_keys(cfg)
        self.app = make(cfg.app, "app", App)
        self.operator = make(cfg.operator, "operator", HodgeStar)
        self.boundary = make(cfg.boundary, "boundary", BoundaryAdaptation)
        self.solver = make(cfg.solver, "solver", Solver)  # a missing optional package → SolverError now
        self.mesh_source = make(cfg.mesh, "mesh", MeshSource)
        self.export = make(cfg.export, "export", Export) if "export" in cfg else None
        self.app.check_solver(self.solver)
        self.checkpoint = (CheckpointConfig(**OmegaConf.to_container(cfg.checkpoint, resolve=True))
                           if "checkpoint" in cfg else CheckpointConfig())


def check_root_keys(cfg: DictConfig) -> None:
    """ConfigError for a root key the schema :class:`decrun.runner.config.DecrunConfig` does
    not have: Hydra's ``+foo=1`` adds keys even to a struct config, and nothing would read it."""
    known = [f.name for f in dataclasses.fields(DecrunConfig)]
    unknown = [key for key in cfg if key not in known and key != "hydra"]  # hydra: a sweep job's own node
    if unknown:
        raise ConfigError(f"{unknown[0]}: unknown root key (nothing reads it); the config has {known}: "
                          f"drop +{unknown[0]}=..., or put the option under its group (e.g. +app.{unknown[0]}=...)")


#: a message starting with one of these names its config key already
_KEYS = ("mesh", "operator", "boundary", "app", "solver", "export", "progress", "figures")


def name_the_key(exc: DecrunError, experiment: Experiment, where: str) -> DecrunError:
    """``exc`` with the config key it comes from in front, when its message (raised by the
    core, which knows no config) does not start with one: ``solver=<name>`` for solver
    errors, ``app=<name>`` otherwise. Mesh and topology errors always name the mesh
    (``where``: its file or sample, :func:`mesh_where`), also when they name an app key
    (``app=parametrization needs a border``); a bare ``mesh:`` becomes ``where``.
    Errors about files (an OSError such as ResultWriteError) name their file already."""
    message = str(exc)
    if isinstance(exc, OSError):
        return exc
    if isinstance(exc, (MeshError, TopologyError)):
        if message.startswith(("mesh.", "mesh=", "mesh ")):  # names the mesh already
            return exc
        message = message.removeprefix("mesh: ")
        prefix = where
    elif message.startswith(_KEYS):
        return exc
    elif isinstance(exc, SolverError):
        prefix = f"solver={experiment.solver.name} (app={experiment.app.name})"
    else:
        prefix = f"app={experiment.app.name}"
    try:
        return type(exc)(f"{prefix}: {message}")
    except TypeError:  # a subclass with another signature: keep it as it is
        return exc


def mesh_where(mesh) -> str:
    """How an error names the mesh: ``mesh.sample=<name>``, ``mesh.path='<file>'`` or ``mesh <label>``."""
    if mesh.meta.get("source") == "sample":
        return f"mesh.sample={mesh.meta.get('label', '')}"
    return f"mesh.path={mesh.meta['path']!r}" if "path" in mesh.meta else f"mesh {mesh.meta.get('label', '')}"


def validate(cfg: DictConfig, memo: dict | None = None, delta: Any = None) -> Experiment:
    """Build and type-check every plugin node of ``cfg`` (ConfigError naming the key).

    ``memo`` (a sweep's plan, many jobs checked in a row): a plugin node whose resolved
    values equal those of a node already built with the same memo is not built again —
    its plugin, or its error, is the earlier one's (the same checks, once per distinct node).

    ``delta`` (:class:`~decrun.runner.sweep.checks.JobDelta`, with ``memo``): ``cfg`` equals
    the config last checked with the same ``delta.group`` except at the plain keys
    ``delta.keys`` (and in the roots ``delta.interpolated``, which are built as above). A
    root none of those keys is under keeps its plugin; a root they are under is rebuilt
    from its last typed config with those leaves assigned (:class:`~decrun.runner.plugins.Rebuilt`),
    so a 10 000-value sweep of ``app.dt`` checks each job in well under a millisecond."""
    if memo is None:
        return Experiment(cfg)

    def memoized(node, key: str, base: type):
        values = OmegaConf.to_container(node, resolve=True, enum_to_str=True) if OmegaConf.is_config(node) else node
        try:
            seen = (key, json.dumps(values, sort_keys=True))
        except TypeError:  # a value JSON cannot write: build it every time
            return build(node, key, base)
        if seen not in memo:
            try:
                memo[seen] = build(node, key, base)
            except DecrunError as exc:
                memo[seen] = exc
        if isinstance(memo[seen], DecrunError):
            raise memo[seen]
        return memo[seen]

    if delta is None:
        return Experiment(cfg, memoized)
    kept, rebuilt = memo.setdefault(("group", delta.group), ({}, {}))

    def make(node, key: str, base: type):
        if key in delta.interpolated:
            return memoized(node, key, base)
        leaves = {name.split(".", 1)[1]: OmegaConf.select(cfg, name) for name in delta.keys
                  if name.split(".", 1)[0] == key and "." in name}
        if not leaves:
            if key not in kept:
                kept[key] = memoized(node, key, base)
            return kept[key]
        if key not in rebuilt:
            rebuilt[key] = Rebuilt(node, key, base)
            return rebuilt[key].plugin
        return rebuilt[key].with_leaves(node, leaves)

    return Experiment(cfg, make)


def run_experiment(cfg: DictConfig, progress: Callable | None = None, out: Path | None = None, cache: bool = False
                   ) -> tuple[Result, Any, dict]:
    """Compose mesh → complex → DEC → app for ``cfg``; returns ``(result, mesh, timings)``.

    Every plugin is built and checked before the mesh is loaded, and the app checks the
    mesh and operators before any solve. Raises :class:`DecrunError` on bad input.

    With ``out`` (a run directory) the app's ``ctx.record`` calls stream to
    ``out/result.h5`` through a :class:`decrun.runner.results.recorder.ResultRecorder`
    (``mesh.recorder``; :func:`write_run` finishes it). If the app raises, the steps
    recorded so far are kept in an incomplete result.h5 (status failed / interrupted);
    nothing is written when nothing was recorded. Without ``out`` the recorded series end
    up in ``result.series``.

    With ``cache`` (sweep jobs) the mesh, complex and DEC come from the per-process cache
    :mod:`decrun.runner.sweep.job_cache` when an earlier job had the same mesh / operator /
    boundary config (``mesh_seconds`` is then 0).
    """
    t = time.perf_counter()
    experiment = validate(cfg)
    # the one kernel switch (decrun/core/jit.py) for the whole job: mesh, complex, operators, app
    with jit.use(str(getattr(experiment.app, "kernels", "auto"))):
        return _run_experiment(cfg, experiment, t, progress, out, cache)


def _run_experiment(cfg: DictConfig, experiment, t: float, progress: Callable | None, out: Path | None, cache: bool
                    ) -> tuple[Result, Any, dict]:
    """:func:`run_experiment` after validation (``t`` its start), under the job's kernel switch."""
    timings: dict[str, float] = {}
    progress = progress or make_progress(False)
    timings["mesh_seconds"] = 0.0

    def load_mesh():
        with task(progress, f"loading mesh={experiment.mesh_source.name}"):
            mesh = experiment.mesh_source.load()
        timings["mesh_seconds"] = time.perf_counter() - t
        return mesh

    def build_dec(mesh):
        try:
            with task(progress, "building and checking the simplicial complex"):
                complex_ = SimplicialComplex(mesh.vertices, mesh.simplices, orient=experiment.mesh_source.orient)
        except MeshError as exc:  # name the mesh the complex refused, with the override that fixes it
            dimension = mesh.simplices.shape[1] - 1
            raise type(exc)(f"{mesh_where(mesh)}: {cli_message(exc, experiment.mesh_source, dimension)}") from exc
        complex_.meta = mesh.meta
        try:  # before the operators: a Hodge-star variant may not exist in this dimension either
            experiment.app.check_dimension(complex_)
        except DecrunError as exc:
            raise name_the_key(exc, experiment, mesh_where(mesh)) from exc
        return complex_, DEC(complex_, star=experiment.operator, boundary=experiment.boundary)

    if cache:
        mesh, complex_, dec = mesh_and_dec(cfg, load_mesh, build_dec)
    else:
        mesh = load_mesh()
        complex_, dec = build_dec(mesh)
    timings["complex_seconds"] = time.perf_counter() - t - timings["mesh_seconds"]
    t = time.perf_counter()
    where = mesh_where(mesh)
    app = experiment.app
    try:
        app.check_dimension(complex_)  # again: a cached complex was checked for another app
        app.check_operators(dec)
        app.check_solver(experiment.solver, dec)
        app.check(complex_, dec)
    except DecrunError as exc:
        raise name_the_key(exc, experiment, where) from exc
    timings["complex_seconds"] += time.perf_counter() - t
    t = time.perf_counter()
    recorder = None
    if out is not None:
        recorder = ResultRecorder(Path(out) / "result.h5", vertices=mesh.vertices, simplices=mesh.simplices,
                                  edges=complex_.simplices(1), config_yaml=OmegaConf.to_yaml(cfg, resolve=True),
                                  mesh_hash=mesh.meta.get("hash", ""))
    mesh.recorder = recorder
    ctx = RunContext(app, complex_, dec, new_solver=experiment.solver.fresh, meta=mesh.meta,
                     progress=progress, recorder=recorder, logger=log)
    if out is not None:  # a time-stepping app continues from out/checkpoint.h5 (decrun.methods.stepping)
        ctx.checkpoint = RunCheckpoint(Path(out) / CHECKPOINT, config_hash(cfg), recorder=recorder,
                                       steps=experiment.checkpoint.steps, seconds=experiment.checkpoint.seconds,
                                       log=log.info)
    try:
        result = app.run(ctx)
    except BaseException as exc:
        named = name_the_key(exc, experiment, where) if isinstance(exc, DecrunError) else exc
        if recorder is not None:  # keep what was recorded, marked incomplete
            status = "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed"
            error = (f"interrupted ({interrupt_cause(exc)})" if isinstance(exc, KeyboardInterrupt) else str(named)
                     if isinstance(exc, DecrunError) else f"{type(exc).__name__}: {exc}")
            try:
                recorder.abort(status, error)
            except (OSError, RuntimeError) as write_error:  # e.g. the disk is full: report the first error
                if not isinstance(exc, OSError):
                    exc.add_note(str(write_error))
        if named is not exc:
            raise named from exc
        raise
    if recorder is None:
        for name, values in ctx.series.items():
            result.series.setdefault(name, values)
    timings["app_seconds"] = time.perf_counter() - t
    result.metrics.setdefault("status", "ok")
    result.metrics.setdefault("n_vertices", int(complex_.num_simplices(0)))
    result.metrics.setdefault("n_faces", int(complex_.num_simplices(complex_.dim)))
    for key in ("largest_component_components", "largest_component_dropped_vertices",
                "largest_component_dropped_faces"):  # mesh.largest_component: nothing dropped unreported
        if key in mesh.meta:
            result.metrics.setdefault(key, int(mesh.meta[key]))
    mesh.complex = complex_
    return result, mesh, timings


def write_run(out: Path, cfg: DictConfig, result: Result, mesh, timings: dict) -> list[Path]:
    """Write ``result.h5`` (atomic; finishing the run's recorder when it has one),
    ``metrics.json`` (the metrics and ``result_h5``: the size and sha256 of result.h5,
    :func:`~decrun.runner.results.checked.file_record`) and the figures into ``out``."""
    written = []
    t = time.perf_counter()
    if cfg.get("figures", True) and result.figures:
        from decrun.runner.plots.common import draw_figures  # lazy: matplotlib only when there are figures (start-up speed)

        written += draw_figures(result.figures, out, mesh.complex)
    timings["figures_seconds"] = time.perf_counter() - t
    timings["total_seconds"] = sum(v for k, v in timings.items() if k != "total_seconds")
    result.metrics.setdefault("total_seconds", timings["total_seconds"])
    if getattr(mesh, "recorder", None) is not None:
        h5 = mesh.recorder.finish(result, timings)
    else:
        h5 = write_result(out / "result.h5", result, vertices=mesh.vertices, simplices=mesh.simplices,
                          edges=mesh.complex.simplices(1) if mesh.complex is not None else None,
                          config_yaml=OmegaConf.to_yaml(cfg, resolve=True), mesh_hash=mesh.meta.get("hash", ""),
                          timings=timings)
    # the size and sha256 of result.h5 as written: readers never take a truncated or altered one for it
    metrics = write_metrics_json(out / "metrics.json", {**result.metrics, RESULT_RECORD: file_record(h5)})
    (Path(out) / CHECKPOINT).unlink(missing_ok=True)  # the run is complete: nothing to continue
    exported = build(cfg.export, "export", Export).write(out, result, mesh) if cfg.get("export") is not None else []
    return [h5, metrics, *written, *exported]


def run(cfg: DictConfig, out: Path, *, multirun: bool = False, verbose: bool = False, log_name: str = "") -> int | float:
    """One run (or one sweep job, ``multirun``) of ``cfg`` into the directory ``out``: the
    experiment, its files (:func:`write_run`) and what it prints. Returns 0 (1 for a failed
    sweep job), or with ``optimize.metric`` set the objective
    :meth:`decrun.runner.config.OptimizeConfig.objective` for a sweeper; a failed single
    run exits 1 (an interrupted one 130/143) after recording its status in ``out``; an
    interrupted sweep job re-raises the interrupt, for the sweeper to say which jobs finished.
    ``verbose`` logs the traceback of a DecrunError; ``log_name`` is the job's log file
    (``<log_name>.log``, named in the closing line).

    The run holds ``out``'s lock (:mod:`decrun.runner.locks`; a single run took it before
    Hydra made the directory) while it runs: when another process holds it, one line on
    stderr naming that process and nothing written (exit 1; a sweep job returns as failed)."""
    try:
        taken = out.is_dir() and acquire(out, "run", fix="choose another run directory with hydra.run.dir=DIR")
    except LockedError as exc:
        print(f"error: {exc}", file=sys.stderr)  # not the log: it is the other process's
        if multirun:
            return 1
        sys.exit(1)
    try:
        return _run(cfg, out, multirun=multirun, verbose=verbose, log_name=log_name)
    finally:
        if taken:
            release(out)


def _run(cfg: DictConfig, out: Path, *, multirun: bool, verbose: bool, log_name: str) -> int | float:
    """:func:`run` once ``out`` is locked."""
    identity = {"config_hash": config_hash(cfg)} if multirun else {}  # ties metrics.json to the manifest
    earlier = file_identity(Path(out) / "result.h5")  # an earlier run's result, set aside if this one fails
    optimize = None
    try:
        optimize = OptimizeConfig(**OmegaConf.to_container(cfg.optimize)) if "optimize" in cfg else OptimizeConfig()
        result, mesh, timings = run_experiment(cfg, make_progress(bool(cfg.get("progress", True)) and not multirun),
                                               out=out, cache=multirun)
        result.metrics.update(identity)
        written = write_run(out, cfg, result, mesh, timings)
        objective = optimize.objective(result.metrics) if optimize.metric else 0
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (failures.Terminated)
        cause = interrupt_cause(exc)
        note = set_aside_stale(out, earlier) + record_status(out, "interrupted", f"interrupted ({cause})", identity)
        print(f"decrun: interrupted ({cause}); what was recorded is in {out}/{note}", file=sys.stderr)
        if multirun:  # the sweeper says which jobs finished (decrun.runner.sweep.stops)
            raise
        sys.exit(exit_code(exc))
    except Exception as exc:
        os_error = None if isinstance(exc, DecrunError) else find_os_error(exc)
        memory = None if isinstance(exc, DecrunError) or os_error is not None else find_memory_error(exc)
        message = (str(exc) if isinstance(exc, DecrunError) else os_error_message(os_error) if os_error is not None
                   else memory_message(memory, cfg) if memory is not None else f"{type(exc).__name__}: {exc}")
        note = set_aside_stale(out, earlier) + record_status(out, "failed", message, identity)
        if verbose or not (isinstance(exc, DecrunError) or os_error is not None or memory is not None):
            log.exception("error: %s%s", message, note)
        else:
            log.error("error: %s%s", message, note)
        if multirun:
            return optimize.objective(None) if optimize is not None and optimize.metric else 1
        sys.exit(1)
    metrics = result.metrics
    shown = ", ".join(f"{k}={_short(v)}" for k, v in metrics.items() if k not in ("status", "config_hash"))
    log.info("metrics: %s", shown)
    if optimize.metric:
        log.info("optimize: %s %s = %s", optimize.direction, optimize.metric, objective)
        return objective
    if not multirun:
        try:
            where = out.relative_to(Path.cwd())
        except ValueError:
            where = out
        print(f"decrun: wrote {where}/ ({', '.join(p.name for p in written)}, {log_name}.log)")
    return 0


def memory_message(exc: BaseException, cfg: DictConfig) -> str:
    """``<where>: could not allocate <size> for an array of shape (…) <dtype>; <the setting
    to lower>`` for a run that ran out of memory (:func:`decrun.runner.failures.memory_error_text`,
    :func:`decrun.runner.hints.memory_hint`); ``where`` names the app and the mesh source."""
    where = f"app={plugin_name(cfg, 'app') or '?'} on mesh={plugin_name(cfg, 'mesh') or '?'}"
    hint = memory_hint(cfg, getattr(exc, "shape", None))
    return f"{where}: {memory_error_text(exc)}" + (f"; {hint}" if hint else "")


def _short(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)
