"""The metrics of ``app=spectrum``: what a computed set of Laplacian eigenpairs (Δ_k u = λ u,
the pencil A u = λ M u with A = the symmetric Δ_k, M = ⋆_k) says about itself — the range,
the kernel against Betti_k (§6.3.6), and whether they are eigenpairs at all."""

from __future__ import annotations

import numpy as np

__all__ = ["eigen_metrics", "relative_residual"]


def eigen_metrics(K, dec, k: int, pairs, betti) -> dict:
    """``degree``, ``eigenvalue_min`` / ``_max``, ``kernel_dimension`` (eigenvalues below
    1e-8 / h̄², h̄ the mean edge length), ``betti_<k>`` (when known), ``kernel_dimension_matches_betti``
    (only when the solve converged and the kernel fits in the computed pairs: else it would
    claim nothing), ``eigen_converged``, ``eigen_residual_max``, ``orthonormality_error_max`` and
    ``residual_relative_max`` (:func:`relative_residual`) of ``pairs``
    (:class:`decrun.methods.spectrum` eigenpairs: ``values`` (c,), ``vectors`` (n_k, c),
    ``converged``, ``residual_max``, ``orthonormality_error``)."""
    values, vectors = pairs.values, pairs.vectors
    metrics: dict = {"degree": k, "eigenvalue_min": float(values[0]), "eigenvalue_max": float(values[-1])}
    length = K.mean_edge_length
    kernel = int(np.sum(np.abs(values) < 1e-8 / length**2))
    metrics.update(kernel_dimension=kernel, **({f"betti_{k}": betti} if betti is not None else {}))
    if pairs.converged and kernel < len(values) and betti is not None:
        metrics["kernel_dimension_matches_betti"] = bool(kernel == betti)
    metrics.update(eigen_converged=pairs.converged, eigen_residual_max=pairs.residual_max,
                   orthonormality_error_max=pairs.orthonormality_error,
                   residual_relative_max=relative_residual(dec, k, values, vectors))
    return metrics


def relative_residual(dec, k: int, values: np.ndarray, vectors: np.ndarray) -> float:
    """max ‖A u − λ M u‖ / (‖M u‖ λ_max): the eigen-equation's residual in the units of the
    largest computed eigenvalue (kernel vectors have A u ≈ 0 and λ ≈ 0)."""
    M = dec.star(k)
    A = dec.laplacian_symmetric(k)
    MU = M @ vectors
    AU = np.column_stack([A @ vectors[:, j] for j in range(vectors.shape[1])])
    residual = np.linalg.norm(AU - MU * values, axis=0)
    scale = np.linalg.norm(MU, axis=0) * max(float(np.abs(values).max()), 1e-300)
    return float(np.max(residual / scale))
