"""One run of the ``decrun`` command, without Hydra's machinery (also used by the tests).

:func:`run` is what the Hydra task of :mod:`decrun.runner.command.task` calls with the composed
config and the run directory. A run is one :class:`Run` record carried through three
steps: :func:`prepare` (the config's plugins built and checked,
:class:`~decrun.runner.job.experiment.Experiment` → the
mesh (:mod:`decrun.runner.mesh`) → ``SimplicialComplex`` → ``DEC``, checked by
:meth:`decrun.apps.base.App.validate`), :func:`execute` (``app.run``, its records streamed
to ``result.h5``) and :func:`write` (``result.h5`` (atomic) + ``metrics.json`` + figures +
export). Errors get their config key in one place, :meth:`Run.naming_errors`; the run
directory's file names are those of :class:`decrun.runner.io.files.RunFiles`.
"""

from __future__ import annotations

import functools
import logging
import sys
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from omegaconf import DictConfig, OmegaConf

from decrun.apps.base import Result
from decrun.core import jit
from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.errors import ConfigError, DecrunError, MeshError, TopologyError
from decrun.runner.io.files import RunFiles
from decrun.runner.io.job_cache import mesh_and_dec
from decrun.runner.io.locks import LockedError, acquire, release
from decrun.runner.job.config import OptimizeConfig
from decrun.runner.job.context import RunContext
from decrun.runner.job.experiment import Experiment, mesh_where, name_the_key, root_options, validate
from decrun.runner.job.failures import (
    Stopped,
    exit_code,
    file_identity,
    find_in_chain,
    find_memory_error,
    find_os_error,
    interrupt_cause,
    memory_error_text,
    os_error_message,
    record_status,
    set_aside_stale,
    shorten_words,
)
from decrun.runner.job.hints import cli_message, memory_hint, plugin_name, resolution_message
from decrun.runner.job.plugins import Recent
from decrun.runner.job.progress import make_progress, task
from decrun.runner.job.verdict import unstable_verdict
from decrun.runner.mesh import Mesh
from decrun.runner.results import write_metrics_json, write_result
from decrun.runner.results.checked import RESULT_RECORD
from decrun.runner.results.checkpoint import RunCheckpoint, remove_checkpoint
from decrun.runner.results.export import ExportFailed
from decrun.runner.results.provenance import result_record
from decrun.runner.results.reading import CHAINED_STATUS
from decrun.runner.results.recorder import ResultRecorder
from decrun.runner.sweep.manifest import config_hash

__all__ = ["Experiment", "Run", "validate", "prepare", "execute", "write", "run_experiment", "run", "FiguresFailed",
           "FIGURES_ERROR"]

log = logging.getLogger("decrun")


@dataclass
class Run:
    """One run as it goes through :func:`prepare` → :func:`execute` → :func:`write`.

    ``cfg``: the composed config; ``experiment``: its plugins, built and checked
    (:class:`Experiment`); ``files``: the run directory's files (:class:`RunFiles`), or None
    when nothing is streamed to disk (tests, notebooks: :func:`write` is then given the
    directory); ``progress``: the progress factory. Set by :func:`prepare`: ``mesh`` (the
    job's own :class:`~decrun.runner.mesh.Mesh` record), ``complex`` and ``dec`` (maybe
    shared with earlier sweep jobs, read-only); by :func:`execute`: ``recorder`` (with
    ``files``), ``result``; ``timings``: ``mesh_seconds``, ``complex_seconds``,
    ``app_seconds``, then ``figures_seconds`` and ``total_seconds`` (:func:`write`).
    """

    cfg: DictConfig
    experiment: Experiment
    files: RunFiles | None = None
    progress: Callable = field(default_factory=lambda: make_progress(False))
    mesh: Mesh | None = None
    complex: SimplicialComplex | None = None
    dec: DEC | None = None
    recorder: ResultRecorder | None = None
    result: Result | None = None
    timings: dict[str, float] = field(default_factory=dict)
    #: :func:`config_hash` of ``cfg`` once made (:meth:`config_hash`)
    hashed: str | None = None

    def config_hash(self) -> str:
        """:func:`~decrun.runner.sweep.manifest.config_hash` of ``cfg``, made once: a sweep job's
        metrics.json and its checkpoint both carry it (a YAML dump per root key: ~2.5 ms)."""
        if self.hashed is None:
            self.hashed = config_hash(self.cfg)
        return self.hashed

    @property
    def where(self) -> str:
        """How an error names the mesh (:func:`mesh_where`)."""
        return mesh_where(self.mesh)

    def kernels(self):
        """The one kernel switch (:func:`decrun.core.jit.use`) for the run's work: mesh, complex,
        operators, app — the app's ``kernels`` option (``auto`` for an app without one)."""
        return jit.use(str(getattr(self.experiment.app, "kernels", "auto")))

    @contextmanager
    def naming_errors(self, stage: str = "app"):
        """The one place errors get the config key they come from in front (the core raises
        them knowing no config). ``stage="complex"``: the complex refused the mesh — a
        :class:`MeshError` names the mesh and gets the override that fixes it
        (:func:`decrun.runner.job.hints.cli_message`); ``stage="app"`` (the app's checks, the
        operators, the run): a :class:`DecrunError` as :func:`name_the_key` names it.
        Anything else goes on as it is."""
        try:
            yield
        except DecrunError as exc:
            if stage == "complex":
                if not isinstance(exc, MeshError):
                    raise
                dimension = self.mesh.simplices.shape[1] - 1
                message = cli_message(exc, self.experiment.mesh_source, dimension)
                raise type(exc)(f"{self.where}: {message}") from exc
            named = name_the_key(exc, self.experiment, self.where)
            if named is exc:
                raise
            raise named from exc


