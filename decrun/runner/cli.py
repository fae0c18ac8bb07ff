"""The ``decrun`` command (a Hydra app) and ``decrun-table``.

``decrun [-v] [overrides...]`` composes ``conf/config.yaml`` (defaults: mesh, operator,
app, solver), runs one experiment into ``outputs/runs/<stamp>/`` and prints what it
wrote. ``decrun -m key=a,b ...`` runs a sweep into ``outputs/sweeps/<stamp>/<job>/`` and
writes ``metrics.csv`` / ``metrics.md`` at the sweep root (one row per job, also for
jobs that failed); it exits non-zero when a job failed.

Data flow of one run (:func:`run_experiment`): validate the config nodes → load the mesh
(:mod:`decrun.runner.meshes`) → ``SimplicialComplex`` → ``DEC`` → solver → ``app.run`` →
``result.h5`` (atomic) + ``metrics.json`` + figures (:func:`write_run`).

Errors: a :class:`decrun.errors.DecrunError` (bad input) prints one line
``error: <message>`` and exits 1 with no ``result.h5``; ``-v``/``--verbose`` or
``hydra.verbose=true`` show the traceback. Config keys Hydra cannot compose (a misspelt
key, a wrong type, an unknown option) are reported by Hydra before anything runs.
"""

from __future__ import annotations

import logging
import os
import secrets
import sys
import time
from datetime import datetime
from pathlib import Path
from typing import Any, Callable

import hydra
from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from decrun.errors import DecrunError, MeshError
from decrun.runner.config import config_dir, load_option, register_configs
from decrun.runner.failures import (exit_code, find_os_error, install_sigterm, interrupt_cause, os_error_message,
                                    record_status)

if False:  # typing only
    from decrun.apps.base import Result

log = logging.getLogger("decrun")

# ----------------------------------------------------------------------------------
# directory names that never collide
# ----------------------------------------------------------------------------------


_ISSUED_STAMPS: set[str] = set()


def unique_stamp() -> str:
    """``YYYY-mm-dd_HH-MM-SS_<6 hex>``: a timestamp plus 24 random bits, so two runs or
    sweeps started in the same second get different directories (two processes collide with
    probability 2⁻²⁴); within one process a stamp is never issued twice."""
    while True:
        stamp = f"{datetime.now():%Y-%m-%d_%H-%M-%S}_{secrets.token_hex(3)}"
        if stamp not in _ISSUED_STAMPS:
            _ISSUED_STAMPS.add(stamp)
            return stamp


if not OmegaConf.has_resolver("decrun.stamp"):
    # cached: every job of a sweep (Hydra copies the resolver cache into each job's
    # config, also across joblib processes) sees the sweep's single stamp
    OmegaConf.register_new_resolver("decrun.stamp", unique_stamp, use_cache=True)

register_configs()

# ----------------------------------------------------------------------------------
# one run, without Hydra's machinery (also used by the tests)
# ----------------------------------------------------------------------------------


from decrun.runner.progress import make_progress  # noqa: E402  (re-exported: the run's ctx.progress)


class Experiment:
    """The plugins of one run, built and checked from ``cfg`` before any work.

    Attributes: ``mesh_source``, ``operator`` (Hodge-star variant), ``boundary``, ``app``,
    ``solver`` — instances of the classes named by the config's ``_target_`` keys.
    """

    def __init__(self, cfg: DictConfig):
        from decrun.apps.base import App
        from decrun.core.boundary import BoundaryAdaptation
        from decrun.core.solvers import Solver
        from decrun.core.stars import HodgeStar
        from decrun.runner.meshes import MeshSource
        from decrun.runner.plugins import build

        check_root_keys(cfg)
        self.app = build(cfg.app, "app", App)
        self.operator = build(cfg.operator, "operator", HodgeStar)
        self.boundary = build(cfg.boundary, "boundary", BoundaryAdaptation)
        self.solver = build(cfg.solver, "solver", Solver)  # a missing optional package → SolverError now
        self.mesh_source = build(cfg.mesh, "mesh", MeshSource)
        from decrun.runner.export import Export

        self.export = build(cfg.export, "export", Export) if "export" in cfg else None
        self.app.check_solver(self.solver)


