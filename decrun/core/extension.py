"""The core's compiled kernels: the extension ``decrun.core._kernels`` (Cython), built by the install.

The kernels of the complex and its operators (row sorting and grouping, facet pairs,
orientation, vertex fans, volumes, dual volumes, incidence) and the intrinsic Delaunay flip
rounds run as machine code that loads with its module, in milliseconds. Each has a numpy twin
beside its caller: the reference the tests hold it to bit for bit (``tests/core/test_extension.py``)
and the fallback where the install built no extension (no C compiler) or the switch says
``numpy`` (``app.kernels`` / ``DECRUN_NUMBA``, :func:`decrun.core.jit.mode`; ``auto`` and
``numba`` take the extension at every size). numba compiles only the fluid's kernels
(:mod:`decrun.core.jit`, :mod:`decrun.methods.fluid.compiled`).
"""

from __future__ import annotations

from types import ModuleType

from decrun.core.jit.switch import mode

__all__ = ["built", "kernels"]

_searched = False
_module: ModuleType | None = None


def built() -> ModuleType | None:
    """The extension module, imported once; None when the install built none."""
    global _searched, _module
    if not _searched:
        try:
            from decrun.core import _kernels  # type: ignore[attr-defined]
        except ImportError:
            _module = None
        else:
            _module = _kernels
        _searched = True
    return _module


def kernels() -> ModuleType | None:
    """The extension where a core kernel runs compiled: built, and the switch is not ``numpy``."""
    return built() if mode() != "numpy" else None