#: the plugins the last sweep job of this process built, made anew for the next one when its
#: nodes have the same values (:class:`~decrun.runner.job.plugins.Recent`)
_RECENT = Recent()


def prepare(cfg: DictConfig, progress: Callable | None = None, out: Path | None = None, cache: bool = False) -> Run:
    """Everything before the app's work: build and check every plugin of ``cfg``
    (:func:`validate`), load the mesh, build the complex and the operators, and check them
    against the app (:meth:`decrun.apps.base.App.validate`). Raises :class:`DecrunError` on
    bad input, naming its key (:meth:`Run.naming_errors`).

    ``out``: the run directory (:func:`execute` then streams the app's records to its
    result.h5). With ``cache`` (sweep jobs) the mesh, complex and DEC come from the
    per-process cache :mod:`decrun.runner.io.job_cache` when an earlier job had the same
    mesh / operator / boundary config (``mesh_seconds`` is then 0), and a plugin node equal to
    the previous job's is made from that one's typed config (:class:`~decrun.runner.job.plugins.Recent`)."""
    t = time.perf_counter()
    experiment = validate(cfg, recent=_RECENT if cache else None)
    run = Run(cfg, experiment, RunFiles(out) if out is not None else None, progress or make_progress(False))
    with run.kernels():
        return _prepare(run, cache, t)


def _prepare(run: Run, cache: bool, t: float) -> Run:
    """:func:`prepare` after validation (``t`` its start), under the run's kernel switch."""
    cfg, experiment, timings = run.cfg, run.experiment, run.timings
    timings["mesh_seconds"] = 0.0

    def load_mesh():
        with task(run.progress, f"loading mesh={experiment.mesh_source.name}"):
            mesh = experiment.mesh_source.load()
        timings["mesh_seconds"] = time.perf_counter() - t
        return mesh

    def build_complex(mesh):
        run.mesh = mesh  # names the mesh in the complex's errors
        with run.naming_errors("complex"), task(run.progress, "building and checking the simplicial complex"):
            complex_ = SimplicialComplex(mesh.vertices, mesh.simplices, orient=experiment.mesh_source.orient)
        complex_.meta = mesh.meta
        return complex_

    def build_dec(complex_):
        return DEC(complex_, star=experiment.operator, boundary=experiment.boundary)

    if cache:
        run.mesh, run.complex, operators = mesh_and_dec(cfg, load_mesh, build_complex, build_dec)
    else:
        run.mesh = load_mesh()
        run.complex = build_complex(run.mesh)
        operators = functools.partial(build_dec, run.complex)
    with run.naming_errors():
        run.dec = experiment.app.validate(run.complex, experiment.solver, operators)
    timings["complex_seconds"] = time.perf_counter() - t - timings["mesh_seconds"]
    return run


