"""The runner's application context: series streamed to ``result.h5`` as the run goes."""

from __future__ import annotations

from pathlib import Path

from decrun.apps.base import Context
from decrun.errors import ConfigError, CorruptFileError
from decrun.runner.results import read_mesh, read_result
from decrun.runner.results.reading import chained_status

__all__ = ["RunContext"]


class RunContext(Context):
    """:class:`decrun.apps.base.Context` whose ``record`` appends to the run's result file
    (``recorder.record``), so memory stays flat and a killed run keeps what it recorded."""

    def __init__(self, *args, recorder=None, logger=None, **kwargs):
        super().__init__(*args, **kwargs)
        self.recorder = recorder
        self.logger = logger
        #: the status of an incomplete result read by :meth:`read_result` ("" when none was,
        #: or it was complete): the run's metric ``chained_result_status``
        self.chained_status = ""

    def record(self, step: int, **values) -> None:
        if self.recorder is None:
            super().record(step, **values)
        else:
            self.recorder.record(step, **values)

    def read_result(self, path: str):
        """``(Result, vertices)`` of a previous run's result.h5 (complete or not: an
        incomplete one is said in one warning and kept in :attr:`chained_status`)."""
        if not Path(path).is_file():
            raise ConfigError(f"app.input_path: no result file at {str(path)!r}")
        try:
            result = read_result(path)
            vertices, _ = read_mesh(path)
        except CorruptFileError as exc:  # names the file and what is wrong with it
            raise ConfigError(f"app.input_path={str(path)!r}: {exc}") from None
        except KeyError as exc:  # h5py: a group or attribute of the layout is missing
            raise ConfigError(f"app.input_path={str(path)!r}: an HDF5 file but not a decrun result.h5 "
                              f"({_first_line(exc)})") from None
        except (OSError, ValueError, TypeError) as exc:  # not HDF5, truncated, corrupt, damaged JSON
            raise ConfigError(f"app.input_path={str(path)!r}: cannot read it as a decrun result.h5 "
                              f"({_first_line(exc)})") from None
        warn = self.logger.warning if self.logger is not None else self.log
        self.chained_status = chained_status(result, f"app.input_path={str(path)!r}", warn) or self.chained_status
        return result, vertices

    def log(self, message: str) -> None:
        if self.logger is not None:
            self.logger.info(message)
        else:
            super().log(message)


def _first_line(exc: BaseException) -> str:
    """The first line of an exception's message (h5py's KeyError text is quoted)."""
    text = (exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)) or type(exc).__name__
    return str(text).strip().splitlines()[0]
