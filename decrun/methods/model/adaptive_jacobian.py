"""The exact Jacobian of a model's strong right side F(u) = M⁻¹ Σ_v A_uv v + R_u (every evolved
value, border values included), for SciPy's BDF and Radau (``jac`` of ``solve_ivp``).

With diagonal row masses M_u (⋆0, the circumcentric ⋆k) it is sparse:
∂F/∂u = M⁻¹ A + ∂R/∂u, with ∂R/∂u from the derivative pass
(:meth:`decrun.methods.model.problem.ModelProblem.rest_jacobian`: each operator's derivative rule),
and its rows at fixed (Dirichlet) values are 0, as F's are. Where that Jacobian cannot be made —
a Galerkin mass (M⁻¹ dense) or a term without a derivative rule — :func:`exact_jacobian` returns
None and the integrator takes M_L⁻¹ ∂f/∂y with the lumped mass
(:mod:`decrun.methods.model.lumped_jacobian`) or else finite differences on the sparsity pattern;
a Galerkin Laplacian of k-forms (k ≥ 1), which needs a mass matrix, is refused in one line
(:func:`decrun.methods.model.mixed.refuse_adaptive`).
"""

from __future__ import annotations

from typing import Callable, Optional

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.language import ModelError
from decrun.methods.model.mixed import refuse_adaptive

__all__ = ["exact_jacobian"]


def exact_jacobian(model) -> Optional[Callable[[float, np.ndarray], sp.csr_matrix]]:
    """``jac(t, u) -> csr (total, total)``, ∂F/∂u over the stacked evolved values (module
    docstring), or None when it is not available as a sparse matrix."""
    refuse_adaptive(model, "bdf/radau")
    evolution, problem = model.evolution, model.problem
    inverse = []
    for u in evolution.names:
        diagonal = evolution.mass[u].diagonal()
        if (evolution.mass[u] - sp.diags(diagonal)).nnz or np.any(diagonal == 0):
            return None
        inverse.append(1.0 / diagonal)
    try:
        problem.check_jacobian()
    except ModelError:
        return None
    strong = (sp.diags(np.concatenate(inverse)) @ problem.stiff_full).tocsr()
    keep = np.ones(evolution.total)
    fixed_index, _ = evolution.fixed()
    keep[fixed_index] = 0.0
    keep_rows = sp.diags(keep)

    def jacobian(t: float, x: np.ndarray) -> sp.csr_matrix:
        rest = problem.rest_jacobian(np.asarray(x, dtype=np.float64), t)
        total = strong if rest is None else strong + rest
        return (keep_rows @ total).tocsc()
    return jacobian
