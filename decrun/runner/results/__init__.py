"""Result files: ``result.h5`` streamed while a run goes and finished atomically
(:mod:`.recorder`, on the append-only :mod:`.journal`), read back complete or not
(:mod:`.reading`), with their provenance and ``metrics.json`` (:mod:`.provenance`).

Applications never touch the disk; the runner streams a run's recorded series and writes
its :class:`~decrun.apps.base.Result` through :class:`ResultRecorder`, whose module
docstring gives the layout of ``result.h5`` (mesh, fields — 1-forms with
``form_degree = 1`` and ``on = "mesh/edges"`` — series, metrics, provenance attributes)
and the crash semantics: ``result.h5`` is either absent or whole; a killed run leaves its
recorded steps readable (:func:`read_result`, ``.complete`` False).

Layers (tests/test_layers.py): ``recorder | reading | checkpoint > journal | provenance > checked``
(:mod:`.checked`: the checked readers every file read back goes through).
"""

from decrun.apps.base import Result
from decrun.runner.results.provenance import read_provenance, write_metrics_json
from decrun.runner.results.reading import RecordedResult, read_mesh, read_result
from decrun.runner.results.recorder import ResultRecorder, ResultWriteError, recover_result, write_result

__all__ = ["Result", "write_result", "read_result", "read_provenance", "read_mesh", "write_metrics_json",
           "recover_result", "RecordedResult", "ResultRecorder", "ResultWriteError"]
