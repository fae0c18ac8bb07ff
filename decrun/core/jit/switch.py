"""The kernel switch: ``auto`` | ``numba`` | ``numpy``, from ``app.kernels`` (:func:`use`) or
``DECRUN_NUMBA`` (:func:`mode`), and whether a numba kernel runs (:func:`enabled`; the package
docstring says how the three words are read), and whether one ran in this process (:func:`started`)."""

from __future__ import annotations

import os
from contextlib import contextmanager
from typing import Iterator

from decrun.core.choices import choice_error
from decrun.errors import ConfigError

__all__ = ["MODES", "check_mode", "mode", "use", "enabled",
           "started", "mark_started"]

#: the switch's values
MODES = ("auto", "numba", "numpy")

_ENV = {"": "auto", "auto": "auto", "numba": "numba", "1": "numba", "numpy": "numpy", "0": "numpy"}

_override: list[str] = []  # the modes :func:`use` set, innermost last
_started = False  # a kernel ran in this process: numba's one-time start is paid


def check_mode(value: str, where: str = "app.kernels") -> str:
    """``value`` if it is one of :data:`MODES`, else a ConfigError naming ``where``."""
    if value not in MODES:
        raise choice_error(where, value, MODES)
    return value


def mode() -> str:
    """The switch in force: the innermost :func:`use` that is not ``auto``, else ``DECRUN_NUMBA``."""
    for value in reversed(_override):
        if value != "auto":
            return value
    setting = os.environ.get("DECRUN_NUMBA", "").strip().lower()
    if setting not in _ENV:
        raise ConfigError(f"DECRUN_NUMBA={setting!r}: must be one of auto, numba, numpy (or 1, 0); "
                          "use DECRUN_NUMBA=auto")
    return _ENV[setting]


@contextmanager
def use(value: str) -> Iterator[None]:
    """Within the block the switch is ``value`` (``auto`` defers to ``DECRUN_NUMBA``)."""
    _override.append(check_mode(str(value)))
    try:
        yield
    finally:
        _override.pop()


def enabled(kernels: str = "auto") -> bool:
    """Whether to run the numba kernels: ``kernels`` (a caller's own setting) unless ``auto``,
    else :func:`mode`; ``auto`` runs them."""
    setting = check_mode(kernels, "kernels") if kernels != "auto" else mode()
    return setting != "numpy"


def started() -> bool:
    """Whether a kernel ran in this process (numba imported and started: later kernels are cheap)."""
    return _started


def mark_started() -> None:
    """A kernel ran in this process (:class:`.kernels.LazyKernel` after each call): :func:`started`."""
    global _started
    _started = True
