"""Mesh smoothing by mean curvature flow (thesis §1.3, after Desbrun et al. [DMSB99]).

The flow moves every surface point along its mean-curvature normal,

    ∂x/∂t = Δ_M x,        (§1.3; Δ_M x = -2 H n)

which decreases the area. Δ_M is the Laplace–Beltrami operator with the analyst's sign
(Δ = div grad, *negative* semi-definite). decrun's ``dec.laplacian(0)`` is the
Laplace–de Rham operator δd = ⋆0⁻¹ d0ᵀ ⋆1 d0 with the codifferential of eq. 4.14, which
is *positive* semi-definite, so

    Δ_M = -L,     L = dec.laplacian(0) = M⁻¹ S,     M = ⋆0 (diagonal),  S = d0ᵀ ⋆1 d0.

(The thesis writes the flow as ∂v/∂t = δd v; with its eq. 4.14 sign of δ that would be
the *backward* heat equation — the classic sign trap. The flow used here is ∂v/∂t = -L v.)

Time integration, for each coordinate column of the vertex array ``v`` (n0, 3):

- explicit Euler (§1.3):  v_{n+1} = v_n - dt L v_n,
  stable only for dt < dt_crit = 2 / λ_max, λ_max the largest eigenvalue of L
  (generalized eigenproblem S φ = λ M φ);
- implicit Euler (§1.3):  (Id + dt L) v_{n+1} = v_n, solved in the symmetric form
  (M + dt S) v_{n+1} = M v_n (the same equation multiplied by M = ⋆0), so the matrix is
  symmetric positive definite whenever ⋆0 > 0 and S is PSD (cg/amg apply). It is
  factorized once and reused every step; stable for every dt.

The operator is built once on the initial (noisy) mesh (the linearized flow of
[DMSB99]); ``operator.star`` picks the ⋆0 variant. Because the flow shrinks the mesh, it
is rescaled after every step (the thesis' note) about the ⋆0-weighted centroid, which
the flow itself leaves fixed: ``rescale: volume`` keeps the enclosed volume (closed
surfaces only), ``area`` the surface area, ``none`` nothing.

Blow-up: a step *diverges* when a coordinate is NaN/inf or when the roughness

    R(v) = Σ_xyz (v-c)ᵀ S (v-c) / Σ_xyz (v-c)ᵀ M (v-c)      (c: ⋆0-weighted centroid)

— the Rayleigh quotient of L, the ⋆0-weighted mean eigenvalue of the shape's spectrum,
units 1/length², unchanged by rescaling — exceeds ``blowup_factor`` times its initial
value. A stable step damps high eigenvalues more than low ones, so R does not grow;
the explicit instability pumps the top eigenvector (R → λ_max). The run then stops and
records ``stable: false`` and ``diverged_at_step``.

Shape quality: the distortion ρ(v) = E(v) / (2 A(v)) with E(v) = Σ_xyz vᵀ S v (Dirichlet
energy w.r.t. the input mesh). Per triangle |∇v|² = σ1² + σ2² ≥ 2 σ1σ2, so ρ ≥ 1 always
and ρ = 1 exactly for the input; it grows when the mesh folds, crumples or flattens.

Note: with the operator fixed on the input mesh, a *long* implicit run (dt·steps ≫ 1/λ₁)
drifts towards the lowest eigenvector of L and degenerates (flattens) even though each
step is a contraction; keep dt·steps moderate or watch ``distortion_final``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.errors import ConfigError, TopologyError
from decrun.core.geometry import triangle_areas
from decrun.runner.results import Result

SCHEMES = ("explicit", "implicit")
RESCALE = ("volume", "area", "none")


@dataclass
class Config:
    """Schema of ``cfg.app`` for smoothing (conf/app/smoothing.yaml)."""

    name: str = "smoothing"
    scheme: str = "implicit"  # explicit | implicit (Euler, §1.3)
    dt: float = 0.005  # time step (model units squared: L has units 1/length²)
    steps: int = 10
    rescale: str = "volume"  # volume | area | none, applied after every step
    blowup_factor: float = 10.0  # a step diverges when the roughness R exceeds this × R_0
    critical_dt: bool = True  # compute the explicit stability limit 2/λ_max (one eigsh)

    def __post_init__(self):
        if self.scheme not in SCHEMES:
            raise ConfigError(f"app.scheme: must be one of {list(SCHEMES)}, got {self.scheme!r}")
        if self.rescale not in RESCALE:
            raise ConfigError(f"app.rescale: must be one of {list(RESCALE)}, got {self.rescale!r}")
        if not (self.dt > 0 and np.isfinite(self.dt)):
            raise ConfigError(f"app.dt: the time step must be > 0, got {self.dt}")
        if self.steps < 0:
            raise ConfigError(f"app.steps: must be >= 0, got {self.steps}")
        if not self.blowup_factor > 1:
            raise ConfigError(f"app.blowup_factor: must be > 1, got {self.blowup_factor}")


# ----------------------------------------------------------------------------------
# geometry of a triangle mesh (vectorized over faces)
# ----------------------------------------------------------------------------------


def surface_area(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Total area Σ ½|(p1-p0)×(p2-p0)| of the triangles (2-D or 3-D vertices)."""
    return float(triangle_areas(vertices, faces).sum())


