"""``app=spectrum``: the lowest eigenpairs of the Laplace–de Rham operator Δ_k (§4.5.6).

Δ_k = dδ + δd on k-forms (eq. 4.14; positive semi-definite, ⋆-self-adjoint) for any degree
0 ≤ k ≤ n and any Hodge-star variant, on triangle and tetrahedral meshes, by
:func:`decrun.methods.spectrum.laplacian_eigenpairs` (shift-invert about a small negative
shift, the configured solver factorizing the shifted system once). The kernel has dimension
Betti_k (§6.3.6). Where the mesh approximates a shape with a known spectrum — a round sphere
(l(l+1)/r²), an axis-aligned rectangle or box (π²Σ m_i²/L_i², absolute boundary conditions),
a flat torus — the eigenvalues are compared with it (``app.analytic=auto`` recognizes the
shape from the vertices; ``none`` skips the comparison).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from decrun.apps.base import App, Context, Figure, Output, Result
from decrun.core.choices import Choice
from decrun.core.forms import whitney_sharp, whitney_sharp2
from decrun.errors import ConfigError, TopologyError
from decrun.methods.spectrum import (analytic_spectrum, check_stars, detect_domain, laplacian_eigenpairs,
                                     needs_indefinite_solve, spectrum_errors)
from decrun.methods.spectrum_metrics import eigen_metrics


class AnalyticDomain(Choice):
    """``app.analytic``: the domain whose exact spectrum the eigenvalues are compared with
    (``auto``: detected from the mesh, ``none``: no comparison)."""

    auto = "auto"
    none = "none"
    sphere = "sphere"
    ball = "ball"
    box = "box"
    flat_torus = "flat_torus"


@dataclass
class Spectrum(App):
    """Options of ``app=spectrum`` (conf/app/spectrum.yaml)."""

    name = "spectrum"
    dimensions = (2, 3)
    degree: int = 0  # k of Δ_k, 0 ≤ k ≤ n
    count: int = 10  # eigenpairs
    analytic: AnalyticDomain = AnalyticDomain.auto  # auto | none | sphere | ball | box | flat_torus
    shift: Optional[float] = None  # σ < 0 of the shift-invert solve; null: −0.01 / (mean edge)²
    tol: float = 1e-10  # ARPACK's relative tolerance
    figure_count: int = 4  # eigenforms drawn

    def __post_init__(self):
        if self.degree < 0:
            raise ConfigError(f"app.degree: must be ≥ 0, got {self.degree}")
        if self.count < 1:
            raise ConfigError(f"app.count: must be ≥ 1, got {self.count}")
        self.analytic = AnalyticDomain.of(self.analytic, "app.analytic")  # also for Python callers (strings)
        if self.shift is not None and self.shift >= 0:
            raise ConfigError(f"app.shift: must be negative (below the spectrum) or null, got {self.shift}")
        # Δ_k uses ⋆_{k-1}, ⋆_k, ⋆_{k+1}; for k = 0 only the variant's own 0-form operators
        self.form_degrees = (0,) if self.degree == 0 else (self.degree - 1, self.degree, self.degree + 1)

    def check(self, K, dec) -> None:
        if self.degree > K.dim:
            raise ConfigError(f"app.degree: a mesh of dimension {K.dim} has forms of degree 0..{K.dim}, "
                              f"not {self.degree}; use `app.degree={K.dim}`")
        size = K.num_simplices(self.degree)
        if self.count >= size:
            raise ConfigError(f"app.count: this mesh has {size} {self.degree}-simplices, so at most "
                              f"{size - 1} eigenpairs; use `app.count={max(1, min(10, size - 1))}`")
        check_stars(dec, self.degree)
        if self.analytic not in ("auto", "none"):
            domain = detect_domain(K)
            if domain is None or domain.kind != self.analytic:
                found = domain.describe() if domain is not None else "no shape with a known spectrum"
                raise TopologyError(f"app.analytic={self.analytic}: this mesh is {found}; use `app.analytic=auto`")

    def check_solver(self, solver, dec=None) -> None:
        super().check_solver(solver, dec)
        if dec is not None and getattr(solver, "needs_spd", False) and self.degree <= dec.n \
                and needs_indefinite_solve(dec, self.degree):
            raise ConfigError(f"solver={solver.name}: the shifted eigen-system of Δ_{self.degree} with "
                              f"operator={dec.star_variant.name} is symmetric indefinite (a Galerkin ⋆_{self.degree - 1} "
                              f"or a ⋆_{self.degree} that is not positive); use `solver=direct`")

    def outputs(self) -> dict[str, Output]:
        """The eigenvalues (with a known shape the exact ones too) and one eigenform per column."""
        return {"eigenvalues": Output("global", None), "eigenvalues_analytic": Output("global", None),
                "eigenforms": Output(str(int(self.degree)), int(self.count), columns=True)}

    def run(self, ctx: Context) -> Result:
        """The ``count`` lowest eigenpairs of Δ_k; see the module docstring.

        Fields: ``eigenvalues`` (count,), ``eigenforms`` (n_k, count) ⋆_k-normalized,
        ``eigenvalues_analytic`` (count,) where the shape is known.

        Metrics: ``eigenvalue_min``, ``eigenvalue_max``; ``kernel_dimension`` (eigenvalues
        below 1e-8 / h̄²), ``betti_k``, ``kernel_dimension_matches_betti`` (only when the
        eigen-solve converged); ``eigen_converged`` and ``eigen_residual_max`` (max ‖A u − λ M u‖
        / (‖A‖ ‖u‖)), ``orthonormality_error_max`` (max |UᵀM U − I|): a solve whose residual or
        orthonormality misses its bound is not an error — its numbers are kept — but
        ``eigen_converged: false`` says they are not eigenpairs; ``residual_relative_max``
        (max ‖A u − λ M u‖ / (‖M u‖ λ_max), λ_max the largest computed eigenvalue); with a known shape ``analytic_domain`` and
        ``eigenvalue_relative_error_max`` / ``_mean`` (|λ_h − λ| / λ over the nonzero λ) and
        ``eigenvalue_zero_abs_max``; ``solve_seconds``. A mass ⋆_k with negative entries is
        refused before any work (:func:`decrun.methods.spectrum.check_stars`).
        """
        K, dec, k = ctx.complex, ctx.dec, int(self.degree)
        start = time.perf_counter()
        with ctx.task(f"eigen-solve: the {self.count} lowest eigenpairs of Δ_{k}"):
            pairs = laplacian_eigenpairs(dec, k, int(self.count), ctx.new_solver, shift=self.shift, tol=self.tol)
        seconds = time.perf_counter() - start
        values, vectors = pairs.values, pairs.vectors
        metrics = eigen_metrics(K, dec, k, pairs, ctx.betti(k))
        length = K.mean_edge_length
        fields = {"eigenvalues": values, "eigenforms": vectors}
        titles = [f"λ = {v:.4g}" for v in values]
        if self.analytic != "none":
            domain = detect_domain(K)
            if domain is not None and not (domain.kind == "ball" and k != 0):  # the ball: functions only
                exact = analytic_spectrum(domain, k, len(values))
                fields["eigenvalues_analytic"] = exact
                metrics["analytic_domain"] = domain.describe()
                metrics.update(spectrum_errors(values, exact))
                titles = [f"λ = {v:.4g} (exact {e:.4g})" for v, e in zip(values, exact)]
        metrics["solve_seconds"] = seconds
        shown = [i for i in range(len(values)) if abs(values[i]) >= 1e-8 / length**2][: int(self.figure_count)]
        figures = {}
        if shown and K.embedding_dim in (2, 3):
            figures["eigenforms"] = Figure.of_kind(
                "eigenforms", values=[display_values(K, k, vectors[:, i]) for i in shown],
                titles=[titles[i] for i in shown], degree=k)
        return Result(fields=fields, metrics=metrics, figures=figures)


def display_values(K, k: int, form: np.ndarray) -> np.ndarray:
    """What the figure colours: a 0-form per vertex (signed), the magnitude of the Whitney
    field of a 1-form (or 2-form on tetrahedra) per top simplex, a top form as its density
    value/|σ| per top simplex."""
    if k == 0:
        return form
    if k == K.dim:
        return form / K.top_volumes
    if k == 1:
        return np.linalg.norm(whitney_sharp(K, form), axis=1)
    return np.linalg.norm(whitney_sharp2(K, form), axis=1)
