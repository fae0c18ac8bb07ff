"""The fluid's closed option sets (``app.initial``, ``app.velocity``, ``app.circulation``,
``app.walls``, ``app.kernels`` and the backtracking integrator): they name the method's own
variants, so they live with the method (the layers: core <- methods <- apps) and
:mod:`decrun.apps.fluid` imports them. :class:`FluidOptions` is the scheme's choices together,
validated once — each a member of its set, and the two combinations that are unstable refused —
for the app (``key="app"``: messages name ``app.<option>``) and for
:class:`decrun.methods.fluid.simulation.VorticityFluid` alike.
Light on purpose (no numerical import): composing a config reads them for hints."""

from __future__ import annotations

from dataclasses import dataclass

from decrun.core.choices import Choice
from decrun.errors import ConfigError

__all__ = ["Initial", "Velocity", "Circulation", "Kernels", "Walls", "Backtracking", "Intervals", "SWEPT",
           "FluidOptions"]


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
    complex, operators and the fluid): ``auto`` (``DECRUN_NUMBA`` if set, else compiled) or ``numba``
    (every compiled kernel: the fluid's numba kernels, decrun/methods/fluid/compiled.py, and the core's
    compiled extension, decrun.core.extension) or ``numpy`` (their reference twins; numba is not
    imported); the same run, bit for bit."""

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


class Backtracking(Choice):
    """The integrator of the backtracking walk (decrun/methods/fluid/backtrack.py): ``midpoint``,
    ``euler`` or ``per_triangle`` (the thesis' Fig. 7.9, one constant velocity per triangle)."""

    midpoint = "midpoint"
    euler = "euler"
    per_triangle = "per_triangle"


class Intervals(Choice):
    """``app.intervals``: how the swept circulation rules split dt into backtracking intervals
    (decrun/methods/fluid/simulation.py). ``uniform``: k equal intervals for every point, k set by
    the largest CFL number of any point. ``per_point``: K intervals (the smallest 2^a or 3·2^a ≥ that
    k); each point walks the fewest k_p of them that divide K and keep it within ``swept_cfl`` edge
    lengths per interval, and its positions at the K boundaries in between are interpolated
    linearly (a dual side's swept quads then follow the finer of its two ends)."""

    uniform = "uniform"
    per_point = "per_point"


#: the circulation rules that backtrack in intervals and sum the swept vorticity (swept.py)
SWEPT = (Circulation.swept_bounded, Circulation.swept_clamped, Circulation.swept)


@dataclass(frozen=True)
class FluidOptions:
    """The fluid scheme's closed choices, each a member of its set, validated once here.

    Two combinations are refused: ``walls=slip`` with a trapezoid circulation (those rules take
    the wall velocity at the fixed border points, so a slip wall cannot be expressed) and
    ``velocity=least_squares`` with a trapezoid circulation (unstable: its trapezoid circulation
    grew the enstrophy ×14 in 5 s on a sphere). ``key`` prefixes the option names in messages
    (``"app"``: ``app.walls``; ``""``: the keyword names of a Python caller).
    """

    velocity: Velocity = Velocity.least_squares
    circulation: Circulation = Circulation.swept_bounded
    walls: Walls = Walls.auto
    kernels: Kernels = Kernels.auto
    integrator: Backtracking = Backtracking.midpoint
    intervals: Intervals = Intervals.uniform
    key: str = ""

    def __post_init__(self):
        for option, kind in (("velocity", Velocity), ("circulation", Circulation), ("walls", Walls),
                             ("kernels", Kernels), ("integrator", Backtracking), ("intervals", Intervals)):
            object.__setattr__(self, option, kind.of(getattr(self, option), self.name(option)))
        walls, circulation, velocity = self.name("walls"), self.name("circulation"), self.name("velocity")
        if self.walls == Walls.slip and not self.swept:
            raise ConfigError(f"{walls}=slip needs a swept circulation ({circulation}={self.circulation} takes "
                              f"the wall velocity at the border points); use {walls}=no_slip")
        if self.velocity == Velocity.least_squares and not self.swept:
            raise ConfigError(f"{circulation}={self.circulation} with {velocity}=least_squares is unstable; "
                              f"use {velocity}=wshd07 (the thesis' pair: {velocity}=wshd07 "
                              f"{circulation}=trapezoid)")

    def name(self, option: str) -> str:
        """The option's name in messages: ``<key>.<option>``, or ``<option>`` without a key."""
        return f"{self.key}.{option}" if self.key else option

    @property
    def swept(self) -> bool:
        """The circulation is one of the swept rules (:data:`SWEPT`)."""
        return self.circulation in SWEPT

    def resolved_walls(self, viscosity: float) -> Walls:
        """``walls`` with ``auto`` resolved: ``slip`` at ν = 0 with a swept circulation, else ``no_slip``."""
        if self.walls != Walls.auto:
            return self.walls
        return Walls.slip if float(viscosity) == 0.0 and self.swept else Walls.no_slip