def execute(run: Run) -> Run:
    """``app.run`` on the prepared ``run``; sets ``run.result`` (with ``status``, the app's
    ``warnings`` logged and joined into the metric ``warnings``,
    ``n_vertices``, ``n_faces`` and what ``mesh.clean``, ``mesh.largest_component`` and the
    holes' cut dropped among its metrics) and ``run.timings["app_seconds"]``.

    With ``run.files`` the app's ``ctx.record`` calls stream to its result.h5 through a
    :class:`~decrun.runner.results.recorder.ResultRecorder` (``run.recorder``; :func:`write`
    finishes it). If the app raises, the steps recorded so far are kept in an incomplete
    result.h5 (status failed / interrupted); nothing is written when nothing was recorded.
    Without ``run.files`` the recorded series end up in ``result.series``. A time-stepping
    app continues from ``run.files.checkpoint`` when it holds this config's state
    (``ctx.checkpoint``, :mod:`decrun.methods.stepping`)."""
    with run.kernels(), compile_notice():
        return _execute(run)


@contextmanager
def compile_notice():
    """While the block runs, a kernel numba must compile (its disk cache holds none for this
    install or this source: :data:`decrun.core.jit.compile_notice`) is said once in the log:
    the first step of a first run otherwise waits 10–150 s at "0 %" without a word."""
    def say(name: str) -> None:
        log.info("compiling decrun's numba kernels (%s first): once per install — numba caches the machine "
                 "code beside the modules and later runs load it in a second; this first time takes 10-150 s",
                 name)

    before, jit.compile_notice = jit.compile_notice, say
    try:
        yield
    finally:
        jit.compile_notice = before


def _execute(run: Run) -> Run:
    """:func:`execute` under the run's kernel switch."""
    t = time.perf_counter()
    mesh, complex_, app = run.mesh, run.complex, run.experiment.app
    if run.files is not None:
        run.recorder = ResultRecorder(run.files.result, vertices=mesh.vertices, simplices=mesh.simplices,
                                      edges=complex_.simplices(1), config_yaml=OmegaConf.to_yaml(run.cfg, resolve=True),
                                      mesh_hash=mesh.meta.get("hash", ""))
    ctx = RunContext(app, complex_, run.dec, new_solver=run.experiment.solver.fresh, meta=mesh.meta,
                     progress=run.progress, recorder=run.recorder, logger=log)
    if run.files is not None:
        ctx.checkpoint = RunCheckpoint(run.files.checkpoint, run.config_hash(), recorder=run.recorder,
                                       steps=run.experiment.checkpoint.steps,
                                       seconds=run.experiment.checkpoint.seconds, log=log.info)
    try:
        with run.naming_errors():
            result = app.run(ctx)
    except BaseException as exc:  # named already
        if run.recorder is not None:  # keep what was recorded, marked incomplete
            _abort(run.recorder, exc)
        raise
    if run.recorder is None:
        for name, values in ctx.series.items():
            result.series.setdefault(name, values)
    run.timings["app_seconds"] = time.perf_counter() - t
    result.metrics.setdefault("status", "ok")
    for warning in result.warnings:
        log.warning("warning: %s", warning)
    if result.warnings:
        result.metrics["warnings"] = "; ".join(result.warnings)
    result.metrics.setdefault("n_vertices", int(complex_.num_simplices(0)))
    result.metrics.setdefault("n_faces", int(complex_.num_simplices(complex_.dim)))
    for step in ("clean", "largest_component", "holes"):  # the steps that keep the largest piece: nothing
        for what in ("components", "dropped_vertices", "dropped_faces"):  # dropped unreported
            if f"{step}_{what}" in mesh.meta:
                result.metrics.setdefault(f"{step}_{what}", int(mesh.meta[f"{step}_{what}"]))
    chained = mesh.meta.get(CHAINED_STATUS) or ctx.chained_status  # chained from an incomplete result
    if chained:
        result.metrics.setdefault(CHAINED_STATUS, chained)
    run.result = result
    return run


def _abort(recorder: ResultRecorder, exc: BaseException) -> None:
    """Mark the run's result.h5 incomplete after ``exc`` (interrupted or failed, with its message)."""
    interrupted = isinstance(exc, KeyboardInterrupt)
    error = (f"interrupted ({interrupt_cause(exc)})" if interrupted else str(exc) if isinstance(exc, DecrunError)
             else f"{type(exc).__name__}: {exc}")
    try:
        recorder.abort("interrupted" if interrupted else "failed", error)
    except (OSError, RuntimeError) as write_error:  # e.g. the disk is full: report the first error
        if not isinstance(exc, OSError):
            exc.add_note(str(write_error))


