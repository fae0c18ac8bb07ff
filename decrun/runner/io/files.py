"""Every file name of a run directory and of a sweep directory, in one place.

A run directory (``outputs/runs/<stamp>/``, or one sweep job's ``outputs/sweeps/<stamp>/<job>/``)
holds the files of :class:`RunFiles`; a sweep's root those of :class:`SweepFiles`. Code
that writes, reads, clears or globs one of them takes its name from here, never from a
literal: ``RunFiles(out).result`` (the path) or ``RunFiles.RESULT`` (the name, for a
glob or a message).

Adding a file (a checkpoint, say): one name attribute with its ``#:`` comment saying what
it holds and who writes it, one path property made with :func:`_path`, and — when a rerun
of a sweep job must not inherit it — its name in :attr:`RunFiles.JOB_OUTPUTS`.

Hydra's own files (``.hydra/`` and the log) are named by the Hydra config:
:func:`decrun.runner.io.paths.hydra_files` reads their names from it; :attr:`RunFiles.HYDRA` is
Hydra's default name (decrun's conf keeps it), for code that has no config (a sweep's
table, clearing a job to rerun it).

Imports nothing but :mod:`pathlib`: the ``decrun`` command imports it before numpy.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["RunFiles", "SweepFiles"]


def _path(name: str, doc: str) -> property:
    """A read-only property: the directory joined with the class attribute ``name``."""
    return property(lambda self: self.dir / getattr(self, name), doc=doc)


class RunFiles:
    """The files of the run directory ``dir``: each one a name (class attribute) and a path
    (property of the same name in lower case)."""

    #: the run's result: mesh, fields, series, metrics and provenance (HDF5, written
    #: atomically; :mod:`decrun.runner.results.recorder`)
    RESULT = "result.h5"
    #: the append-only journal of the series recorded so far, beside the result while a
    #: run records (:func:`decrun.runner.results.journal.journal_path`)
    JOURNAL = RESULT + ".partial"
    #: an earlier run's result set aside by a run that failed in the same directory
    #: (:func:`decrun.runner.job.failures.set_aside_stale`)
    STALE = RESULT + ".stale"
    #: the hidden temporary names of an atomic write of the result (``.result.h5.tmp-<pid>``,
    #: :func:`decrun.runner.io.atomic.temporary_name`), as a glob
    RESULT_TEMPORARIES = "." + RESULT + "*"
    #: the last recorded state of a time-stepping run, to continue it after a kill
    #: (:mod:`decrun.runner.results.checkpoint`, :mod:`decrun.methods.stepping`); deleted when
    #: the run is complete
    CHECKPOINT = "checkpoint.h5"
    #: the metrics (JSON), with the size and sha256 of the result, or the status and error
    #: of a run that did not finish
    METRICS = "metrics.json"
    #: Hydra's output subdirectory (``hydra.output_subdir``, Hydra's default; ``overrides.yaml`` ...)
    HYDRA = ".hydra"
    #: the lock a run or sweep holds on its directory (:mod:`decrun.runner.io.locks`)
    LOCK = ".decrun.lock"
    #: one figure, ``<name>.png`` (:func:`decrun.runner.plots.common.draw_figures`)
    FIGURE = "{name}.png"
    #: every figure, as a glob
    FIGURES = "*.png"
    #: every animation (``<name>.gif``, :func:`decrun.runner.plots.snapshots`), as a glob
    ANIMATIONS = "*.gif"
    #: ``export=vtu``: the mesh with every field (:class:`decrun.runner.results.export.Vtu`)
    VTU = "result.vtu"
    #: ``export=xdmf``: the recorded series over the mesh, with the heavy data in
    #: :attr:`XDMF_DATA` beside it (meshio's TimeSeriesWriter names it after the stem)
    XDMF = "series.xdmf"
    XDMF_DATA = "series.h5"
    #: ``export=xdmf``: the series on edges (line cells), with :attr:`XDMF_EDGES_DATA`
    XDMF_EDGES = "series_edges.xdmf"
    XDMF_EDGES_DATA = "series_edges.h5"
    #: ``export=ply`` / ``export=obj``: the surface with one field as colours / the surface
    PLY = "result.ply"
    OBJ = "result.obj"
    #: ``tracker=mlflow``: the id of the tracker's run of this job, per store, kept across a
    #: resumed sweep's rerun (:mod:`decrun.runner.tracking`)
    TRACKING = "tracking.json"

    #: what a sweep job's directory may hold that a rerun of the job must not inherit
    #: (besides the figures and the result's temporaries; :mod:`decrun.runner.sweep.sweeper`)
    JOB_OUTPUTS = (METRICS, RESULT, JOURNAL, STALE)

    def __init__(self, dir: str | os.PathLike):
        self.dir = Path(dir)

    result = _path("RESULT", "The run's result.h5.")
    journal = _path("JOURNAL", "The journal of the result being recorded.")
    stale = _path("STALE", "An earlier run's result, set aside.")
    metrics = _path("METRICS", "The run's metrics.json.")
    checkpoint = _path("CHECKPOINT", "The last recorded state of a time-stepping run.")
    lock = _path("LOCK", "The directory's lock file.")
    vtu = _path("VTU", "export=vtu's file.")
    xdmf = _path("XDMF", "export=xdmf's series on the mesh's cells.")
    xdmf_edges = _path("XDMF_EDGES", "export=xdmf's series on edges.")
    ply = _path("PLY", "export=ply's file.")
    obj = _path("OBJ", "export=obj's file.")
    tracking = _path("TRACKING", "The tracker's run id of this run.")

    def figure(self, name: str) -> Path:
        """The figure ``<name>.png``."""
        return self.dir / self.FIGURE.format(name=name)

    def __repr__(self) -> str:
        return f"RunFiles({str(self.dir)!r})"


class SweepFiles:
    """The files at the root of the sweep directory ``dir`` (the jobs' directories below it
    hold :class:`RunFiles`)."""

    #: the plan of the sweep and each job's state (:mod:`decrun.runner.sweep.manifest`)
    MANIFEST = "manifest.json"
    #: the sweep's composed config, as Hydra's basic sweeper writes it
    MULTIRUN = "multirun.yaml"
    #: the table of the jobs' metrics, one row per job (:mod:`decrun.runner.sweep.tables`)
    TABLE_CSV = "metrics.csv"
    TABLE_MD = "metrics.md"
    #: ``tracker=mlflow``: the id of the tracker's run of the whole sweep, per store
    TRACKING = "tracking.json"

    def __init__(self, dir: str | os.PathLike):
        self.dir = Path(dir)

    manifest = _path("MANIFEST", "The sweep's manifest.json.")
    multirun = _path("MULTIRUN", "The sweep's multirun.yaml.")
    table_csv = _path("TABLE_CSV", "The sweep's metrics.csv.")
    table_md = _path("TABLE_MD", "The sweep's metrics.md.")
    tracking = _path("TRACKING", "The tracker's run id of the sweep.")

    def __repr__(self) -> str:
        return f"SweepFiles({str(self.dir)!r})"
