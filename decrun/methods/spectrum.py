"""The low spectrum of the Laplace–de Rham operators Δ_k = dδ + δd (§4.5.6, eq. 4.14).

Δ_k is self-adjoint under the ⋆ inner product (eq. 4.15), so its eigenpairs are those of the
generalized symmetric problem

    (⋆_k Δ_k) u = λ ⋆_k u ,      ⋆_k Δ_k = ⋆_k d_{k-1} ⋆_{k-1}⁻¹ d_{k-1}ᵀ ⋆_k + d_kᵀ ⋆_{k+1} d_k

(:meth:`decrun.core.dec.DEC.laplacian_symmetric`). The lowest eigenvalues come from ARPACK in
shift-invert mode about a small negative shift σ (every λ ≥ 0 > σ, so the eigenvalues nearest
σ are the lowest), with (⋆_kΔ_k − σ⋆_k) factorized once by the configured solver:

- diagonal ⋆_{k-1} (DEC stars, lumped Whitney): ⋆_kΔ_k is a sparse matrix;
- Galerkin ⋆_{k-1} = M_{k-1} (``operator=whitney``): ⋆_{k-1}⁻¹ is never formed; with
  σ_ = M_{k-1}⁻¹ d_{k-1}ᵀ M_k u the shifted system is the symmetric saddle-point system

      [ −M_{k-1}      d_{k-1}ᵀ M_k          ] [ σ_ ]   [ 0 ]
      [ M_k d_{k-1}   d_kᵀ M_{k+1} d_k − σ M_k ] [ u  ] = [ f ]

  (the mixed formulation of finite-element exterior calculus), factorized once.

A ⋆_k with negative entries (circumcentric stars on non-Delaunay or non-well-centred meshes)
makes ⟨·,·⟩_⋆ indefinite: the pencil then has negative and complex eigenvalues that are no
spectrum of Δ_k (measured: −17.0 and −4.6 on ``mesh=box mesh.jitter=0.2 mesh.cells=10``,
degree 1), so it is refused before any work (:func:`check_stars`), naming the Galerkin stars.
Zero entries only make the mass semi-definite (infinite eigenvalues, which the shift-invert
solve never reaches; Arnoldi on (⋆_kΔ_k − σ⋆_k)⁻¹ ⋆_k, since ⋆_k is then no inner product). A ⋆_{k-1} with zero entries makes ⋆_kΔ_k infinite: refused.
A *stiffness* star with negative entries — ⋆_{k-1} inside ⋆_k d ⋆_{k-1}⁻¹ dᵀ ⋆_k (k ≥ 1), or
⋆_{k+1} inside d_kᵀ ⋆_{k+1} d_k (1 ≤ k ≤ n−2) — makes ⋆_kΔ_k itself indefinite: on the
jittered 16 × 16 square, Δ2 with the cot ⋆1 (negative on 137 of 800 edges) has exactly 137
negative eigenvalues, down to −6.8e5, and shift-invert about σ < 0 skipped all of them. It is
refused before any work too (:func:`check_stars`). (⋆1 inside Δ0 = d0ᵀ ⋆1 d0 is not checked:
for the cot weights that is the P1 stiffness matrix, positive semi-definite whatever their
signs.) As a last guard, computed eigenvalues below −1e-8/h̄² (an indefinite operator the
checks did not foresee, e.g. a plugin star) are refused after the solve
(:func:`refuse_negative`).

A mesh of several pieces (top simplices joined through shared vertices) has a block-diagonal
Δ_k: its spectrum is the union of the pieces' spectra, and the kernel of Δ0 has one dimension
per piece. One Lanczos run finds only a few copies of such a repeated eigenvalue (3 of 22 zero
eigenvalues on a 22-piece scan, the rest listed as nonzero), so every piece is solved on its
own and the ``count`` lowest of all are returned (:func:`laplacian_eigenpairs`).

Every returned eigenpair is checked (:func:`eigen_accuracy`): the backward residual
‖A u − λ M u‖ / (‖A‖ ‖u‖) and the M-orthonormality max |UᵀMU − I|; ``converged`` is False
when either exceeds :data:`RESIDUAL_MAX` / :data:`ORTHONORMALITY_MAX`.

:func:`analytic_spectrum` gives the exact spectra the discrete ones converge to:
the round sphere, flat tori and axis-aligned boxes (rectangles, cuboids); :func:`detect_domain`
recognizes those shapes from the vertices.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from math import comb

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.core.connectivity import drop_unreferenced, simplex_pieces
from decrun.core.solvers import solver_factory
from decrun.errors import ConfigError, MeshError, SolverError

__all__ = ["Eigenpairs", "Domain", "laplacian_eigenpairs", "check_stars", "needs_indefinite_solve", "analytic_spectrum",
           "detect_domain", "spectrum_errors", "eigen_accuracy", "refuse_negative", "stiffness_degrees", "piece_decs"]

#: up to this many k-simplices the eigenpairs come from a dense LAPACK solve
DENSE_MAX = 400
#: an eigen-solve has converged when every pair's ‖A u − λ M u‖ / (‖A‖ ‖u‖) is below
#: max(RESIDUAL_MAX, 100 · tol) and max |UᵀMU − I| below ORTHONORMALITY_MAX (measured on
#: converged solves: ≤ 1e-12 and ≤ 1e-11; the indefinite-mass solve this replaced: 0.046 and 1)
RESIDUAL_MAX = 1e-8
ORTHONORMALITY_MAX = 1e-6


@dataclass
class Eigenpairs:
    """The ``count`` lowest eigenpairs of Δ_k.

    values : (count,) ascending
    vectors : (n_k, count), ⋆_k-normalized (uᵀ ⋆_k u = 1)
    shift : the shift σ used (0 for the dense solve)
    residual_max : max over the pairs of ‖A u − λ M u‖ / (‖A‖ ‖u‖), A = ⋆_kΔ_k, M = ⋆_k
    orthonormality_error : max |UᵀMU − I|
    converged : both below their bounds (:data:`RESIDUAL_MAX`, :data:`ORTHONORMALITY_MAX`)
    """

    values: np.ndarray
    vectors: np.ndarray
    shift: float
    residual_max: float = np.nan
    orthonormality_error: float = np.nan
    converged: bool = False


def _star_positive(dec, k: int) -> bool:
    """⋆_k positive definite: Galerkin (SPD by construction) or a positive diagonal."""
    diagonal = dec.star_diagonal_or_none(k)
    return diagonal is None or bool(np.all(diagonal > 0))


def _galerkin_lower(dec, k: int) -> bool:
    return k > 0 and not dec.star_is_diagonal(k - 1)


def needs_indefinite_solve(dec, k: int) -> bool:
    """True when the shifted system of degree k is symmetric indefinite (a Galerkin ⋆_{k-1}
    gives a saddle-point system; a ⋆_k that is not positive an indefinite one): solvers that
    need SPD matrices (cg, amg) cannot solve it."""
    return _galerkin_lower(dec, k) or not _star_positive(dec, k)


def _zero_entries(dec, j: int) -> np.ndarray:
    star = dec.star_diagonal(j)
    return np.flatnonzero(np.abs(star) <= 1e-12 * np.abs(star).max())


def _negative_entries(dec, j: int) -> np.ndarray:
    """Indices where a diagonal ⋆_j is negative beyond round-off (none for a Galerkin ⋆_j)."""
    star = dec.star_diagonal_or_none(j)
    if star is None:
        return np.zeros(0, dtype=np.int64)
    return np.flatnonzero(star < -1e-12 * np.abs(star).max())


def check_stars(dec, k: int) -> None:
    """MeshError when the mass ⋆_k has negative entries (an indefinite pencil: negative and
    complex eigenvalues, no spectrum of Δ_k), naming the operator whose mass is positive there
    (``mixed_area`` for functions on a surface, else the Galerkin ``whitney``); when a
    diagonal ⋆_{k-1} has zero entries (degenerate dual cells, as in Kuhn cubes): ⋆_{k-1}⁻¹ in
    Δ_k is then infinite; or when a stiffness star ⋆_j, j in :func:`stiffness_degrees`, has
    negative entries: ⋆_kΔ_k is then indefinite (module docstring). (Zeros in ⋆_k only make
    the mass singular: infinite eigenvalues, which the shift-invert solve never reaches.)"""
    negative = _negative_entries(dec, k)
    if negative.size:
        fix = "operator=mixed_area" if k == 0 and dec.n == 2 else "operator=whitney"
        what = "mixed Voronoi areas, positive on every mesh" if k == 0 and dec.n == 2 else \
            "Galerkin stars, SPD on every mesh"
        raise MeshError(f"the eigenproblem of Δ_{k} needs a positive mass ⋆_{k}, but ⋆_{k} of operator="
                        f"{dec.star_variant.name} is negative on {negative.size} of {dec.K.num_simplices(k)} simplices "
                        f"(e.g. {negative[:5].tolist()}: non-Delaunay or not well-centred dual cells), which gives "
                        f"negative and complex eigenvalues; use `{fix}` ({what})")
    if k > 0 and not _galerkin_lower(dec, k):
        zero = _zero_entries(dec, k - 1)
        if zero.size:
            raise MeshError(f"Δ_{k} contains ⋆_{k - 1}⁻¹, but ⋆_{k - 1} of operator={dec.star_variant.name} is zero on "
                            f"{zero.size} simplices (e.g. {zero[:5].tolist()}: degenerate dual cells, as in Kuhn cubes); "
                            "use `operator=whitney` (Galerkin stars, SPD on every mesh)")
    for j in stiffness_degrees(dec.n, k):
        negative = _negative_entries(dec, j)
        if negative.size:
            term = f"⋆_{k} d ⋆_{j}⁻¹ dᵀ ⋆_{k}" if j == k - 1 else f"dᵀ ⋆_{j} d"
            raise MeshError(f"⋆_{k}Δ_{k} contains {term}, but ⋆_{j} of operator={dec.star_variant.name} is negative on "
                            f"{negative.size} of {dec.K.num_simplices(j)} simplices (e.g. {negative[:5].tolist()}: "
                            f"non-Delaunay or not well-centred dual cells), which makes Δ_{k} indefinite (negative "
                            "eigenvalues, no spectrum); use `operator=whitney` (Galerkin stars, SPD on every mesh)")


def stiffness_degrees(n: int, k: int) -> tuple[int, ...]:
    """The degrees j of the stars inside ⋆_kΔ_k = ⋆_k d ⋆_{k-1}⁻¹ dᵀ ⋆_k + d_kᵀ ⋆_{k+1} d_k whose
    negative entries make it indefinite: k − 1 (k ≥ 1) and k + 1 (1 ≤ k ≤ n − 2). Not ⋆1 in
    Δ0 = d0ᵀ ⋆1 d0 (the cot weights' P1 stiffness matrix: semi-definite whatever their signs) and
    not ⋆_n (1/|σ| > 0 for every variant: a dual 0-cell)."""
    return tuple(j for j in (k - 1, k + 1) if (j == k - 1 and k >= 1) or (j == k + 1 and 1 <= k <= n - 2))


def refuse_negative(dec, k: int, values: np.ndarray) -> None:
    """MeshError when a computed eigenvalue of Δ_k (positive semi-definite) is below −1e-8/h̄²
    (h̄ the mean edge length; the kernel bound of :func:`decrun.methods.spectrum_metrics.eigen_metrics`):
    ⋆_kΔ_k of this operator is indefinite on this mesh, and the values are no spectrum."""
    length = float(np.linalg.norm(np.diff(dec.K.vertices[dec.K.simplices(1)], axis=1)[:, 0], axis=1).mean())
    negative = np.asarray(values)[np.asarray(values) < -1e-8 / length**2]
    if negative.size:
        raise MeshError(f"Δ_{k} with operator={dec.star_variant.name} is indefinite on this mesh: {negative.size} of the "
                        f"{len(values)} lowest eigenvalues are negative (down to {negative.min():.4g}), no spectrum of "
                        "Δ_k; use `operator=whitney` (Galerkin stars, SPD on every mesh)")


def _default_shift(dec) -> float:
    """σ = −0.01 / h̄² (h̄ the mean edge length): a small negative number in the units of λ."""
    length = np.linalg.norm(np.diff(dec.K.vertices[dec.K.simplices(1)], axis=1)[:, 0], axis=1).mean()
    return -0.01 / float(length) ** 2


def _shifted_inverse(dec, k: int, shift: float, solver) -> spla.LinearOperator:
    """(⋆_kΔ_k − σ ⋆_k)⁻¹ as a LinearOperator on (n_k,) vectors; factorized once."""
    size = dec.K.num_simplices(k)
    M = sp.csr_matrix(dec.star(k))
    if not _galerkin_lower(dec, k):
        T = sp.csr_matrix(dec.laplacian_symmetric(k)) - shift * M
        try:
            solver.factorize(T)
        except SolverError as exc:
            zero = _zero_entries(dec, k) if dec.star_is_diagonal(k) else np.zeros(0)
            if not zero.size:
                raise
            raise MeshError(f"the shifted eigen-system of Δ_{k} is singular: ⋆_{k} of operator="
                            f"{dec.star_variant.name} is zero on {zero.size} simplices (e.g. {zero[:5].tolist()}: "
                            "degenerate dual cells, as in Kuhn cubes) and Δ_k does not reach them; use "
                            "`operator=whitney` (Galerkin stars, SPD on every mesh)") from exc
        return spla.LinearOperator((size, size), matvec=lambda f: solver.solve(np.ravel(f)), dtype=np.float64)
    lower = sp.csr_matrix(dec.star(k - 1))
    star_d = (M @ dec.d(k - 1)).tocsr()
    up = dec.d(k).T @ dec.star(k + 1) @ dec.d(k) if k < dec.n else sp.csr_matrix((size, size))
    block = sp.bmat([[-lower, star_d.T], [star_d, up - shift * M]], format="csr")
    solver.factorize(block)
    offset = lower.shape[0]

    def apply(f):
        rhs = np.concatenate([np.zeros(offset), np.ravel(f)])
        return solver.solve(rhs)[offset:]

    return spla.LinearOperator((size, size), matvec=apply, dtype=np.float64)


def laplacian_eigenpairs(dec, k: int, count: int, solver=None, shift: float | None = None, tol: float = 1e-10,
                         seed: int = 0) -> Eigenpairs:
    """The ``count`` lowest eigenpairs of Δ_k on ``dec``'s mesh (module docstring).

    Parameters
    ----------
    dec : DEC (any Hodge-star variant providing ⋆_{k-1}, ⋆_k, ⋆_{k+1})
    k : form degree, 0 ≤ k ≤ n
    count : number of eigenpairs (≥ 1, < n_k)
    solver : solver name, instance or factory for the shifted system (default ``direct``)
    shift : σ < 0 (default :func:`_default_shift`, −0.01/h̄²)
    tol : ARPACK's relative tolerance

    Returns
    -------
    :class:`Eigenpairs`, checked (``residual_max``, ``orthonormality_error``, ``converged``).
    On a mesh of several pieces each piece is solved on its own (:func:`piece_decs`) and the
    ``count`` lowest pairs of all are kept (vectors zero off their piece). Raises MeshError for
    a mass ⋆_k or a stiffness ⋆_{k±1} with negative entries (:func:`check_stars`) and for
    negative eigenvalues (:func:`refuse_negative`), SolverError when ARPACK stops short of
    ``count`` pairs.
    """
    size = dec.K.num_simplices(k)
    if not 1 <= count < size:
        raise ConfigError(f"app.count: needs 1 ≤ count < {size} (the number of {k}-simplices), got {count}")
    check_stars(dec, k)
    M = sp.csr_matrix(dec.star(k))
    pieces = piece_decs(dec, k)
    if pieces is None:
        values, vectors, shift = _lowest(dec, k, count, M, solver, shift, tol, seed)
    else:
        shift = _default_shift(dec) if shift is None else float(shift)  # one σ, in the whole mesh's units
        values, vectors = [], []
        for piece, index in pieces:  # a loop over the pieces, each solved as a whole
            got, local, _ = _lowest(piece, k, min(count, len(index)), sp.csr_matrix(piece.star(k)), solver, shift,
                                    tol, seed)
            embedded = np.zeros((size, local.shape[1]))
            embedded[index] = local
            values.append(got)
            vectors.append(embedded)
        values, vectors = np.concatenate(values), np.hstack(vectors)
    order = np.argsort(values)[:count]
    values, vectors = np.asarray(values)[order], np.asarray(vectors)[:, order]
    refuse_negative(dec, k, values)
    norms = np.sqrt(np.abs(np.einsum("ij,ij->j", vectors, M @ vectors)))
    vectors = vectors / np.where(norms > 0, norms, 1.0)
    residual, orthonormality = eigen_accuracy(dec, k, values, vectors)
    converged = bool(residual <= max(RESIDUAL_MAX, 100 * tol) and orthonormality <= ORTHONORMALITY_MAX)
    return Eigenpairs(values=values, vectors=vectors, shift=shift, residual_max=residual,
                      orthonormality_error=orthonormality, converged=converged)


def piece_decs(dec, k: int) -> list[tuple] | None:
    """None for a connected mesh; else per piece (top simplices joined through shared
    vertices, :meth:`~decrun.core.complex.SimplicialComplex.connected_components`) the pair
    (DEC of the piece with ``dec``'s star variant and boundary adaptation, (m_p,) indices of its
    k-simplices in ``dec``'s order). Δ_k is block-diagonal over the pieces, and the stars are
    local, so the piece's operators are the blocks of the whole mesh's. Vertices are renumbered
    in their order, so the piece's sorted k-simplices come in the whole mesh's order."""
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC

    K = dec.K
    count, top_label = K.connected_components()
    if count == 1:
        return None
    label = simplex_pieces(top_label, K.simplices(K.dim), K.simplices(k), K.num_simplices(0))
    top = K.oriented_simplices()
    out = []
    for p in range(count):  # a loop over the pieces, not the simplices
        vertices, simplices, _ = drop_unreferenced(K.vertices, top[top_label == p])
        piece = DEC(SimplicialComplex(vertices, simplices, orient="check"), star=dec.star_variant,
                    boundary=dec.boundary)
        out.append((piece, np.flatnonzero(label == p)))
    return out


def _lowest(dec, k: int, count: int, M, solver, shift, tol: float, seed: int) -> tuple[np.ndarray, np.ndarray, float]:
    """(values, vectors, σ): at least the ``count`` lowest eigenpairs of Δ_k on a connected mesh
    (``count`` ≤ n_k; the dense LAPACK solve up to :data:`DENSE_MAX` k-simplices, else ARPACK
    in shift-invert mode about σ), unsorted and not yet normalized."""
    size = M.shape[0]
    if size <= DENSE_MAX:
        values, vectors = _dense(dec, k, count, M, _star_positive(dec, k))
        return values, vectors, 0.0
    shift = _default_shift(dec) if shift is None else float(shift)
    if shift >= 0:
        raise ConfigError(f"app.shift: must be negative (below the spectrum), got {shift}")
    inverse = _shifted_inverse(dec, k, shift, solver_factory(solver)())
    v0 = np.random.default_rng(seed).standard_normal(size)
    # a few more than asked, and a wide Krylov space: symmetric meshes have exactly repeated
    # eigenvalues (5-fold l = 2 on an icosphere), which Lanczos from one start vector finds
    # only through rounding; too small a space missed two of five (measured, icosphere(3))
    wanted = min(count + max(5, count // 2), size - 2)
    ncv = min(size - 1, max(2 * wanted + 1, wanted + 20))
    try:
        if _star_positive(dec, k):  # the symmetric Lanczos solve in the M inner product
            values, vectors = spla.eigsh(dec.laplacian_symmetric(k), k=wanted, M=M, sigma=shift, which="LM",
                                         OPinv=inverse, v0=v0, tol=tol, ncv=ncv)
        else:  # a mass with zero entries (check_stars refused negative ones) is no inner product:
            # Arnoldi on (A − σM)⁻¹ M; its finite eigenvalues are real (A symmetric, M ≥ 0)
            operator = spla.LinearOperator((size, size), matvec=lambda x: inverse @ (M @ np.ravel(x)),
                                           dtype=np.float64)
            nu, vectors = spla.eigs(operator, k=wanted, which="LM", v0=v0, tol=tol, ncv=ncv)
            values, vectors = _real_orthonormal(shift + 1.0 / nu, vectors, M)
    except spla.ArpackNoConvergence as exc:
        raise SolverError(f"eigen-solve of Δ_{k}: ARPACK converged {len(exc.eigenvalues)} of {wanted} "
                          f"eigenpairs (app.tol={tol:g}, {ncv} Lanczos vectors)") from None
    return values, vectors, shift


def _real_orthonormal(values: np.ndarray, vectors: np.ndarray, M, rtol: float = 1e-8):
    """Real, M-orthonormal eigenvectors from Arnoldi's complex ones: per cluster of equal
    (real) eigenvalues — |Δλ| ≤ ``rtol`` max(|λ|, 1) — the m vectors' real and imaginary
    parts span the eigenspace; its m-dimensional M-orthonormal basis is taken from the
    eigenvectors of their M-Gram matrix (Arnoldi's vectors of a repeated eigenvalue are
    neither real nor M-orthogonal: orthonormality error 1 on a flat torus). (values (c,),
    vectors (n, c)) in ascending order."""
    order = np.argsort(values.real)
    values, vectors = values.real[order], vectors[:, order]
    cuts = np.flatnonzero(np.diff(values) > rtol * np.maximum(np.abs(values[1:]), 1.0)) + 1
    out = []
    for cluster in np.split(np.arange(len(values)), cuts):  # a loop over the few eigenvalues, not the mesh
        basis = np.hstack([vectors[:, cluster].real, vectors[:, cluster].imag])
        weights, coefficients = la.eigh(basis.T @ (M @ basis))
        top = coefficients[:, -len(cluster):] / np.sqrt(np.maximum(weights[-len(cluster):], np.finfo(float).tiny))
        out.append(basis @ top)
    return values, np.hstack(out)


def _dense(dec, k, count, M, positive) -> tuple[np.ndarray, np.ndarray]:
    size = M.shape[0]
    A = dec.laplacian_symmetric(k)
    A = A.toarray() if sp.issparse(A) else A @ np.eye(size)
    A = 0.5 * (A + A.T)
    if positive:
        return la.eigh(A, M.toarray(), subset_by_index=[0, count - 1])
    # a mass with zero entries (semi-definite): LAPACK's QZ, the infinite eigenvalues dropped
    values, vectors = la.eig(A, M.toarray())
    finite = np.isfinite(values)
    return values[finite].real, vectors[:, finite].real


def _norm_estimate(A, size: int, steps: int = 30) -> float:
    """‖A‖₂ of the symmetric PSD A: √(‖A‖₁‖A‖∞) for a sparse matrix, else ``steps`` power
    iterations (a LinearOperator with a Galerkin ⋆_{k-1}⁻¹ inside; seeded)."""
    from decrun.core.solvers.base import norm_bound

    if sp.issparse(A):
        return norm_bound(A)
    x = np.random.default_rng(0).standard_normal(size)
    value = 0.0
    for _ in range(steps):
        y = A @ (x / np.linalg.norm(x))
        value, x = float(np.linalg.norm(y)), y
        if value == 0.0:
            break
    return value


def eigen_accuracy(dec, k: int, values: np.ndarray, vectors: np.ndarray) -> tuple[float, float]:
    """(max_j ‖A u_j − λ_j M u_j‖ / (‖A‖ ‖u_j‖), max |UᵀMU − I|) for A = ⋆_kΔ_k, M = ⋆_k:
    the backward residual of each eigenpair and the M-orthonormality of the (n_k, c) vectors."""
    M, A = dec.star(k), dec.laplacian_symmetric(k)
    MU = M @ vectors
    AU = A @ vectors if sp.issparse(A) else np.column_stack([A @ vectors[:, j] for j in range(vectors.shape[1])])
    scale = _norm_estimate(A, vectors.shape[0]) * np.linalg.norm(vectors, axis=0)
    residual = np.linalg.norm(AU - MU * values, axis=0) / np.where(scale > 0, scale, 1.0)
    orthonormality = np.abs(vectors.T @ MU - np.eye(len(values))).max() if len(values) else 0.0
    return float(residual.max(initial=0.0)), float(orthonormality)


# ---------------------------------------------------------------------------- analytic spectra
@dataclass
class Domain:
    """A shape with a known spectrum.

    kind : ``sphere`` or ``ball`` (sizes = (radius,)), ``box`` (sizes = side lengths, one per dimension:
        a rectangle or a cuboid; the unadapted operators give absolute (Neumann-type)
        boundary conditions) or ``flat_torus`` (sizes = the periods 2π r_i)
    """

    kind: str
    sizes: tuple

    def describe(self) -> str:
        return f"{self.kind}({', '.join(f'{s:.6g}' for s in self.sizes)})"


def _lattice_values(steps, low, count: int) -> np.ndarray:
    """The ``count`` smallest Σ_i (m_i · steps_i)² over integers m_i ≥ low_i (low_i = 0 or 1;
    ``low_i = -inf`` for m_i ∈ ℤ), with multiplicity."""
    steps = np.asarray(steps, dtype=np.float64)
    bound = 4
    while True:
        axes = []
        for step, lowest in zip(steps, low, strict=True):
            start = -bound if lowest == -np.inf else lowest
            axes.append((np.arange(start, bound + 1) * step) ** 2)
        grid = np.zeros(1)
        for axis in axes:
            grid = (grid[:, None] + axis[None, :]).ravel()
        grid.sort()
        # every value left out has some |m_i| > bound, so it is at least ((bound + 1) · min step)²
        if grid.size >= count and grid[count - 1] < ((bound + 1) * steps.min()) ** 2:
            return grid[:count]
        bound *= 2


def _ball_neumann(radius: float, count: int) -> np.ndarray:
    """Neumann eigenvalues of the ball: (a/r)² for the zeros a > 0 of j_l' (spherical Bessel),
    multiplicity 2l + 1, and 0 (the constants)."""
    from scipy.optimize import brentq
    from scipy.special import spherical_jn

    limit = 8.0
    while True:
        values = [0.0]
        grid = np.linspace(1e-6, limit, int(400 * limit))
        for degree in range(int(limit) + 2):
            f = spherical_jn(degree, grid, derivative=True)
            for i in np.flatnonzero(np.sign(f[:-1]) * np.sign(f[1:]) < 0):
                root = brentq(lambda x, degree=degree: spherical_jn(degree, x, derivative=True), grid[i], grid[i + 1])
                values += [(root / radius) ** 2] * (2 * degree + 1)
        values.sort()
        # every zero of j_l' exceeds l (McMahon), so zeros beyond `limit` come from l < limit + 2
        if len(values) >= count and values[count - 1] < (limit / radius) ** 2:
            return np.array(values[:count])
        limit *= 2


def analytic_spectrum(domain: Domain, k: int, count: int) -> np.ndarray:
    """The ``count`` lowest eigenvalues of the smooth Hodge Laplacian Δ_k on ``domain``, with
    multiplicity, ascending.

    - sphere of radius r (k = 0, 2): l(l+1)/r², multiplicity 2l+1, l ≥ 0; (k = 1): the
      same for l ≥ 1 twice (dY and ⋆dY), multiplicity 2(2l+1).
    - box with sides L_i, absolute boundary conditions (the natural ones of primal forms:
      harmonic k-forms = H^k): for each k-subset I of the axes the coefficient of dx_I is
      Π_{i∈I} sin(m_i π x_i/L_i) Π_{i∉I} cos(m_i π x_i/L_i), m_i ≥ 1 on I and ≥ 0 off it;
      λ = Σ_i (m_i π / L_i)² (k = 0: Neumann, k = n: Dirichlet).
    - flat torus with periods P_i: C(n, k) copies of the functions' spectrum
      Σ_i (2π m_i / P_i)², m_i ∈ ℤ.
    - ball of radius r (k = 0, Neumann): (a/r)², a the positive zeros of j_l', multiplicity
      2l + 1, and 0.
    """
    if domain.kind == "ball":
        if k != 0:
            raise ValueError("the ball's spectrum is known here for functions (k = 0) only")
        return _ball_neumann(domain.sizes[0], count)
    if domain.kind == "sphere":
        (radius,) = domain.sizes
        if k not in (0, 1, 2):
            raise ValueError(f"the sphere has forms of degree 0..2, not {k}")
        values = []
        degree = 0 if k != 1 else 1
        while len(values) < count:
            values += [degree * (degree + 1) / radius**2] * ((2 if k == 1 else 1) * (2 * degree + 1))
            degree += 1
        return np.array(values[:count])
    n = len(domain.sizes)
    if not 0 <= k <= n:
        raise ValueError(f"a {n}-dimensional {domain.kind} has forms of degree 0..{n}, not {k}")
    if domain.kind == "box":
        steps = np.pi / np.asarray(domain.sizes, dtype=np.float64)
        parts = [_lattice_values(steps, [1 if i in subset else 0 for i in range(n)], count)
                 for subset in itertools.combinations(range(n), k)]
        return np.sort(np.concatenate(parts))[:count]
    if domain.kind == "flat_torus":
        steps = 2 * np.pi / np.asarray(domain.sizes, dtype=np.float64)
        one = _lattice_values(steps, [-np.inf] * n, count)
        return np.sort(np.repeat(one, comb(n, k)))[:count]
    raise ValueError(f"no analytic spectrum for {domain.kind!r}")


def detect_domain(K, rtol: float = 1e-6) -> Domain | None:
    """The :class:`Domain` ``K`` approximates, or None.

    - sphere: a closed triangle mesh in R³ whose vertices all lie at one distance r from
      their mean (to ``rtol``); ball: a tetrahedral mesh whose border vertices do;
    - box: a triangle mesh in a plane z = const or a tetrahedral mesh in R³ whose area/volume
      equals that of its axis-aligned bounding box (to ``rtol``): a rectangle or cuboid with
      no holes;
    - flat torus: a triangle mesh in R⁴ whose vertices satisfy x1² + x2² = r1², x3² + x4² = r2²
      (the Clifford embedding of the flat torus with periods 2π r1, 2π r2).
    """
    V = K.vertices
    n = K.dim
    if n == 2 and V.shape[1] == 4:
        r1, r2 = np.hypot(V[:, 0], V[:, 1]), np.hypot(V[:, 2], V[:, 3])
        if np.ptp(r1) <= rtol * r1.mean() and np.ptp(r2) <= rtol * r2.mean():
            return Domain("flat_torus", (2 * np.pi * r1.mean(), 2 * np.pi * r2.mean()))
        return None
    border, _ = K.border_faces()
    if n == 3 and V.shape[1] == 3 and len(border):
        on_border = np.unique(K.simplices(2)[border])
        center = V[on_border].mean(axis=0)
        radius = np.linalg.norm(V[on_border] - center, axis=1)
        if np.ptp(radius) <= rtol * radius.mean() and np.linalg.norm(V - center, axis=1).max() <= radius.max():
            return Domain("ball", (float(radius.mean()),))
    if n == 2 and V.shape[1] == 3 and len(border) == 0:
        radius = np.linalg.norm(V - V.mean(axis=0), axis=1)
        if np.ptp(radius) <= rtol * radius.mean():
            return Domain("sphere", (float(radius.mean()),))
        return None
    extent = np.ptp(V, axis=0)
    if n == 2:
        if V.shape[1] == 3 and extent[2] > rtol * extent.max():
            return None
        sides = extent[:2]
    elif n == 3 and V.shape[1] == 3:
        sides = extent
    else:
        return None
    if np.any(sides <= 0) or len(border) == 0:
        return None
    if abs(K.top_volumes.sum() - np.prod(sides)) <= rtol * np.prod(sides):
        return Domain("box", tuple(float(s) for s in sides))
    return None


def spectrum_errors(computed: np.ndarray, exact: np.ndarray, zero_tol: float = 1e-8) -> dict:
    """Compare sorted eigenvalues with the analytic ones (same length).

    Returns ``eigenvalue_relative_error_max`` and ``_mean`` over the nonzero analytic values
    (|λ_h − λ|/λ) and ``eigenvalue_zero_abs_max`` (max |λ_h| where λ = 0, relative to the
    largest analytic value) when there are zero ones.
    """
    computed, exact = np.asarray(computed, dtype=np.float64), np.asarray(exact, dtype=np.float64)
    scale = max(float(exact.max()), 1e-300)
    zero = exact <= zero_tol * scale
    out = {}
    if (~zero).any():
        relative = np.abs(computed[~zero] - exact[~zero]) / exact[~zero]
        out["eigenvalue_relative_error_max"] = float(relative.max())
        out["eigenvalue_relative_error_mean"] = float(relative.mean())
    if zero.any():
        out["eigenvalue_zero_abs_max"] = float(np.abs(computed[zero]).max() / scale)
    return out