def run_experiment(cfg: DictConfig, progress: Callable | None = None, out: Path | None = None, cache: bool = False
                   ) -> Run:
    """:func:`prepare` then :func:`execute`: the finished :class:`Run` of ``cfg`` (its files
    not written yet, :func:`write`)."""
    return execute(prepare(cfg, progress, out=out, cache=cache))


def write(run: Run, out: Path | None = None) -> list[Path]:
    """Write the finished ``run`` into its directory (``out`` when the run has none):
    ``result.h5`` (atomic; finishing the run's recorder when it has one) and ``metrics.json``
    (the metrics and ``result_h5``: the size and sha256 of result.h5 and the hash of its
    content, :func:`~decrun.runner.results.provenance.result_record`) first — the result is
    complete before any figure is drawn, so an interrupt while drawing (SIGTERM, Ctrl-C) keeps
    it (the interrupt carries ``result_complete``, and metrics.json, still ``status: ok``, gains
    :data:`FIGURES_INTERRUPTED` and :data:`FIGURES_NOT_DRAWN`) — then the figures (each written under a
    temporary name and renamed: none is left truncated), after removing the figures an earlier
    run left in the directory (:func:`remove_earlier_figures`), then the export's files (after
    removing an earlier run's, :func:`remove_earlier_exports`). A figure that cannot be drawn or
    saved loses neither: metrics.json gets :data:`FIGURES_ERROR` added, the export still runs,
    then :class:`FiguresFailed` is raised.
    ``total_seconds`` is the run's time up to its result; ``figures_seconds`` is logged."""
    files = run.files if out is None else RunFiles(out)
    if files is None:
        raise ValueError("write(run): the run has no directory; give one (out=...)")
    cfg, result, mesh, timings = run.cfg, run.result, run.mesh, run.timings
    assert result is not None  # write() follows execute(), which made the result
    timings["total_seconds"] = sum(v for k, v in timings.items() if k not in ("total_seconds", "figures_seconds"))
    result.metrics.setdefault("total_seconds", timings["total_seconds"])
    if run.recorder is not None:
        h5 = run.recorder.finish(result, timings)
    else:
        h5 = write_result(files.result, result, vertices=mesh.vertices, simplices=mesh.simplices,
                          edges=run.complex.simplices(1), config_yaml=OmegaConf.to_yaml(cfg, resolve=True),
                          mesh_hash=mesh.meta.get("hash", ""), timings=timings)
    # the size and sha256 of result.h5 as written (readers never take a truncated or altered one for it)
    # and the hash of its content, equal for two runs of one config (docs/running.md: "Reproducible records")
    record = {**result.metrics, RESULT_RECORD: result_record(h5)}
    metrics = write_metrics_json(files.metrics, record)
    drawn = bool(cfg.get("figures", True) and result.figures)
    written = []
    figures_failed = None
    t = time.perf_counter()
    try:
        remove_checkpoint(files.checkpoint)  # the run is complete: nothing to continue (nor a killed write's .tmp)
        removed = remove_earlier_figures(files.dir, result.figures if drawn else {})
        if removed:
            log.info("removed the earlier run's figures %s (they do not show this result)", ", ".join(removed))
        removed = remove_earlier_exports(files.dir)
        if removed:
            log.info("removed the earlier run's export files %s (they do not hold this result)", ", ".join(removed))
        if drawn:
            try:
                # lazy: matplotlib only for figures (start-up speed)
                from decrun.runner.plots.common import draw_figures

                written += draw_figures(result.figures, files.dir, run.complex)
            except Exception as exc:  # the result and metrics stand; the error is added to them (below)
                interrupt = find_in_chain(exc, KeyboardInterrupt)
                if interrupt is not None:  # Ctrl-C/SIGTERM inside an extension's import: its ImportError wraps it
                    raise interrupt from None
                figures_failed = FiguresFailed(_figures_message(exc), exc)
                record = {**record, FIGURES_ERROR: shorten_words(str(figures_failed))}
                write_metrics_json(files.metrics, record)
            else:
                log.info("figures: %s in %.1f s", ", ".join(p.name for p in written), time.perf_counter() - t)
    except KeyboardInterrupt as exc:  # the result is complete: the caller keeps it (see _run)
        not_drawn = [name for name in result.figures if drawn and not _drawn(files.dir, name)]
        exc.result_complete = not_drawn  # type: ignore[attr-defined]  # read by _run
        # the record says what is true: the run is ok (a sweep's resume keeps it), its figures were cut short
        write_metrics_json(files.metrics, {**record, FIGURES_INTERRUPTED: f"interrupted ({interrupt_cause(exc)})",
                                           FIGURES_NOT_DRAWN: not_drawn})
        raise
    timings["figures_seconds"] = time.perf_counter() - t
    export = run.experiment.export
    try:
        exported = export.write(files, result, mesh, run.complex, run.experiment.app) if export is not None else []
    except Exception as exc:  # the run is done: its metrics stay, the export's error is added to them
        message = str(exc) if isinstance(exc, DecrunError) else f"{type(exc).__name__}: {exc}"
        write_metrics_json(files.metrics, {**record, "export_error": shorten_words(message)})
        raise ExportFailed(message, exc) from exc
    if figures_failed is not None:
        raise figures_failed from figures_failed.cause
    return [h5, metrics, *written, *exported]


