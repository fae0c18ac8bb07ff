"""Newton and block-system solves whose unknowns have Dirichlet values that read ``t`` (issue #47,
item 4): the fixed values g(t) are taken at the environment's t, everything else stays as compiled.

- A Newton solve (:class:`~decrun.methods.model.nonlinear.NonlinearSolve`) of ``lhs(u) = rhs``
  iterates on the free values u_F with u_D = g(t) in F(u_F) = lhs(u_F, g(t))_F − rhs_F; its
  Jacobian ∂F/∂u_F is the same derivative rule, evaluated at that u.
- A block system (:class:`~decrun.methods.model.passes.systems.SystemSolve`) solves
  A_FF x_F = b_F − A_FD g(t): its matrix A is factorized once, at the first solve, and only the
  condensed right side changes with t.

Each gets ``moving_values``: t ↦ the stacked fixed values of its unknowns (in the order of the
unknowns, as its ``fixed_values``), g(t) at the border vertices of each moving field and the
compiled static values of the others. A plain linear solve reads them through its right side
(:func:`decrun.methods.model.borders._moving_rhs`).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["fixed_values_at", "take_moving_values"]


def fixed_values_at(model, unknowns, moving: dict) -> Callable[[float], np.ndarray]:
    """t ↦ (m,) the fixed values of ``unknowns`` (those in ``model.fixed``, in order, stacked):
    ``moving[u].at(border vertices, t)`` for a field u with moving values, its static values
    otherwise. ``moving`` maps field → :class:`~decrun.methods.model.borders.BorderExpression`."""
    vertices = model.ops.K.vertices
    parts = []
    for name in unknowns:
        if name in model.fixed:
            border, static = model.fixed[name]
            parts.append((moving.get(name), vertices[border], np.asarray(static, dtype=np.float64)))

    def at(t: float) -> np.ndarray:
        return np.concatenate([values if g is None else g.at(points, t) for g, points, values in parts])
    return at


def take_moving_values(what: str, item, model, moving: dict) -> None:
    """Give a ``"newton"`` or ``"system"`` entry of ``model.order`` its ``moving_values`` (module
    docstring): its fixed values read at each solve's t."""
    unknowns = tuple(item.unknowns) if what == "system" else (item.unknown,)
    item.moving_values = fixed_values_at(model, unknowns, moving)
