"""The runner's application context: series streamed to ``result.h5`` as the run goes."""

from __future__ import annotations

from decrun.apps.base import Context

__all__ = ["RunContext"]


class RunContext(Context):
    """:class:`decrun.apps.base.Context` whose ``record`` appends to the run's result file
    (``recorder.record``), so memory stays flat and a killed run keeps what it recorded."""

    def __init__(self, *args, recorder=None, logger=None, **kwargs):
        super().__init__(*args, **kwargs)
        self.recorder = recorder
        self.logger = logger

    def record(self, step: int, **values) -> None:
        if self.recorder is None:
            super().record(step, **values)
        else:
            self.recorder.record(step, **values)

    def read_result(self, path: str):
        """``(Result, vertices)`` of a previous run's result.h5 (complete or not)."""
        from pathlib import Path

        from decrun.errors import ConfigError
        from decrun.runner.results import read_mesh, read_result

        if not Path(path).is_file():
            raise ConfigError(f"app.input_path: no result file at {str(path)!r}")
        result = read_result(path)
        vertices, _ = read_mesh(path)
        return result, vertices

    def log(self, message: str) -> None:
        if self.logger is not None:
            self.logger.info(message)
        else:
            super().log(message)