#: the metric a run whose figures failed carries (its message), beside its own metrics
FIGURES_ERROR = "figures_error"


class FiguresFailed(DecrunError):
    """Drawing or saving a figure failed after a finished run: result.h5 and metrics.json
    stand, with :data:`FIGURES_ERROR` added to the metrics (``cause``: the error)."""

    def __init__(self, message: str, cause: BaseException | None = None):
        super().__init__(message)
        self.cause = cause


def _figures_message(exc: BaseException) -> str:
    """``figures: <what failed>; figures=false runs without them``: the one line for a figure
    that could not be drawn or saved (an OS error as :func:`os_error_message` says it)."""
    os_error = None if isinstance(exc, DecrunError) else find_os_error(exc)
    if os_error is not None and os_error.filename2 is not None:  # os.replace onto the figure: name the figure
        os_error = OSError(os_error.errno, os_error.strerror, os_error.filename2)
    cause = (str(exc) if isinstance(exc, DecrunError) else os_error_message(os_error) if os_error is not None
             else f"{type(exc).__name__}: {exc}")
    return f"figures: {cause}; figures=false runs without them"


#: the endings of the figures a run draws (``<name>.png``; an animation's ``<name>.gif``)
FIGURE_ENDINGS = (".png", ".gif")
#: keys :func:`write` adds to a complete run's metrics.json (``status`` stays ``ok``) when an
#: interrupt stops its figures: the cause (``interrupted (SIGTERM)``) and the figures not drawn
FIGURES_INTERRUPTED = "figures_interrupted"
FIGURES_NOT_DRAWN = "figures_not_drawn"


def _drawn(directory: Path, name: str) -> bool:
    return any((Path(directory) / f"{name}{ending}").is_file() for ending in FIGURE_ENDINGS)


def remove_earlier_figures(directory: Path, figures: dict) -> list[str]:
    """Remove the figures (``*.png``, ``*.gif`` directly in the run directory, one with Hydra's
    ``.hydra/``: nowhere else) that an earlier run in ``directory`` drew and this run, whose result was just written, does not draw
    again under the same name (``figures``: this run's, empty when it draws none): they
    would show another result beside this one. Returns the names removed, sorted."""
    mine = {f"{name}{ending}" for name in figures for ending in FIGURE_ENDINGS}
    removed: list[str] = []
    if not (Path(directory) / RunFiles.HYDRA).is_dir():  # not a run directory the command made: not ours
        return removed
    for path in sorted(Path(directory).iterdir()):
        if path.suffix in FIGURE_ENDINGS and path.name not in mine and path.is_file() and not path.is_symlink():
            path.unlink()
            removed.append(path.name)
    return removed


#: the files an export writes (:mod:`decrun.runner.results.export`), any format
EXPORT_FILES = (RunFiles.VTU, RunFiles.XDMF, RunFiles.XDMF_DATA, RunFiles.XDMF_EDGES, RunFiles.XDMF_EDGES_DATA,
                RunFiles.PLY, RunFiles.OBJ)


def remove_earlier_exports(directory: Path) -> list[str]:
    """Remove the export files (:data:`EXPORT_FILES`) an earlier run left in the run directory
    ``directory`` (one with Hydra's ``.hydra/``), before this run's export writes its own: a
    ``result.vtu`` of another result beside this one would be read as this one's. Returns the
    names removed, in :data:`EXPORT_FILES` order."""
    removed: list[str] = []
    if not (Path(directory) / RunFiles.HYDRA).is_dir():  # not a run directory the command made: not ours
        return removed
    for name in EXPORT_FILES:
        path = Path(directory) / name
        if path.is_file() and not path.is_symlink():
            path.unlink()
            removed.append(name)
    return removed


