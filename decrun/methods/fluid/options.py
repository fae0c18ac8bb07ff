"""The fluid's closed option sets (``app.initial``, ``app.velocity``, ``app.circulation``,
``app.walls``, ``app.kernels``): they name the method's own variants, so they live with the method
(the layers: core <- methods <- apps) and :mod:`decrun.apps.fluid` imports them.
Light on purpose (no numerical import): composing a config reads them for hints."""

from __future__ import annotations

from decrun.core.choices import Choice

__all__ = ["Initial", "Velocity", "Circulation", "Kernels", "Walls"]


class Initial(Choice):
    """``app.initial``: the vorticity at t = 0 (``rotation`` and ``vortex_pair`` on the unit
    sphere; ``mesh_field`` from ``mesh=result mesh.field=...``)."""

    zero = "zero"
    rotation = "rotation"
    vortex_pair = "vortex_pair"
    random = "random"
    mesh_field = "mesh_field"


class Velocity(Choice):
    """``app.velocity``: the velocity reconstruction (decrun/methods/fluid/reconstruction.py):
    ``least_squares`` or ``wshd07``, the thesis' interpolation (§7.2.3)."""

    least_squares = "least_squares"
    wshd07 = "wshd07"


class Circulation(Choice):
    """``app.circulation``: the circulation of the back-traced dual cells
    (decrun/methods/fluid/simulation.py): ``swept_bounded`` (swept, energy and enstrophy bounded
    by the previous step's without inflow; decrun/methods/fluid/limiter.py), ``swept_clamped``
    (also a local clamp), ``swept``, ``corrected_trapezoid`` or ``trapezoid``, the thesis' rule."""

    swept_bounded = "swept_bounded"
    swept_clamped = "swept_clamped"
    swept = "swept"
    corrected_trapezoid = "corrected_trapezoid"
    trapezoid = "trapezoid"


class Kernels(Choice):
    """``app.kernels``: the one kernel switch of decrun.core.jit for the whole run (mesh,
    complex, operators and the fluid): ``auto`` (``DECRUN_NUMBA`` if set, else the fluid's loops
    compiled and the core's from 500k simplices on), ``numba`` (every compiled kernel,
    decrun/methods/fluid/compiled.py and the core's) or ``numpy`` (their reference twins; numba
    is not imported); the same run, bit for bit."""

    auto = "auto"
    numba = "numba"
    numpy = "numpy"


class Walls(Choice):
    """``app.walls``: the condition at walls (obstacles; the outer border without inflow).
    ``slip`` is the Euler condition (u·n = 0; walls make no vorticity; the swept change runs in
    every cell), ``no_slip`` the thesis' border cells (trapezoid circulation with the wall at rest,
    §7.2.4: walls shed vorticity); ``auto`` is ``slip`` at ν = 0 with a swept circulation (at
    ν = 0 the no-slip wall is a vortex sheet of strength |v| at every wall, ~|v|/h per border
    cell: the inviscid channels diverged) and ``no_slip`` otherwise."""

    auto = "auto"
    slip = "slip"
    no_slip = "no_slip"