def check_root_keys(cfg: DictConfig) -> None:
    """ConfigError for a root key the schema :class:`decrun.runner.config.DecrunConfig` does
    not have: Hydra's ``+foo=1`` adds keys even to a struct config, and nothing would read it."""
    import dataclasses

    from decrun.errors import ConfigError
    from decrun.runner.config import DecrunConfig

    known = [f.name for f in dataclasses.fields(DecrunConfig)]
    unknown = [key for key in cfg if key not in known]
    if unknown:
        raise ConfigError(f"{unknown[0]}: unknown root key (nothing reads it); the config has {known}: "
                          f"drop +{unknown[0]}=..., or put the option under its group (e.g. +app.{unknown[0]}=...)")


#: a message starting with one of these names its config key already
_KEYS = ("mesh", "operator", "boundary", "app", "solver", "export", "progress", "figures")


def name_the_key(exc: DecrunError, experiment: Experiment, where: str) -> DecrunError:
    """``exc`` with the config key it comes from in front, when its message (raised by the
    core, which knows no config) does not start with one: the mesh (``where``) for mesh
    and topology errors, ``solver=<name>`` for solver errors, ``app=<name>`` otherwise.
    Errors about files (an OSError such as ResultWriteError) name their file already."""
    from decrun.errors import SolverError, TopologyError

    message = str(exc)
    if message.startswith(_KEYS) or isinstance(exc, OSError):
        return exc
    if isinstance(exc, (MeshError, TopologyError)):
        prefix = where
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


def validate(cfg: DictConfig) -> Experiment:
    """Build and type-check every plugin node of ``cfg`` (ConfigError naming the key)."""
    return Experiment(cfg)


def run_experiment(cfg: DictConfig, progress: Callable | None = None, out: Path | None = None, cache: bool = False
                   ) -> tuple[Result, Any, dict]:
    """Compose mesh → complex → DEC → app for ``cfg``; returns ``(result, mesh, timings)``.

    Every plugin is built and checked before the mesh is loaded, and the app checks the
    mesh and operators before any solve. Raises :class:`DecrunError` on bad input.

    With ``out`` (a run directory) the app's ``ctx.record`` calls stream to
    ``out/result.h5`` through a :class:`decrun.runner.recorder.ResultRecorder`
    (``mesh.recorder``; :func:`write_run` finishes it). If the app raises, the steps
    recorded so far are kept in an incomplete result.h5 (status failed / interrupted);
    nothing is written when nothing was recorded. Without ``out`` the recorded series end
    up in ``result.series``.

    With ``cache`` (sweep jobs) the mesh, complex and DEC come from the per-process cache
    :mod:`decrun.runner.job_cache` when an earlier job had the same mesh / operator /
    boundary config (``mesh_seconds`` is then 0).
    """
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC
    from decrun.runner.context import RunContext

    timings: dict[str, float] = {}
    t = time.perf_counter()
    from decrun.runner.progress import task

    experiment = validate(cfg)
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
            from decrun.runner.hints import cli_message

            raise type(exc)(f"{mesh_where(mesh)}: {cli_message(exc, experiment.mesh_source, mesh.simplices.shape[1] - 1)}") from exc
        complex_.meta = mesh.meta
        try:  # before the operators: a Hodge-star variant may not exist in this dimension either
            experiment.app.check_dimension(complex_)
        except DecrunError as exc:
            raise name_the_key(exc, experiment, mesh_where(mesh)) from exc
        return complex_, DEC(complex_, star=experiment.operator, boundary=experiment.boundary)

    if cache:
        from decrun.runner.job_cache import mesh_and_dec

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
        from decrun.runner.recorder import ResultRecorder

        recorder = ResultRecorder(Path(out) / "result.h5", vertices=mesh.vertices, simplices=mesh.simplices,
                                  edges=complex_.simplices(1), config_yaml=OmegaConf.to_yaml(cfg, resolve=True),
                                  mesh_hash=mesh.meta.get("hash", ""))
    mesh.recorder = recorder
    ctx = RunContext(app, complex_, dec, new_solver=experiment.solver.fresh, meta=mesh.meta,
                     progress=progress, recorder=recorder, logger=log)
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
    mesh.complex = complex_
    return result, mesh, timings