def run(cfg: DictConfig, out: Path, *, multirun: bool = False, verbose: bool = False, log_name: str = "",
        made: Path | None = None) -> int | float:
    """One run (or one sweep job, ``multirun``) of ``cfg`` into the directory ``out``: the
    experiment (:func:`prepare`, :func:`execute`), its files (:func:`write`) and what it prints. Returns 0 (1 for a failed
    sweep job), or with ``optimize.metric`` set the objective
    :meth:`decrun.runner.job.config.OptimizeConfig.objective` for a sweeper; a failed single
    run exits 1 (an interrupted one 130/143) after recording its status in ``out``; an
    interrupted sweep job re-raises the interrupt, for the sweeper to say which jobs finished.
    ``verbose`` logs the traceback of a DecrunError; ``log_name`` is the job's log file
    (``<log_name>.log``, named in the closing line). ``made``: the caller made ``out`` for
    this run (it did not exist), and with it the parents up to ``made`` (``out`` itself, or
    e.g. ``outputs`` of a first ``outputs/runs/<stamp>``): a single run refused as bad input
    then removes ``out`` again, and those parents while they are empty.

    The run holds ``out``'s lock (:mod:`decrun.runner.io.locks`; a single run took it before
    Hydra made the directory) while it runs: when another process holds it, one line on
    stderr naming that process and nothing written (exit 1; a sweep job returns as failed)."""
    try:
        taken = out.is_dir() and acquire(out, "run", fix="choose another run directory with hydra.run.dir=DIR")
    except LockedError as exc:
        print(f"error: {exc}", file=sys.stderr)  # not the log: it is the other process's
        if multirun:
            return 1
        raise Stopped(f"error: {exc}") from exc
    fresh = made is not None and not multirun and _only_hydras_files(out, log_name)
    try:
        return _run(cfg, out, multirun=multirun, verbose=verbose, log_name=log_name)
    except Stopped as exc:
        if fresh and made is not None and getattr(exc, "refused", False) and \
                _only_hydras_files(out, log_name, RunFiles.METRICS):
            exc.leave_nothing = (out, made)  # removed below, once the lock is dropped
        raise
    finally:
        if taken:
            release(out)
        _remove_failed_attempt(sys.exc_info()[1])


def _only_hydras_files(out: Path, log_name: str, *more: str) -> bool:
    """Whether ``out`` holds nothing but what Hydra and the lock put there before the task
    (``.hydra/``, ``<log_name>.log``, the lock file) and ``more``: a directory this run made."""
    try:
        names = {p.name for p in out.iterdir()}
    except OSError:
        return False
    return names <= {RunFiles.HYDRA, f"{log_name}.log", RunFiles.LOCK, *more}


def _remove_failed_attempt(exc: BaseException | None) -> None:
    """A single run refused as bad input (a ConfigError, MeshError or TopologyError: a value
    typo, a missing file) in a directory made for it leaves no directory behind: the one line
    said everything, and ``outputs/runs`` keeps only runs that ran. A sweep job keeps its
    directory (the table's row needs its metrics.json); so does a run into a directory that
    existed before, or one that failed otherwise (out of memory, a full disk). The parents
    made with the run directory (``outputs/runs`` in a fresh folder, up to ``made`` of
    :func:`run`) go too while they are empty; one that holds anything, or existed before, stays."""
    import shutil

    left = getattr(exc, "leave_nothing", None)
    if left is None:
        return
    out, outermost = Path(left[0]).absolute(), Path(left[1]).absolute()
    shutil.rmtree(out, ignore_errors=True)
    if out.exists() or outermost not in out.parents:
        return
    for parent in out.parents:
        try:
            parent.rmdir()  # only an empty directory: another run's, or a file put there meanwhile, stops it
        except OSError:
            return
        if parent == outermost:
            return


