"""The implicit matrix of a linear scheme checked before it is factorized (issue 48, item 9).

Implicit Euler, Crank–Nicolson and IMEX solve (M − θ dt A) u⁺ = … once per step with one
factorization. Where A is symmetric — diffusion, damping, growth — M − θ dt A must be positive
definite: a mode that grows at rate λ (A v = λ M v, λ > 0, as the constants under Allen–Cahn's
``u - u**3``) is multiplied by 1/(1 − θ dt λ) per step, which is infinite at θ dt λ = 1 and flips
the sign beyond. Allen–Cahn under ``imex`` at dt ≥ 1 made (1 − dt) M + dt·eps·S singular or
indefinite and the solver said only "the solution is not finite". Two cheap tests find it before
any step — a diagonal entry ≤ 0, or the constant vector c with cᵀ(M − θ dt A)c ≤ 0 — and the
refusal names ``app.dt``, the linear term that grows, the largest step that keeps the matrix
definite on that test, and the two fixes: a smaller dt, or the term under ``explicit(·)``."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.language import ModelError, Node, to_text
from decrun.methods.model.sides import summed

__all__ = ["check_implicit_matrix"]


def _symmetric(A: sp.spmatrix) -> bool:
    A = sp.csr_matrix(A)
    scale = abs(A).max() if A.nnz else 0.0
    return bool(scale == 0 or abs(A - A.T).max() <= 1e-12 * scale)


def _growth_terms(model, u: str, M: sp.spmatrix):
    """[(term, cᵀ A_term c)] of the linear terms of dt(u) in u whose weak matrix A_term grows the
    constants (cᵀ A_term c > 0), c the constant vector."""
    compiler = model.compiler
    equation = next(eq for eq in model.equations if eq.kind == "evolution" and eq.target == u)
    ones = np.ones(M.shape[0])
    out = []
    for sign, term in compiler.terms(equation.rhs):
        blocks, _rest = compiler.split(term, {u})
        block = blocks.get(u)
        if block is None:
            continue
        A = block.A if block.inv is not None else M @ block.A
        rate = float(sign * ones @ (A @ ones))
        if rate > 0:
            out.append((term, rate))
    return equation, out


def check_implicit_matrix(model, evolution, theta: float, dt: float, scheme: str) -> None:
    """Refuse a symmetric diagonal block M_u − θ dt A_uu that a constant vector or a diagonal
    entry shows is not positive definite (module docstring); one line naming the equation, the
    growing term, ``app.dt`` and the fixes."""
    for u in evolution.names:
        A = evolution.blocks.get((u, u))
        if A is None:
            continue
        M = sp.csr_matrix(evolution.mass[u])
        matrix = sp.csr_matrix(M - theta * dt * A)
        if not (_symmetric(matrix) and _symmetric(M)) or u in model.fixed:
            continue
        ones = np.ones(M.shape[0])
        mass, growth = float(ones @ (M @ ones)), float(ones @ (A @ ones))
        diagonal = matrix.diagonal()
        if mass > theta * dt * growth and diagonal.min(initial=np.inf) > 0:
            continue
        equation, terms = _growth_terms(model, u, M)
        if not terms:  # no linear term grows: a zero ⋆ entry or the like, not this check's diagnosis
            continue
        limit = mass / (theta * growth) if growth > 0 else np.inf
        if not np.isfinite(limit):
            positive = A.diagonal() > 0
            limit = float(np.min(M.diagonal()[positive] / (theta * A.diagonal()[positive]))) if positive.any() else dt
        if not 0 < limit <= dt:  # the growing term is not what breaks the matrix
            continue
        term = to_text(terms[0][0])
        raise ModelError(f"{equation.where}: under app.integrator={scheme} the implicit matrix M - {theta:g}*dt*A of "
                         f"dt({u}) is singular or indefinite at app.dt={dt:g}: its term {term} grows faster than the "
                         f"step can follow (dt must stay below {limit:.3g}); take `app.dt={0.5 * limit:.3g}` or keep "
                         f"the term out of the matrix: {_explicit_rewrite(model, u, equation, terms)!r}")


def _explicit_rewrite(model, u: str, equation, terms) -> str:
    """``dt(u) = <the other linear terms> + explicit(<the growing terms and the nonlinear rest>)``."""
    growing = [term for term, _rate in terms]
    kept: list[tuple[int, Node]] = []
    moved: list[tuple[int, Node]] = []
    for sign, term in model.compiler.terms(equation.rhs):
        blocks, _rest = model.compiler.split(term, {u})
        (moved if term in growing or not blocks else kept).append((1 if sign > 0 else -1, term))
    inner = to_text(summed(moved))
    return f"dt({u}) = {to_text(summed(kept))} + explicit({inner})" if kept else f"dt({u}) = explicit({inner})"
