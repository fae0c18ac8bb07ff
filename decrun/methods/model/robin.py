"""The Robin term of ``app.fields.<u>.robin: {alpha: α, value: v}`` (∂u/∂n + α u = v, issue #47
item 4) on the mesh: the coefficient that :func:`decrun.methods.model.borders.rewrite` writes into
``laplacian(u)``, static or moving in time, for a diagonal or a Galerkin ⋆0.

With R = diag(w), w_i = ∫_{Γ_i} α (:func:`~decrun.core.boundary.conditions.robin_matrix`), the
border form of the Laplacian is ⋆0 Δu = −(S + R) u + b(v). In the language:

- a diagonal ⋆0: ``laplacian(u) - _robin_u*u + inv_star(_robin_value_u)``, ``_robin_u`` = w/⋆0
  (a coefficient form: ⋆0⁻¹ R u = (w/⋆0) u);
- a Galerkin ⋆0 M (``operator=whitney``): ⋆0⁻¹ R u is not a coefficient times u (M⁻¹ is dense), so
  the term is ``inv_star(border_mass(_robin_u*u))`` with ``_robin_u`` = w/m (ᾱ, the mean of α
  weighted by the hats) and ``border_mass`` = diag(m), m_i = ∫_∂Ω φ_i (:func:`built_in_operators`;
  here w_i = ∫_∂Ω α φ_i, the P1 border quadrature of :func:`quadrature`): border_mass(ᾱ u) = R u, a
  dual n-form, and its ``inv_star`` is M⁻¹ R u — the same inverse star as ``laplacian(u)`` =
  M⁻¹(−S u), so the linear split (:mod:`decrun.methods.model.linear`) adds them into one weak block
  ⋆0⁻¹(−(S + R)): one M solve, never an inverse matrix.

When α reads ``t`` the coefficient is a moving definition (:func:`moving_coefficient`, evaluated
first in every environment at its t, like the moving border loads): ``_robin_u*u`` is then a term
linear in u with a time-dependent coefficient — an explicit term of the evolutions whose exact
Jacobian diag(_robin_u(t)) the derivative rules give (implicit integrators solve it by Newton), and
a solve with it is a Newton solve reading α at its t (one iteration: it is linear).
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import scipy.sparse as sp

from decrun.core.boundary.conditions import (
    BorderQuadrature,
    border_load,
    border_quadrature,
    hat_quadrature,
    robin_matrix,
)
from decrun.methods.model.kinds import Kind, dual, primal
from decrun.methods.model.language import ModelError

__all__ = ["border_mass", "built_in_operators", "coefficient", "moving_coefficient", "quadrature", "refuse_indefinite",
           "static_coefficient"]


def quadrature(ops) -> BorderQuadrature:
    """The border quadrature of the Neumann and Robin terms: DEC's circumcentric pieces Γ_i of the
    dual cells for a diagonal ⋆0, the P1 hat functions' for a Galerkin ⋆0 (there S u = ∫_∂Ω ∂u/∂n φ_i
    exactly for linear u; :func:`~decrun.core.boundary.conditions.hat_quadrature`)."""
    return border_quadrature(ops.K) if ops.diagonal(0) is not None else hat_quadrature(ops.K)


def border_mass(ops) -> np.ndarray:
    """(n0,) m_i = ∫_∂Ω φ_i, the lumped border mass of the P1 hats (½ of each adjacent border
    edge, ⅓ of each adjacent border triangle; 0 inside), cached on the DEC."""
    return ops.dec.require("border_mass", lambda: border_load(ops.K, hat_quadrature(ops.K), 1.0))


def _weights(ops, quadrature: BorderQuadrature, alpha: np.ndarray) -> np.ndarray:
    return robin_matrix(ops.K, quadrature, alpha).diagonal()


def coefficient(ops, weights: np.ndarray, where: str, t: float | None = None) -> np.ndarray:
    """(n0,) the Robin coefficient ``_robin_u`` from w = diag(R): w/⋆0 for a diagonal ⋆0, w/m
    (m = :func:`border_mass`) for a Galerkin one (module docstring); −laplacian(u) with the border
    checked definite first (``t``: the time of a moving α, named in the refusal)."""
    star0 = ops.diagonal(0)
    if np.any(weights < 0):
        refuse_indefinite(ops, weights, where, t)
    if star0 is not None:
        return weights / star0
    measure = border_mass(ops)  # > 0 at every border vertex, 0 inside (where the weights are 0 too)
    return np.divide(weights, measure, out=np.zeros_like(weights), where=measure > 0)


def moving_coefficient(ops, quadrature: BorderQuadrature, alpha, where: str) -> Callable[[float], np.ndarray]:
    """``t ↦ _robin_u`` at t for an α that reads t (``alpha`` a
    :class:`~decrun.methods.model.borders.BorderExpression`): the coefficient of :func:`coefficient`,
    with the definiteness check at every time where a weight is negative (the caller computes each
    time once: :func:`~decrun.methods.model.borders.at_each_time`)."""
    def at(t: float) -> np.ndarray:
        return coefficient(ops, _weights(ops, quadrature, alpha.at(quadrature.points, t)), where, t)
    return at


def static_coefficient(ops, quadrature: BorderQuadrature, alpha, where: str) -> np.ndarray:
    """(n0,) ``_robin_u`` of α at t = 0 (for an α without t, its value for the whole run)."""
    return coefficient(ops, _weights(ops, quadrature, alpha.at(quadrature.points, 0.0)), where)


def refuse_indefinite(ops, weights: np.ndarray, where: str, t: float | None = None) -> None:
    """One line when S + R (R = diag ``weights``) has a negative eigenvalue in the ⋆0 inner product:
    −laplacian(u) with this Robin border is then indefinite (solves are ill-posed, evolutions grow).
    A Galerkin ⋆0 M is positive definite, so (S + R) x = λ M x has the inertia of S + R (Sylvester):
    its rows are scaled by the lumped mass M 1 instead."""
    from scipy.sparse.linalg import eigsh

    star0 = ops.diagonal(0)
    if star0 is None:
        star0 = np.asarray(ops.dec.star(0).sum(axis=1)).ravel()
    d0 = ops.dec.d(0)
    S = (d0.T @ ops.dec.star(1) @ d0).tocsr()
    scale = 1.0 / np.sqrt(np.abs(star0))
    A = sp.diags(scale) @ (S + sp.diags(weights)) @ sp.diags(scale)
    if A.shape[0] <= 400:
        smallest = float(np.linalg.eigvalsh(A.toarray())[0])
    else:
        smallest = float(eigsh(A.tocsc(), k=1, which="SA", return_eigenvectors=False, tol=1e-8)[0])
    if smallest < -1e-12 * abs(A).max():
        when = "" if t is None else f" at t = {t:g}"
        raise ModelError(f"{where}: the Robin weights ∫_Γi α are negative{when} at {int(np.sum(weights < 0))} border "
                         "vertices (α < 0, or obtuse border triangles of tetrahedra) and make −laplacian(u) with this "
                         f"border indefinite (smallest eigenvalue {smallest:.3g} of ⋆0⁻¹(S + R)): solves are ill-posed "
                         f"and evolutions grow without bound; make α ≥ 0, e.g. `{where}=1`")


# ---------------------------------------------------------------------- the operator border_mass
def _border_mass_kind(args: list[Kind], n: int) -> Kind:
    from decrun.methods.model.operators import Mismatch

    (kind,) = args
    if kind != primal(0):
        raise Mismatch(f"border_mass takes a primal 0-form (values at vertices), got a {kind}")
    return dual(n)


def _border_mass_linear(ops, kind: Kind):
    from decrun.methods.model.operators import Linear

    return Linear(None, sp.diags(border_mass(ops)).tocsr())


def built_in_operators() -> list:
    """``border_mass`` (:class:`~decrun.methods.model.operators.Operator`), registered as a built-in
    at the end of :mod:`decrun.methods.model.operators`."""
    from decrun.methods.model.operators import Operator

    return [Operator("border_mass", (1,), "primal 0-form → dual n-form",
                     "diag(m) u, m_i = ∫_∂Ω φ_i the lumped border mass of the P1 hats (half of each border edge "
                     "at vertex i, a third of each border triangle), 0 inside — ∫_∂Ω u v lumped; "
                     "inv_star(border_mass(ᾱ*u)), ᾱ_i = ∫_∂Ω α φ_i / m_i, is the Robin term ⋆0⁻¹ R u of a "
                     "Galerkin ⋆0",
                     _border_mass_kind, None, _border_mass_linear)]