def _run(cfg: DictConfig, out: Path, *, multirun: bool, verbose: bool, log_name: str) -> int | float:
    """:func:`run` once ``out`` is locked."""
    identity = {"config_hash": config_hash(cfg)} if multirun else {}  # ties metrics.json to the manifest
    earlier = file_identity(RunFiles(out).result)  # an earlier run's result, set aside if this one fails
    optimize = None
    try:
        optimize = root_options(cfg, "optimize", OptimizeConfig)
        progress = make_progress(bool(cfg["progress"] if "progress" in cfg else True) and not multirun)
        prepared = prepare(cfg, progress, out=out, cache=multirun)
        prepared.hashed = identity.get("config_hash")  # made above for a sweep job: not twice
        done = execute(prepared)
        result = done.result
        result.metrics.update(identity)
        written = write(done)
        objective = optimize.objective(result.metrics) if optimize.metric else 0
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM (failures.Terminated)
        cause = interrupt_cause(exc)
        missing = getattr(exc, "result_complete", None)
        if missing is not None:  # while drawing the figures: the result and metrics stand (status ok)
            said = (f"decrun: interrupted ({cause}) while drawing the figures; the run is complete: "
                    f"{RunFiles.RESULT} and {RunFiles.METRICS} in {out}; not drawn: {', '.join(missing) or 'none'}")
            print(said, file=sys.stderr)
            if multirun:  # a finished job for the sweeper (decrun.runner.sweep.stops): resume keeps it
                raise
            raise Stopped(said, exit_code(exc)) from exc
        note = set_aside_stale(out, earlier) + record_status(out, "interrupted", f"interrupted ({cause})", identity)
        said = f"decrun: interrupted ({cause}); what was recorded is in {out}/{note}"
        print(said, file=sys.stderr)
        if multirun:  # the sweeper says which jobs finished (decrun.runner.sweep.stops)
            raise
        raise Stopped(said, exit_code(exc)) from exc
    except (ExportFailed, FiguresFailed) as exc:  # after a finished run: result.h5 and the metrics stay (+ the error)
        said = (f"error: {exc} (the run finished: {RunFiles.RESULT} and {RunFiles.METRICS} in {out} keep its result "
                "and metrics)")
        log.error("%s", said)
        if multirun:
            return optimize.objective(None) if optimize is not None and optimize.metric else 1
        raise Stopped(said, 1) from exc
    except Exception as exc:
        unresolved = None if isinstance(exc, DecrunError) else resolution_message(exc, cfg)
        if unresolved is not None:  # an interpolation read outside the checks (progress=${oc.env:X}): no bug
            exc = ConfigError(unresolved)
        os_error = None if isinstance(exc, DecrunError) else find_os_error(exc)
        memory = None if isinstance(exc, DecrunError) or os_error is not None else find_memory_error(exc)
        message = (str(exc) if isinstance(exc, DecrunError) else os_error_message(os_error) if os_error is not None
                   else memory_message(memory, cfg) if memory is not None else f"{type(exc).__name__}: {exc}")
        message = shorten_words(message)  # a 120 kB value stays out of the line, the log and metrics.json
        note = set_aside_stale(out, earlier) + record_status(out, "failed", message, identity)
        if verbose or not (isinstance(exc, DecrunError) or os_error is not None or memory is not None):
            log.exception("error: %s%s", message, note)
        else:
            log.error("error: %s%s", message, note)
        if multirun:
            return optimize.objective(None) if optimize is not None and optimize.metric else 1
        stopped = Stopped(f"error: {message}{note}")
        # bad input (a config value, a mesh): the attempt leaves nothing (see run); not a full disk
        stopped.refused = isinstance(exc, (ConfigError, MeshError, TopologyError)) and find_os_error(exc) is None
        raise stopped from exc
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
        warned = f"; warning: {metrics['warnings']}" if metrics.get("warnings") else ""
        verdict = unstable_verdict(metrics)
        if verdict:  # a line of its own: a diverged run is not an answer
            print(verdict)
        print(f"decrun: wrote {where}/ ({', '.join(p.name for p in written)}, {log_name}.log){warned}")
    return 0


def memory_message(exc: BaseException, cfg: DictConfig) -> str:
    """``<where>: could not allocate <size> for an array of shape (…) <dtype>; <the setting
    to lower>`` for a run that ran out of memory (:func:`decrun.runner.job.failures.memory_error_text`,
    :func:`decrun.runner.job.hints.memory_hint`); ``where`` names the app and the mesh source."""
    where = f"app={plugin_name(cfg, 'app') or '?'} on mesh={plugin_name(cfg, 'mesh') or '?'}"
    hint = memory_hint(cfg, getattr(exc, "shape", None))
    return f"{where}: {memory_error_text(exc)}" + (f"; {hint}" if hint else "")


def _short(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)
