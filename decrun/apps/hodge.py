"""``app=hodge``: the discrete Hodge decomposition of a k-form (§6.3.4–6.3.6, Theorem 5).

A k-form ω (``app.degree``: 1 on triangle meshes, 1 or 2 on tetrahedral ones) — sampled from
an analytic vector field (§3.2.1: line integrals along edges for k = 1, fluxes through faces
for k = 2), a seeded random form, or the form stored in a previous run's ``result.h5`` — is
split ⋆_k-orthogonally as

    ω = dα + δβ + γ ,    γ harmonic (dγ = 0, δγ = 0),

by :func:`decrun.core.hodge.hodge_decomposition` (two Poisson problems, the configured solver).
The metrics check Theorem 5 (pairwise ⋆_k-orthogonality, γ harmonic) and §6.3.6
(dim ker Δ_k = Betti_k: Betti_1 is 0 on a sphere, 2 on a torus, the number of holes of a
planar domain or of tunnels through a solid; Betti_2 of a solid is its number of cavities). Theorem 5 needs d and δ adjoint, which holds for the unadapted operators only:
``boundary=flux`` (the §6.4.4 adaptation of the vector_field app) is rejected.

Analytic fields (``app.analytic``; ``a`` = ``app.vector``, points x in model units):

``gradient``          a, the gradient of the linear function a·x: sampled exactly as d0(a·x),
                      so the decomposition is purely exact.
``rotated_gradient``  (x/|x|) × a: on a sphere centred at the origin this is ⋆d(a·x) (the
                      gradient rotated by 90° in the tangent plane): coexact up to sampling.
``rotation``          a × x, the rigid rotation about the axis a.
``toroidal``          ∇φ = (−y, x, 0)/(x² + y²), φ the angle about the z axis: closed but not
                      exact on a torus around the z axis (mostly harmonic there).
``mixed``             gradient + rotated_gradient + toroidal (on a torus: all three parts).
``frame`` (default)   built from the mesh's own frame (:func:`decrun.core.geometry.principal_frame`):
                      c the vertex centroid, e1, e2, e3 the principal axes of the vertex
                      covariance (variance decreasing, e3 = e1 × e2), s the RMS distance of
                      the vertices from c, u_i = e_i·(x − c)/s.
                      X = (e1 + u2 e2) + e3 × (x − c)/s + sin(π u1) e2: the gradient of
                      s(u1 + u2²/2) (exact), a rotation about the axis of least variance (the
                      normal of a planar mesh, the axis of a flat torus) and a bounded part
                      that is not closed (curl (π/s) cos(π u1) e3). Smooth everywhere (no
                      singular point or axis), so it samples on any mesh with nonzero exact
                      and coexact parts (and a harmonic one where Betti_k > 0). It moves with
                      the mesh: translating or rotating the vertices gives the same k-form
                      (when the frame is unique: distinct variances, and nonzero third
                      moments along e1, e2, which fix their signs). ``app.vector`` is not
                      used (a non-default value is refused).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import List

import numpy as np

from decrun.apps.base import App, Context, FieldOnEdges, Figure, Output, Result
from decrun.core.choices import Choice
from decrun.core.complex import simplex_volumes
from decrun.core.forms import sample_flux, sample_vector_field, whitney_sharp, whitney_sharp2
from decrun.core.geometry import embed3, principal_frame
from decrun.core.hodge import HodgeDecomposer, harmonic_basis
from decrun.errors import ConfigError, TopologyError
from decrun.methods.hodge_metrics import harmonic_residuals, orthogonality_metrics


class Input(Choice):
    """``app.input``: the k-form decomposed — an ``analytic`` field sampled on the mesh, a
    ``random`` one, or a field of a previous run's ``result``."""

    analytic = "analytic"
    random = "random"
    result = "result"


#: ``app.vector``'s default (a of the analytic fields; ``frame`` has none)
DEFAULT_VECTOR = [0.0, 0.0, 1.0]



class AnalyticField(Choice):
    """``app.analytic``: the analytic field of ``app.input=analytic`` (module docstring)."""

    gradient = "gradient"
    rotated_gradient = "rotated_gradient"
    rotation = "rotation"
    toroidal = "toroidal"
    mixed = "mixed"
    frame = "frame"


