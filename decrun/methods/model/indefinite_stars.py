"""Before a model runs: is the weight of each evolution definite? (Called from
:meth:`decrun.apps.model.Model.check`; the existence of every ⋆ a model reads is
``_check_stars`` of :mod:`decrun.methods.model.system`.)

dt(u) of a field on s-simplices is weighted by ⋆_s: dt(u) = ⋆_s⁻¹ (…). A circumcentric ⋆_s with
negative entries (obtuse triangles on a border, slivers) makes that weight indefinite, and the
operator then has eigenvalues of the wrong sign: a diffusion dt(w) = Δw grows without bound at
any dt, under any integrator. A zero entry makes ⋆_s⁻¹ infinite. Refused in one line naming ⋆_s,
the count of its bad entries and a variant whose ⋆_s is positive (Whitney's Galerkin ⋆ is SPD on
every mesh). A negative ⋆ read only inside a stiffness dᵀ⋆d of a lower degree (the cotan
Laplacian of a 0-form) keeps that stiffness positive semi-definite — the P1 finite-element
matrix — and is left alone: the model stays well-posed.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.language import ModelError

__all__ = ["refuse_indefinite_stars"]


def refuse_indefinite_stars(model, scheme: str) -> None:
    """ModelError when dt(u) is weighted by a diagonal ⋆_s (s the simplex dimension of u) with
    negative or zero entries (module docstring), naming ⋆_s, the count, and the fix."""
    compiler, dec = model.compiler, model.ops.dec
    n = model.ops.n
    for equation in model.equations:
        if equation.kind != "evolution":
            continue
        u, kind = equation.target, model.kinds[equation.target]
        if not kind.is_form:
            continue
        s = kind.simplex_dimension(n)
        if s not in compiler.star_degrees(equation.rhs, equation.where):
            continue
        star = dec.star(s)
        diagonal = star.diagonal()
        if (star != _diagonal_matrix(diagonal)).nnz:  # a Galerkin ⋆ (Whitney): SPD
            continue
        negative, zero = int(np.sum(diagonal < 0)), int(np.sum(diagonal == 0))
        if negative + zero == 0:
            continue
        bad = f"{negative} negative" + (f" and {zero} zero" if zero else "") if negative else f"{zero} zero"
        why = "its inverse is infinite there" if not negative else \
            "so dt({u}) = ⋆{s}⁻¹(…) is indefinite and grows without bound at any dt".format(u=u, s=s)
        raise ModelError(f"{equation.where}: dt({u}) is weighted by ⋆{s} of operator={dec.star_variant.name}, which has "
                         f"{bad} entries of {diagonal.size} on this mesh (obtuse or right triangles: circumcentric "
                         f"duals), {why}; use {_star_fix(s, scheme)}")


def _diagonal_matrix(diagonal: np.ndarray) -> sp.csr_matrix:
    return sp.diags(diagonal, format="csr")


def _star_fix(s: int, scheme: str) -> str:
    """The override that gives dt(u) a positive ⋆_s: a variant with a positive ⋆0 for 0-forms;
    Whitney's SPD Galerkin ⋆ otherwise (its ⋆⁻¹ has no sparse matrix, so with an explicit
    integrator), or a mesh without obtuse triangles."""
    if s == 0:
        return "`operator=mixed_area` (its ⋆0, the mixed Voronoi–barycentric area, is positive on every mesh)"
    explicit = scheme in ("explicit_euler", "rk4", "ssprk3", "rk45")
    integrator = "" if explicit else " app.integrator=rk45"
    return (f"`operator=whitney{integrator}` (Whitney's Galerkin ⋆{s} is positive definite on every mesh; its ⋆⁻¹ "
            "is a solve, so an explicit integrator) or a mesh without obtuse triangles")
