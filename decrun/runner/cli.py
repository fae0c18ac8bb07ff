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

if False:  # typing only
    from decrun.apps.base import Result

log = logging.getLogger("decrun")

# ----------------------------------------------------------------------------------
# directory names that never collide
# ----------------------------------------------------------------------------------


def unique_stamp() -> str:
    """``YYYY-mm-dd_HH-MM-SS_<6 hex>``: a timestamp plus 24 random bits, so two runs or
    sweeps started in the same second get different directories."""
    return f"{datetime.now():%Y-%m-%d_%H-%M-%S}_{secrets.token_hex(3)}"


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

        self.app = build(cfg.app, "app", App)
        self.operator = build(cfg.operator, "operator", HodgeStar)
        self.boundary = build(cfg.boundary, "boundary", BoundaryAdaptation)
        self.solver = build(cfg.solver, "solver", Solver)  # a missing optional package → SolverError now
        self.mesh_source = build(cfg.mesh, "mesh", MeshSource)
        self.app.check_solver(self.solver)


def validate(cfg: DictConfig) -> Experiment:
    """Build and type-check every plugin node of ``cfg`` (ConfigError naming the key)."""
    return Experiment(cfg)


def run_experiment(cfg: DictConfig, progress: Callable | None = None, out: Path | None = None
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
    """
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC
    from decrun.runner.context import RunContext

    timings: dict[str, float] = {}
    t = time.perf_counter()
    from decrun.runner.progress import task

    experiment = validate(cfg)
    progress = progress or make_progress(False)
    with task(progress, f"loading mesh={experiment.mesh_source.name}"):
        mesh = experiment.mesh_source.load()
    timings["mesh_seconds"] = time.perf_counter() - t
    t = time.perf_counter()
    try:
        with task(progress, "building and checking the simplicial complex"):
            complex_ = SimplicialComplex(mesh.vertices, mesh.simplices, orient=experiment.mesh_source.orient)
    except MeshError as exc:  # name the mesh the complex refused, with the override that fixes it
        from decrun.runner.hints import cli_message

        if mesh.meta.get("source") == "sample":
            where = f"mesh.sample={mesh.meta.get('label', '')}"
        else:
            where = f"mesh.path={mesh.meta['path']!r}" if "path" in mesh.meta else f"mesh {mesh.meta.get('label', '')}"
        raise type(exc)(f"{where}: {cli_message(exc, experiment.mesh_source)}") from exc
    complex_.meta = mesh.meta
    dec = DEC(complex_, star=experiment.operator, boundary=experiment.boundary)
    app = experiment.app
    app.check_operators(dec)
    app.check_solver(experiment.solver, dec)
    app.check(complex_, dec)
    timings["complex_seconds"] = time.perf_counter() - t
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
        if recorder is not None:  # keep what was recorded, marked incomplete
            status = "interrupted" if isinstance(exc, KeyboardInterrupt) else "failed"
            recorder.abort(status, str(exc) if isinstance(exc, DecrunError) else f"{type(exc).__name__}: {exc}")
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
    return [h5, metrics, *written]


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


def _task(cfg: DictConfig) -> int:
    from hydra.core.hydra_config import HydraConfig

    out = Path(HydraConfig.get().runtime.output_dir)
    multirun = _is_multirun()
    try:
        result, mesh, timings = run_experiment(cfg, make_progress(bool(cfg.get("progress", True)) and not multirun),
                                               out=out)
        written = write_run(out, cfg, result, mesh, timings)
    except KeyboardInterrupt:
        from decrun.runner.results import write_metrics_json

        write_metrics_json(out / "metrics.json", {"status": "interrupted", "error": "interrupted (Ctrl-C)"})
        print(f"decrun: interrupted; what was recorded is in {out}/", file=sys.stderr)
        sys.exit(130)
    except Exception as exc:
        message = str(exc) if isinstance(exc, DecrunError) else f"{type(exc).__name__}: {exc}"
        from decrun.runner.results import write_metrics_json

        write_metrics_json(out / "metrics.json", {"status": "failed", "error": message})
        if _verbose() or not isinstance(exc, DecrunError):
            log.exception("error: %s", message)
        else:
            log.error("error: %s", message)
        if multirun:
            return 1
        sys.exit(1)
    metrics = result.metrics
    shown = ", ".join(f"{k}={_short(v)}" for k, v in metrics.items() if k not in ("status",))
    log.info("metrics: %s", shown)
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
    """Hydra callback (``hydra.callbacks.sweep_table`` in conf/config.yaml): at the end of a
    sweep writes ``metrics.csv`` and ``metrics.md`` at the sweep root."""

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

    def on_multirun_end(self, config: DictConfig, **kwargs) -> None:
        from decrun.runner.tables import failed_jobs, to_markdown, write_sweep_table

        if SweepTable._progress is not None:
            SweepTable._progress.stop()
            SweepTable._progress = None
        sweep_dir = Path(str(config.hydra.sweep.dir))
        table = write_sweep_table(sweep_dir)
        bad = failed_jobs(table)
        SweepTable.failed = len(bad)
        shown = table.drop(columns=[c for c in ("error",) if c in table.columns and not len(bad)])
        print(to_markdown(shown), end="")
        print(f"decrun: sweep of {len(table)} jobs ({len(bad)} failed) → {sweep_dir}/metrics.csv, metrics.md")
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
    SweepTable.failed = 0
    _hydra_main()
    if SweepTable.failed:
        sys.exit(1)


# ----------------------------------------------------------------------------------
# decrun-table
# ----------------------------------------------------------------------------------


def table_main(argv: list[str] | None = None) -> int:
    """Console script ``decrun-table SWEEP_DIR [--csv]``: rebuild ``metrics.csv`` /
    ``metrics.md`` of a sweep and print the table (markdown, or CSV with ``--csv``)."""
    import argparse

    from decrun.runner.tables import NotASweepError, failed_jobs, to_markdown, write_sweep_table

    parser = argparse.ArgumentParser(prog="decrun-table", description=table_main.__doc__)
    parser.add_argument("sweep_dir", help="a sweep directory, e.g. outputs/sweeps/<stamp>")
    parser.add_argument("--csv", action="store_true", help="print CSV instead of markdown")
    args = parser.parse_args(argv)
    try:
        table = write_sweep_table(args.sweep_dir)
    except (FileNotFoundError, NotASweepError) as exc:
        print(f"decrun-table: error: {exc}", file=sys.stderr)
        return 2
    if table.empty:
        print(f"decrun-table: error: no job directories (with .hydra/) in {args.sweep_dir}", file=sys.stderr)
        return 2
    print(table.to_csv(index=False) if args.csv else to_markdown(table), end="")
    return 1 if len(failed_jobs(table)) else 0