@dataclass
class Hodge(App):
    """Options of ``app=hodge`` (conf/app/hodge.yaml)."""

    name = "hodge"
    headline_metrics = ("orthogonality_max", "energy_fraction_exact", "energy_fraction_coexact",
                        "energy_fraction_harmonic", "harmonic_dimension_matches_betti")
    dimensions = (2, 3)
    form_degrees = (0, 1, 2)
    operator_hint = "`operator=whitney` (the app's default: SPD ⋆1 on every mesh)"
    boundary_note = ("the Hodge decomposition (Theorem 5) needs d and δ adjoint, which the §6.4.4 flux "
                     "adaptation breaks; app=vector_field reports that as adjointness_defect")
    degree: int = 1  # k: 1 (triangle or tetrahedral meshes) or 2 (tetrahedral meshes)
    input: Input = Input.analytic  # analytic | random | result
    analytic: AnalyticField = AnalyticField.frame  # see the module docstring
    vector: List[float] = field(default_factory=lambda: list(DEFAULT_VECTOR))  # a of the analytic fields
    quadrature_order: int = 3  # Gauss points per edge when sampling (§3.2.1)
    seed: int = 0  # random: ω_e = ξ_e |e|, ξ ~ N(0, 1)
    input_path: str = ""  # result: path of a previous run's result.h5
    input_field: str = "omega"  # result: name of its k-form field
    harmonic_dimension: bool = True  # compute dim ker Δ_k (a few extra solves)
    figure_arrows: int = 500

    def __post_init__(self):
        if self.degree not in (1, 2):
            raise ConfigError(f"app.degree: must be 1 or 2 (the forms between functions and densities), got {self.degree}")
        self.form_degrees = (self.degree - 1, self.degree, self.degree + 1)
        self.input = Input.of(self.input, "app.input")  # also for Python callers (strings)
        self.analytic = AnalyticField.of(self.analytic, "app.analytic")
        if len(self.vector) != 3:
            raise ConfigError(f"app.vector: must be three numbers, got {list(self.vector)}")
        if self.analytic == "frame" and list(map(float, self.vector)) != DEFAULT_VECTOR:
            raise ConfigError(f"app.vector={list(self.vector)}: app.analytic=frame takes its directions from the "
                              "mesh's principal axes and has no vector a; use `app.analytic=gradient` (or rotation, "
                              "rotated_gradient, mixed: the fields with a)")
        if self.quadrature_order < 1:
            raise ConfigError(f"app.quadrature_order: must be >= 1, got {self.quadrature_order}")
        if self.input == "result" and not self.input_path:
            raise ConfigError("app.input_path: app.input=result needs the path of a previous run's result.h5, "
                              "e.g. app.input_path=outputs/runs/<stamp>/result.h5")

    def check(self, K, dec) -> None:
        if self.degree >= K.dim:
            raise TopologyError(f"app.degree={self.degree}: a mesh of dimension {K.dim} has nothing to decompose "
                                f"in degree {self.degree} (only exact and harmonic parts); use `app.degree=1`")

    def check_solver(self, solver, dec=None) -> None:
        super().check_solver(solver, dec)
        k = self.degree
        if dec is not None and k <= dec.n and getattr(solver, "needs_spd", False) and dec.star_is_diagonal(k):
            star = dec.star_diagonal(k)
            tiny = 1e-12 * np.abs(star).max()
            bad, zero = int(np.sum(star <= tiny)), int(np.sum(np.abs(star) <= tiny))
            if bad:
                # a zero ⋆k cannot be inverted by any solver (HodgeDecomposer reports it); a
                # negative one only makes the systems indefinite, which MINRES solves
                other = "" if zero else "; or `solver=iterative` (MINRES for symmetric indefinite systems)"
                raise ConfigError(f"solver={solver.name}: ⋆{k} of operator={dec.star_variant.name} is not positive on "
                                  f"{bad} {k}-simplices (non-Delaunay or right-angled cells), so the Poisson systems of "
                                  "app=hodge are indefinite; use `operator=whitney` with `operator.lumped=true` "
                                  f"(an SPD ⋆{k} on every mesh){other}")
        if dec is not None and k <= dec.n and getattr(solver, "needs_spd", False) and not dec.star_is_diagonal(k):
            raise ConfigError(f"solver={solver.name}: with a Galerkin ⋆{k} (operator={dec.star_variant.name}) the "
                              "coexact part of app=hodge is a symmetric indefinite saddle-point system; use "
                              "`solver=iterative` (GMRES with an incomplete LU), `solver=direct` (or "
                              "`operator.lumped=true`)")

    def outputs(self) -> dict[str, Output]:
        """The k-form and its parts (k-simplices), their vectors per top simplex, the potentials
        α ((k−1)-simplices) and β ((k+1)-simplices)."""
        k = int(self.degree)
        parts = ("omega", "exact", "coexact", "harmonic")
        return {**{name: Output(str(k)) for name in parts}, **{f"{name}_vectors": Output("dual0", 3) for name in parts},
                "alpha": Output(str(k - 1)), "beta": Output(str(k + 1))}

    def run(self, ctx: Context) -> Result:
        """Decompose the configured k-form; see the module docstring.

        Fields: ``omega``, ``exact``, ``coexact``, ``harmonic`` (n_k,) k-forms (1-forms carry
        their edge list) and their Whitney vectors at the barycenters of the top simplices
        ``*_vectors`` (n_n, 3); ``alpha`` (n_{k-1},), ``beta`` (n_{k+1},) the potentials.

        Metrics: ``orthogonality_exact_coexact`` / ``_exact_harmonic`` / ``_coexact_harmonic``
        (|⟨a,b⟩_⋆k|/‖ω‖²) and ``orthogonality_max``; ``reconstruction_error_relative``;
        ``energy_fraction_{exact,coexact,harmonic}``; ``harmonic_curl_relative``
        ‖dγ‖_⋆/‖dω‖_⋆ and ``harmonic_codifferential_relative`` ‖δγ‖_⋆/‖δω‖_⋆ (γ is harmonic:
        both ≈ 0; absent when γ or dω / δω is zero to round-off (:mod:`decrun.methods.hodge_metrics`):
        a ratio of round-off means nothing); ``harmonic_dimension`` (dim ker Δ_k, numerically),
        ``betti_<k>``, ``harmonic_dimension_matches_betti``; ``degree``; ``solve_seconds``.
        """
        K, dec, k = ctx.complex, ctx.dec, int(self.degree)
        omega = input_form(K, self, ctx)
        start = time.perf_counter()
        with ctx.task("Hodge decomposition (two Poisson solves)"):
            parts = HodgeDecomposer(dec, k, ctx.new_solver).decompose(omega)
        seconds = time.perf_counter() - start
        named = {"exact": parts.exact, "coexact": parts.coexact, "harmonic": parts.harmonic}
        metrics = orthogonality_metrics(dec, omega, named, k)
        metrics["degree"] = k
        metrics.update(harmonic_residuals(dec, omega, parts.harmonic, metrics, k))
        betti = ctx.betti(k)
        if betti is not None:
            metrics[f"betti_{k}"] = betti
        if self.harmonic_dimension:
            start = time.perf_counter()
            with ctx.task(f"harmonic basis (dim ker Δ{k})"):
                h = harmonic_basis(dec, k, ctx.new_solver).shape[1]
            seconds += time.perf_counter() - start
            metrics["harmonic_dimension"] = int(h)
            if betti is not None:
                metrics["harmonic_dimension_matches_betti"] = bool(h == betti)
        metrics["solve_seconds"] = seconds
        metrics["input"] = str(self.input if self.input != "analytic" else self.analytic)
        wrap = FieldOnEdges if k == 1 else (lambda form: form)
        fields = {"omega": wrap(omega), **{name: wrap(form) for name, form in named.items()}}
        sharp = whitney_sharp if k == 1 else (lambda K_, form: whitney_sharp2(K_, form))
        vectors = {f"{name}_vectors": embed3(sharp(K, form)) for name, form in (("omega", omega), *named.items())}
        fields.update(vectors)
        if parts.alpha is not None:
            fields["alpha"] = parts.alpha
        if parts.beta is not None:
            fields["beta"] = parts.beta
        figures = {"hodge_parts": Figure.of_kind(
            "hodge_parts", vectors=vectors,
            energy={name: metrics.get(f"energy_fraction_{name}", 0.0) for name in named},
            max_arrows=int(self.figure_arrows))}
        return Result(fields=fields, metrics=metrics, figures=figures)


