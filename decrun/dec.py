"""Public home of :class:`DEC` (implemented in :mod:`decrun.core.dec`)."""

from decrun.core.dec import DEC  # noqa: F401

__all__ = ["DEC"]