def enclosed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed volume (1/6) Σ p0 · (p1 × p2) enclosed by a closed, consistently oriented
    surface (divergence theorem); positive for outward-oriented faces."""
    p0, p1, p2 = (vertices[faces[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", p0, np.cross(p1, p2)).sum() / 6.0)


def explicit_critical_dt(S: sp.spmatrix, M: np.ndarray) -> float:
    """dt_crit = 2 / λ_max for explicit Euler on v' = -M⁻¹ S v (λ_max: largest eigenvalue of
    S φ = λ M φ). NaN when it cannot be computed (⋆0 not positive, no convergence)."""
    if np.any(M <= 0) or S.shape[0] < 3:
        return float("nan")
    scale = sp.diags(1.0 / np.sqrt(M))
    A = (scale @ S @ scale).tocsr()
    try:
        lam = spla.eigsh(A, k=1, which="LA", tol=1e-8, return_eigenvectors=False,
                         v0=np.ones(A.shape[0]), maxiter=20 * A.shape[0])[0]
    except (spla.ArpackNoConvergence, ValueError):
        return float("nan")
    return float(2.0 / lam) if lam > 0 else float("inf")


# ----------------------------------------------------------------------------------
# the application
# ----------------------------------------------------------------------------------


def run(complex, dec, solver, cfg, progress) -> Result:
    """Smooth ``complex`` by mean curvature flow (§1.3); see the module docstring.

    Metrics: ``area_ratio`` (final/initial area), ``volume_drift_rel`` (|V_end - V_0|/|V_0|,
    NaN for open or planar meshes), ``stable``, ``diverged_at_step`` (-1 when stable),
    ``steps_done``, ``roughness_ratio`` (R_end / R_0), ``distortion_final`` (ρ, 1 for the input), ``dt_critical_explicit`` and
    ``dt_over_critical``, ``distance_to_clean_rms`` and ``distance_to_clean_rms_initial``
    (RMS vertex distance to the noise-free mesh / its bounding-box diagonal, only with
    noise), ``negative_star1_fraction``, ``setup_seconds``, ``solve_seconds``.
    Series (steps_done + 1 entries, initial state first): ``area``, ``volume``, ``roughness``,
    ``distortion``.
    Fields: ``vertices_initial``, ``vertices_final`` (n0, d), ``faces`` (n2, 3),
    ``displacement`` (n0,).
    """
    K = complex
    if K.dim != 2:
        raise TopologyError(f"smoothing needs a triangle mesh (dimension 2), got dimension {K.dim}")
    scheme, dt, steps, rescale = str(cfg.scheme), float(cfg.dt), int(cfg.steps), str(cfg.rescale)
    faces = K.oriented_simplices()
    vertices = np.array(K.vertices, dtype=np.float64)
    closed = not bool(K.boundary_vertices().any())
    has_volume = closed and vertices.shape[1] == 3
    if rescale == "volume" and not has_volume:
        raise ConfigError("app.rescale=volume needs a closed surface in 3-D; this mesh has a border "
                          "or is planar: use app.rescale=area or app.rescale=none")

    t0 = time.perf_counter()
    M = dec.star_diagonal(0)  # ⋆0: dual (Voronoi / mixed / barycentric) vertex areas
    S = dec.laplacian_symmetric(0)  # d0ᵀ ⋆1 d0, cot stiffness (symmetric)
    L = dec.laplacian(0)  # M⁻¹ S = δd (eq. 4.14), PSD; Laplace–Beltrami Δ_M = -L
    star1 = dec.star_diagonal(1)
    if scheme == "implicit":
        solver.factorize(sp.diags(M) + dt * S)  # (M + dt S) v_{n+1} = M v_n, once
    dt_crit = explicit_critical_dt(S, M) if cfg.critical_dt else float("nan")
    setup_seconds = time.perf_counter() - t0
    centroid = (M @ vertices) / M.sum()  # conserved by both schemes: 1ᵀ S = 0

    def roughness(v):
        w = v - centroid
        denominator = float(np.einsum("ij,ij->", w, M[:, None] * w))
        return float(np.einsum("ij,ij->", w, S @ w)) / denominator if denominator > 0 else float("inf")

    def distortion(v):
        area = surface_area(v, faces)
        energy = float(np.einsum("ij,ij->", v, S @ v))
        return energy / (2.0 * area) if area > 0 else float("inf")

    area0 = surface_area(vertices, faces)
    volume0 = enclosed_volume(vertices, faces) if has_volume else float("nan")
    rho0, rough0 = distortion(vertices), roughness(vertices)
    areas, volumes, distortions, roughs = [area0], [volume0], [rho0], [rough0]
    v = vertices.copy()
    diverged_at = -1
    t1 = time.perf_counter()
    for step in progress(range(1, steps + 1), total=steps, desc=f"smoothing ({scheme})"):
        if scheme == "explicit":
            v = v - dt * (L @ v)  # v_{n+1} = v_n + dt Δ_M v_n, Δ_M = -L
        else:
            v = solver.solve(M[:, None] * v)  # (M + dt S) v_{n+1} = M v_n
        if not np.all(np.isfinite(v)):
            diverged_at = step
            break
        if rescale == "volume":
            volume = enclosed_volume(v, faces)
            if not volume > 0:  # flattened or turned inside out: cannot be rescaled
                diverged_at = step
                break
            v = centroid + np.cbrt(volume0 / volume) * (v - centroid)
        elif rescale == "area":
            area = surface_area(v, faces)
            if area > 0:
                v = centroid + np.sqrt(area0 / area) * (v - centroid)
        rough = roughness(v)
        areas.append(surface_area(v, faces))
        volumes.append(enclosed_volume(v, faces) if has_volume else float("nan"))
        distortions.append(distortion(v))
        roughs.append(rough)
        if not (np.isfinite(areas[-1]) and rough <= cfg.blowup_factor * rough0):
            diverged_at = step
            break
    solve_seconds = time.perf_counter() - t1
    stable = diverged_at < 0

    metrics = {
        "stable": stable,
        "diverged_at_step": diverged_at,
        "steps_done": len(areas) - 1,
        "area_ratio": areas[-1] / area0,
        "volume_drift_rel": abs(volumes[-1] - volume0) / abs(volume0) if has_volume else float("nan"),
        "roughness_ratio": roughs[-1] / rough0,
        "distortion_final": distortions[-1],
        "dt_critical_explicit": dt_crit,
        "dt_over_critical": dt / dt_crit if np.isfinite(dt_crit) and dt_crit > 0 else float("nan"),
        "negative_star1_fraction": float(np.mean(star1 < 0)),
    }
    meta = getattr(K, "meta", None) or {}
    clean = meta.get("clean_vertices")
    if clean is not None and np.shape(clean) == vertices.shape:
        clean = np.asarray(clean)
        diagonal = float(np.linalg.norm(clean.max(axis=0) - clean.min(axis=0)))

        def rms(x):
            return float(np.sqrt(np.mean(np.sum((x - clean) ** 2, axis=1))) / diagonal)

        metrics["distance_to_clean_rms"] = rms(v) if stable else float("nan")
        metrics["distance_to_clean_rms_initial"] = rms(vertices)
    metrics["setup_seconds"] = setup_seconds
    metrics["solve_seconds"] = solve_seconds

    series = {"area": np.array(areas), "volume": np.array(volumes), "roughness": np.array(roughs), "distortion": np.array(distortions)}
    fields = {
        "vertices_initial": vertices,
        "vertices_final": v,
        "faces": faces,
        "displacement": np.linalg.norm(v - vertices, axis=1),
    }
    return Result(fields=fields, series=series, metrics=metrics, figures=_figures(vertices, v, faces, series, cfg, stable, diverged_at))


def _figures(before, after, faces, series, cfg, stable, diverged_at):
    from decrun.runner import plots

    label = f"{cfg.scheme} Euler, dt={cfg.dt:g}, rescale={cfg.rescale}"
    state = f"{len(series['area']) - 1} steps" if stable else f"diverged at step {diverged_at}"
    shown_after = after if np.all(np.isfinite(after)) else before
    figures = {
        "smoothing": plots.before_after(before, shown_after, faces, titles=("input", f"after {state}"),
                                        suptitle=f"mean curvature flow (§1.3): {label}"),
        "smoothing_series": plots.plot_series(series, ["area", "volume", "roughness"] if np.isfinite(series["volume"][0]) else ["area", "roughness"],
                                              title=label),
    }
    return figures
