"""The vorticity fluid solver of thesis ch. 7 (Elcott et al. 2007) as pure numerics.

Public API: :class:`VorticityFluid` (simulation.py), the initial-vorticity and stirring
helpers (initial.py), the dual cells (dual_cells.py), the WSHD07 interpolation
(interpolation.py), the backtracking walk (backtrack.py) and the harmonic part
(harmonic.py).
"""

from decrun.methods.fluid.simulation import VorticityFluid

__all__ = ["VorticityFluid"]