def mesh_frame(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(c, E, s) of the ``frame`` field: :func:`decrun.core.geometry.principal_frame` of the
    vertices (centroid, principal axes as rows by decreasing variance, RMS radius)."""
    c, E, s, _ = principal_frame(vertices)
    if not s > 0:
        raise ConfigError("app.analytic=frame: all vertices coincide (no frame); use `app.input=random`")
    return c, E, s


def analytic_field(name: str, a, vertices: np.ndarray | None = None) -> callable:
    """The vector field X: (N, 3) → (N, 3) called ``name`` (module docstring); ``frame``
    needs the mesh's ``vertices`` (its frame, :func:`mesh_frame`)."""
    a = np.asarray(a, dtype=np.float64)

    def gradient(x):
        return np.broadcast_to(a, x.shape).copy()

    def rotated_gradient(x):
        return np.cross(x / np.linalg.norm(x, axis=1, keepdims=True), a)

    def rotation(x):
        return np.cross(a, x)

    def toroidal(x):
        r2 = x[:, 0] ** 2 + x[:, 1] ** 2
        return np.stack([-x[:, 1] / r2, x[:, 0] / r2, np.zeros(len(x))], axis=1)

    def mixed(x):
        return gradient(x) + rotated_gradient(x) + toroidal(x)

    if name == "frame":
        if vertices is None:
            raise ValueError("analytic_field('frame', ...) needs the mesh's vertices")
        c, E, s = mesh_frame(vertices)

        def frame(x):
            r = x - c
            u = r @ E.T / s  # (N, 3) frame coordinates
            exact = E[0] + u[:, 1:2] * E[1]  # s ∇(u1 + u2²/2)
            rotation = np.cross(E[2], r) / s  # about the axis of least variance
            bounded = np.sin(np.pi * u[:, 0:1]) * E[1]
            return exact + rotation + bounded

        return frame
    return {"gradient": gradient, "rotated_gradient": rotated_gradient, "rotation": rotation,
            "toroidal": toroidal, "mixed": mixed}[name]


def input_form(K, cfg, ctx: Context | None = None) -> np.ndarray:
    """The k-form to decompose, (n_k,), as configured (``app.input``, ``app.degree``): line
    integrals (k = 1) or fluxes (k = 2) of the analytic field, or ξ_σ |σ| with ξ ~ N(0, 1);
    ``input=result`` reads the previous run through ``ctx.read_result``."""
    k = int(getattr(cfg, "degree", 1))
    if cfg.input == "analytic":
        X = analytic_field(cfg.analytic, cfg.vector, K.vertices)
        with np.errstate(divide="ignore", invalid="ignore"):
            if k == 2:
                omega = sample_flux(K, X, order=min(int(cfg.quadrature_order), 2))
            elif K.embedding_dim == 2:  # planar meshes: evaluate in the z = 0 plane
                omega = sample_vector_field(K, lambda p: X(embed3(p))[:, :2], order=int(cfg.quadrature_order))
            else:
                omega = sample_vector_field(K, X, order=int(cfg.quadrature_order))
        bad = np.flatnonzero(~np.isfinite(omega))
        if bad.size:
            raise ConfigError(f"app.analytic={cfg.analytic}: the field is not finite on {bad.size} {k}-simplices "
                              f"(e.g. {bad[:5].tolist()}: the toroidal part is singular on the z axis, the rotated "
                              "gradient at the origin); use `app.analytic=frame` (smooth everywhere, the default), "
                              "`app.input=random` (or `app.analytic=gradient`)")
        return omega
    if cfg.input == "random":
        size = simplex_volumes(K.vertices[K.simplices(k)])
        return np.random.default_rng(int(cfg.seed)).standard_normal(size.size) * size
    if ctx is None:
        raise ConfigError("app.input=result needs a context that can read result files (the decrun runner)")
    return _form_from_result(K, cfg, ctx)


def _form_from_result(K, cfg, ctx: Context) -> np.ndarray:
    path = cfg.input_path
    k = int(getattr(cfg, "degree", 1))
    result, vertices = ctx.read_result(path)
    if cfg.input_field not in result.fields:
        raise ConfigError(f"app.input_field: {path} has no field {cfg.input_field!r}; it has {sorted(result.fields)}")
    omega = np.asarray(result.fields[cfg.input_field], dtype=np.float64)
    if omega.shape != (K.num_simplices(k),):
        raise ConfigError(f"app.input_field: {cfg.input_field!r} in {path} has shape {omega.shape}, "
                          f"but this mesh has {K.num_simplices(k)} {k}-simplices (use the same mesh config as that run)")
    if vertices.shape != K.vertices.shape or not np.allclose(vertices, K.vertices):
        raise ConfigError(f"app.input_path: the mesh stored in {path} differs from this run's mesh "
                          "(use the same mesh config as that run)")
    bad = np.flatnonzero(~np.isfinite(omega))
    if bad.size:
        raise ConfigError(f"app.input_field: {cfg.input_field!r} in {path} holds NaN or ±inf on {bad.size} "
                          f"{k}-simplices (e.g. {bad[:5].tolist()}: the source run diverged?); decompose a finite "
                          "field, e.g. `app.input=random`")
    return omega
