"""The Jacobian SciPy's BDF and Radau get for a Galerkin (non-diagonal) mass: the exact sparse ∂f/∂y
of M y' = f(y, t) divided by the lumped mass, J ≈ M_L⁻¹ ∂f/∂y with M_L = diag(M 1) (M's row sums).

With a Whitney ⋆0 the true Jacobian M⁻¹ ∂f/∂y of y' = M⁻¹ f is dense, and finite differences on the
equations' sparsity pattern approximate it poorly (many rejected Newton iterations and small steps).
M_L⁻¹ ∂f/∂y keeps ∂f/∂y's sparsity and the spectrum's scale (M_L and M agree on constants: M_L 1 = M 1).
The Jacobian only steers SciPy's Newton iterations and step sizes; the right side SciPy integrates
is still M⁻¹ f, so the answer stays within the tolerance asked. Used by the fixed-border path
(:class:`~decrun.methods.model.integrators.Adaptive`, over every evolved value) and the moving one
(:class:`~decrun.methods.model.moving_steppers.MovingSciPy`, over the free values).
"""

from __future__ import annotations

from typing import Callable, Optional

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.language import ModelError

__all__ = ["lumped_jacobian", "lumped_jacobian_of_model"]


def lumped_jacobian(problem) -> Optional[Callable[[float, np.ndarray], sp.csc_matrix]]:
    """``jac(t, y) -> csc (size, size)``: M_L⁻¹ ∂f/∂y over the free values y of ``problem`` (a
    :class:`~decrun.methods.model.problem.ModelProblem` or a
    :class:`~decrun.methods.model.borders.MovingProblem`), M_L the row sums of its mass M_FF and
    ∂f/∂y its exact ``jacobian(y, t)``. None when the mass is diagonal (the exact Jacobian is sparse
    then), when a term has no derivative rule, or when a row sum is not positive (the equations'
    pattern is used then)."""
    mass = problem.mass
    if mass is None or (mass - sp.diags(mass.diagonal())).count_nonzero() == 0:
        return None
    try:
        problem.check_jacobian()
    except ModelError:
        return None
    row_sums = np.asarray(mass.sum(axis=1)).ravel()
    if not np.all(row_sums > 0):
        return None
    inverse = sp.diags(1.0 / row_sums)

    def jacobian(t: float, y: np.ndarray) -> sp.csc_matrix:
        return (inverse @ problem.jacobian(np.asarray(y, dtype=np.float64), t)).tocsc()
    return jacobian


def lumped_jacobian_of_model(model) -> Optional[Callable[[float, np.ndarray], sp.csc_matrix]]:
    """``jac(t, x) -> csc (total, total)`` over every evolved value x (border values included), as
    the fixed-border path steps them: :func:`lumped_jacobian` of the model's problem at the free
    rows and columns, 0 in the rows of the fixed values (they do not move); None as there."""
    problem = model.problem
    free_jacobian = lumped_jacobian(problem)
    if free_jacobian is None:
        return None
    free, total = problem.free, problem.total
    embed = sp.csr_matrix((np.ones(free.size), (free, np.arange(free.size))), shape=(total, free.size))
    embed_transpose = embed.T.tocsr()

    def jacobian(t: float, x: np.ndarray) -> sp.csc_matrix:
        return (embed @ free_jacobian(t, np.asarray(x)[free]) @ embed_transpose).tocsc()
    return jacobian