def compose_config(overrides: list[str] | None = None) -> DictConfig:
    """The config ``decrun <overrides>`` would run (same config dir, schemas and
    defaults; the ``hydra`` node left out). For tests and notebooks."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(config_dir()), version_base="1.3"):
        return compose(config_name="config", overrides=list(overrides or []))


def write_run(out: Path, cfg: DictConfig, result: Result, mesh, timings: dict) -> list[Path]:
    """Write ``result.h5`` (atomic; finishing the run's recorder when it has one),
    ``metrics.json`` and the figures into ``out``."""
    from decrun.runner.results import write_metrics_json, write_result

    written = []
    t = time.perf_counter()
    if cfg.get("figures", True) and result.figures:
        from decrun.runner.plots.common import draw_figures

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
    metrics = write_metrics_json(out / "metrics.json", result.metrics)
    exported = []
    if cfg.get("export") is not None:
        from decrun.runner.export import Export
        from decrun.runner.plugins import build

        exported = build(cfg.export, "export", Export).write(out, result, mesh)
    return [h5, metrics, *written, *exported]


# ----------------------------------------------------------------------------------
# the Hydra task
# ----------------------------------------------------------------------------------

_VERBOSE = False


def _is_multirun() -> bool:
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    return HydraConfig.get().mode == RunMode.MULTIRUN


def _verbose() -> bool:
    from hydra.core.hydra_config import HydraConfig

    return _VERBOSE or bool(HydraConfig.get().verbose)


def _task(cfg: DictConfig) -> int | float:
    """One job. Returns 0 (1 for a failed sweep job), or with ``optimize.metric`` set the
    objective :meth:`decrun.runner.config.OptimizeConfig.objective` for a sweeper."""
    from hydra.core.hydra_config import HydraConfig

    from decrun.runner.config import OptimizeConfig
    from decrun.runner.sweeps import config_hash

    out = Path(HydraConfig.get().runtime.output_dir)
    multirun = _is_multirun()
    identity = {"config_hash": config_hash(cfg)} if multirun else {}  # ties metrics.json to the manifest
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
        note = record_status(out, "interrupted", f"interrupted ({cause})", identity)
        print(f"decrun: interrupted ({cause}); what was recorded is in {out}/{note}", file=sys.stderr)
        sys.exit(exit_code(exc))
    except Exception as exc:
        os_error = None if isinstance(exc, DecrunError) else find_os_error(exc)
        message = (str(exc) if isinstance(exc, DecrunError) else os_error_message(os_error) if os_error is not None
                   else f"{type(exc).__name__}: {exc}")
        note = record_status(out, "failed", message, identity)
        if _verbose() or not (isinstance(exc, DecrunError) or os_error is not None):
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
        print(f"decrun: wrote {where}/ ({', '.join(p.name for p in written)}, {HydraConfig.get().job.name}.log)")
    return 0


def _short(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


@hydra.main(version_base="1.3", config_path=str(config_dir()), config_name="config")
def _hydra_main(cfg: DictConfig) -> int:
    return _task(cfg)


class SweepTable(Callback):
    """Hydra callback (``hydra.callbacks.sweep_table`` in conf/config.yaml): before a sweep,
    refuses a non-empty ``hydra.sweep.dir`` for sweepers without resume (the ``decrun``
    sweeper checks it itself, see :mod:`decrun.runner.sweeper`); at its end writes
    ``metrics.csv`` and ``metrics.md`` at the sweep root and prints the table."""

    failed = 0
    _progress = None

    def on_multirun_start(self, config: DictConfig, **kwargs) -> None:
        """Jobs done / total with ETA in the submitting process (a terminal only)."""
        from decrun.runner.progress import SweepProgress, sweep_size, terminal

        enabled = terminal(bool(config.get("progress", True)))
        if not enabled:
            return
        params = config.hydra.sweeper.get("params") or {}
        params = OmegaConf.to_container(params, resolve=False) if isinstance(params, DictConfig) else dict(params)
        total = sweep_size(list(config.hydra.overrides.task), params)
        SweepTable._progress = SweepProgress(Path(str(config.hydra.sweep.dir)), total, enabled=True).start()

    def on_multirun_start(self, config: DictConfig, **kwargs) -> None:
        sweep_dir = Path(str(config.hydra.sweep.dir))
        target = str(config.hydra.sweeper.get("_target_", ""))
        if not target.startswith("hydra_plugins.decrun_sweeper.") and sweep_dir.is_dir() and any(sweep_dir.iterdir()):
            from decrun.runner.sweeper import SweepError, refuse

            refuse(SweepError(f"error: hydra.sweep.dir={sweep_dir} is not empty; its old jobs would mix into the "
                             f"new table: choose a new hydra.sweep.dir (only hydra/sweeper=decrun resumes)"))

    def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
        from decrun.runner.tables import failed_jobs, select, to_markdown, write_sweep_table

        if SweepTable._progress is not None:
            SweepTable._progress.stop()
            SweepTable._progress = None
        sweep_dir = Path(str(config.hydra.sweep.dir))
        table = write_sweep_table(sweep_dir, sweep=True)
        bad = failed_jobs(table)
        SweepTable.failed = len(bad)
        print(to_markdown(select(table, drop_constant=True)), end="")
        print(f"decrun: sweep of {len(table)} jobs ({len(bad)} not ok) → {sweep_dir}/metrics.csv, metrics.md")
        for row in bad.itertuples(index=False):
            print(f"decrun: job {row.job} {row.status}: {row.error}", file=sys.stderr)


def fast_help() -> str:
    """``decrun --help`` without composing through Hydra (which deep-copies its whole config
    store once per config group): the header, the options of each config group (the YAML
    files of ``conf/``) and the default config (``config.yaml``'s defaults merged in order).
    With overrides (``decrun app=hodge --help``) Hydra's own help runs."""
    root = config_dir()
    main_cfg = OmegaConf.load(root / "config.yaml")
    lines = [str(main_cfg.hydra.help.header).rstrip(), "", "== Configuration groups ==",
             "Compose your configuration from those groups (group=option)", ""]
    for group in sorted(p.name for p in root.iterdir() if p.is_dir() and not p.name.startswith((".", "_"))):
        options = sorted(f.stem for f in (root / group).glob("*.yaml") if not f.stem.startswith("_"))
        if options:
            lines.append(f"{group}: {', '.join(options)}")
    merged = OmegaConf.create()
    for entry in main_cfg.defaults:
        if isinstance(entry, str) or entry is None:
            continue
        for group, option in entry.items():
            if not group.startswith(("override ", "hydra/")):  # Hydra's own groups are not the task's
                merged[group] = load_option(group, option)
    body = {k: v for k, v in OmegaConf.to_container(main_cfg).items() if k not in ("defaults", "hydra")}
    merged = OmegaConf.merge(merged, body)
    lines += ["", "", "== Config ==", "Override anything in the config (foo.bar=value)", "",
              OmegaConf.to_yaml(merged).rstrip(), "", str(main_cfg.hydra.help.footer).rstrip(), ""]
    return "\n".join(lines)


def main() -> None:
    """Console script ``decrun``: ``-v``/``--verbose`` shows tracebacks; everything else is
    Hydra's command line (overrides, ``-m``, ``--cfg job``, ``--help``...)."""
    global _VERBOSE
    args = [a for a in sys.argv[1:] if a not in ("-v", "--verbose")]
    _VERBOSE = len(args) != len(sys.argv) - 1
    if _VERBOSE:
        os.environ["HYDRA_FULL_ERROR"] = "1"
    sys.argv = [sys.argv[0], *args]
    if args in (["--help"], ["-h"]):
        print(fast_help(), end="")
        return
    if any(a.startswith("query=") for a in args) and any(a in ("-sc", "--shell-completion") for a in args):
        _completion()
        return
    SweepTable.failed = 0
    install_sigterm()
    # a log file that cannot be written (full disk) must not print logging's tracebacks;
    # the error itself is reported on the console
    logging.raiseExceptions = False
    # Hydra prints a traceback for an exception outside the task (creating the run
    # directory, saving .hydra/, Ctrl-C while composing); let them reach _report instead
    os.environ["HYDRA_FULL_ERROR"] = "1"
    try:
        _hydra_main()
    except Exception as exc:
        sys.exit(_report(exc))
    except KeyboardInterrupt as exc:
        print(f"decrun: interrupted ({interrupt_cause(exc)}) before the run started", file=sys.stderr)
        sys.exit(exit_code(exc))
    if SweepTable.failed:
        sys.exit(1)


def _completion() -> None:
    """Hydra's shell completion, without the files that are shared pieces of a group rather
    than options (names starting with ``_``, e.g. ``mesh/_post_processing``)."""
    import contextlib
    import io
    import re

    captured = io.StringIO()
    with contextlib.redirect_stdout(captured):
        try:
            _hydra_main()
        except SystemExit:
            pass
    words = [w for w in captured.getvalue().split() if not re.search(r"[=/]_[^/=]*$", w)]
    print(" ".join(words))


def _report(exc: Exception) -> int:
    """Print an exception Hydra let through (see :func:`main`) as one line, as Hydra itself
    would for its own errors; returns the exit code. With -v: the traceback."""
    from hydra.errors import CompactHydraException
    from omegaconf.errors import OmegaConfBaseException

    if _VERBOSE:
        raise exc
    if isinstance(exc, CompactHydraException):  # what Hydra's run_and_report prints
        print(str(exc), file=sys.stderr)
        if isinstance(exc.__cause__, OmegaConfBaseException):
            print(str(exc.__cause__), file=sys.stderr)
        return 1
    if isinstance(exc, DecrunError):
        print(f"error: {exc}", file=sys.stderr)
        return 1
    os_error = find_os_error(exc)
    if os_error is not None:
        print(f"error: {os_error_message(os_error)}", file=sys.stderr)
        return 1
    raise exc  # a bug: show it


# ----------------------------------------------------------------------------------
# decrun-table
# ----------------------------------------------------------------------------------


def table_main(argv: list[str] | None = None) -> int:
    """Console script ``decrun-table SWEEP [SWEEP ...]``: rebuild each sweep's ``metrics.csv``
    / ``metrics.md`` (only in directories a sweep wrote) and print the table — several
    sweeps stacked with a ``sweep`` column. Exit 1 when a job is not ok, 2 on an error."""
    import argparse

    from decrun.runner.tables import failed_jobs, is_sweep_dir, select, stack, to_markdown, write_sweep_table

    parser = argparse.ArgumentParser(prog="decrun-table", description=table_main.__doc__)
    parser.add_argument("sweep_dirs", nargs="+", metavar="SWEEP", help="a sweep directory, e.g. outputs/sweeps/<stamp>")
    parser.add_argument("--csv", action="store_true", help="print CSV instead of markdown")
    parser.add_argument("--metrics", help="comma-separated metric columns to show (default: all)")
    parser.add_argument("--sort", help="comma-separated columns to sort the rows by")
    parser.add_argument("--descending", action="store_true", help="sort in descending order")
    parser.add_argument("--drop-constant", action=argparse.BooleanOptionalAction, default=None,
                        help="drop columns with one value in every row (default: on for markdown, off for --csv)")
    args = parser.parse_args(argv)
    split = (lambda text: [k.strip() for k in text.split(",") if k.strip()] if text else None)
    try:
        for sweep_dir in args.sweep_dirs:
            if not Path(sweep_dir).is_dir():
                raise FileNotFoundError(f"sweep directory {sweep_dir!r} does not exist")
            if is_sweep_dir(sweep_dir):
                write_sweep_table(sweep_dir)
        table = stack(args.sweep_dirs)
        if len(args.sweep_dirs) == 1:
            table = table.drop(columns="sweep")
        drop = (not args.csv) if args.drop_constant is None else args.drop_constant
        shown = select(table, split(args.metrics), split(args.sort), args.descending, drop)
    except (FileNotFoundError, KeyError, DecrunError) as exc:
        print(f"decrun-table: error: {exc.args[0] if isinstance(exc, KeyError) else exc}", file=sys.stderr)
        return 2
    if table.empty:
        print(f"decrun-table: error: no jobs (no manifest.json, no job directories with .hydra/) in "
              f"{', '.join(args.sweep_dirs)}", file=sys.stderr)
        return 2
    print(shown.to_csv(index=False) if args.csv else to_markdown(shown), end="")
    return 1 if len(failed_jobs(table)) else 0
