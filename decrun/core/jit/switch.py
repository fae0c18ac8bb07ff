"""The kernel switch: ``auto`` | ``numba`` | ``numpy``, from ``app.kernels`` (:func:`use`) or
``DECRUN_NUMBA`` (:func:`mode`), and whether a kernel runs for an input of a given size
(:func:`enabled`; the package docstring says how the three words are read)."""

from __future__ import annotations

import os
from contextlib import contextmanager
from typing import Iterator

from decrun.errors import ConfigError

__all__ = ["MIN_SIZE", "MODES", "check_mode", "mode", "use", "enabled"]

#: inputs from this many items (simplices, faces, rows) on take the compiled kernels under ``auto``
MIN_SIZE = 500_000

#: the switch's values
MODES = ("auto", "numba", "numpy")

_ENV = {"": "auto", "auto": "auto", "numba": "numba", "1": "numba", "numpy": "numpy", "0": "numpy"}

_override: list[str] = []  # the modes :func:`use` set, innermost last


def check_mode(value: str, where: str = "app.kernels") -> str:
    """``value`` if it is one of :data:`MODES`, else a ConfigError naming ``where``."""
    if value not in MODES:
        raise ConfigError(f"{where}: must be one of {list(MODES)}, got {value!r}; use {where}=auto")
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


def enabled(size: int | None = None, min_size: int = MIN_SIZE, kernels: str = "auto") -> bool:
    """Whether to run the kernel for an input of ``size`` items (None: any size): ``kernels``
    (a caller's own setting) unless ``auto``, else :func:`mode`; under ``auto`` from ``min_size``
    items on."""
    setting = check_mode(kernels, "kernels") if kernels != "auto" else mode()
    if setting != "auto":
        return setting == "numba"
    return size is None or size >= min_size
