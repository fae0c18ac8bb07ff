"""Mean curvature flow (thesis §1.3, after Desbrun et al. [DMSB99]) as a time stepper.

The flow moves every surface point along its mean-curvature normal,

    ∂x/∂t = Δ_M x,        (§1.3; Δ_M x = -2 H n)

which decreases the area. Δ_M is the Laplace–Beltrami operator with the analyst's sign
(Δ = div grad, *negative* semi-definite). decrun's ``dec.laplacian(0)`` is the
Laplace–de Rham operator δd = ⋆0⁻¹ d0ᵀ ⋆1 d0 with the codifferential of eq. 4.14, which is
*positive* semi-definite, so

    Δ_M = -L,     L = dec.laplacian(0) = M⁻¹ S,     M = ⋆0 (diagonal),  S = d0ᵀ ⋆1 d0.

(The thesis writes the flow as ∂v/∂t = δd v; with its eq. 4.14 sign of δ that would be the
*backward* heat equation — the classic sign trap. The flow used here is ∂v/∂t = -L v.)

Time integration of the vertex array ``v`` (n0, 3), one column per coordinate:

- explicit Euler (§1.3):  v_{n+1} = v_n - dt L v_n, stable only for dt < dt_crit = 2/λ_max,
  λ_max the largest eigenvalue of S φ = λ M φ (:func:`explicit_critical_dt`);
- implicit Euler (§1.3):  (Id + dt L) v_{n+1} = v_n, solved in the symmetric form
  (M + dt S) v_{n+1} = M v_n (multiplied by M = ⋆0), symmetric positive definite whenever
  ⋆0 > 0 and S is PSD (cg/amg apply); factorized once, stable for every dt.

The operator is built once on the initial mesh (the linearized flow of [DMSB99]).

Measurements: the roughness R(v) = Σ_xyz (v-c)ᵀ S (v-c) / Σ_xyz (v-c)ᵀ M (v-c) (c: the
⋆0-weighted centroid, which both schemes conserve) is the Rayleigh quotient of L — the
⋆0-weighted mean eigenvalue of the shape, units 1/length², unchanged by rescaling; a stable
step does not increase it, the explicit instability pumps it towards λ_max. The distortion
ρ(v) = E(v) / (2 A(v)), E(v) = Σ_xyz vᵀ S v, is ≥ 1 (per triangle |∇v|² = σ1² + σ2² ≥ 2σ1σ2)
with equality for the input mesh; it grows when the mesh folds, crumples or flattens.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.core.choices import Choice
from decrun.core.geometry import triangle_areas

__all__ = ["Scheme", "SCHEMES", "MeanCurvatureFlow", "surface_area", "enclosed_volume", "explicit_critical_dt",
           "largest_eigenvalue", "smallest_positive_eigenvalue", "resolution_dt", "TimeStep", "choose_time_step",
           "SmoothingStepper"]


class Scheme(Choice):
    """``app.scheme``: the two Euler schemes of §1.3."""

    implicit = "implicit"
    explicit = "explicit"


SCHEMES = tuple(Scheme.names())


def surface_area(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Total area Σ ½|(p1-p0)×(p2-p0)| of the triangles (2-D or 3-D vertices)."""
    return float(triangle_areas(vertices, faces).sum())


def enclosed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    """Signed volume (1/6) Σ p0 · (p1 × p2) enclosed by a closed, consistently oriented
    surface (divergence theorem); positive for outward-oriented faces."""
    p0, p1, p2 = (vertices[faces[:, i]] for i in range(3))
    return float(np.einsum("ij,ij->i", p0, np.cross(p1, p2)).sum() / 6.0)


#: up to this many vertices λ_max comes from a dense eigen-solve (ARPACK needs k < n;
#: measured: dense eigh takes 0.15 s at n = 162 and 3 s at n = 642, ARPACK 7 ms)
DENSE_EIGEN_MAX = 64


def smallest_positive_eigenvalue(S: sp.spmatrix, M: np.ndarray | sp.spmatrix) -> float:
    """λ_1, the smallest nonzero eigenvalue of S φ = λ M φ on a connected mesh (S PSD with
    the constants as its kernel, M SPD: a diagonal (n,) or a sparse (n, n) mass): the floor
    of the roughness R, a Rayleigh quotient of positions M-orthogonal to the constants, so
    R ≥ λ_1 — on a sphere of radius r, λ_1 ≈ 2/r² (x, y, z are its eigenfunctions), and the
    flow levels off near there (a mean of the three l = 1 eigenvalues) instead of going to 0. Shift-invert ARPACK at a small negative
    shift (S − σM is then SPD); dense ``eigh`` for n ≤ DENSE_EIGEN_MAX. NaN when it fails."""
    n = S.shape[0]
    mass = sp.diags(np.asarray(M, dtype=np.float64)) if not sp.issparse(M) else sp.csr_matrix(M)
    if n < 3:
        return float("nan")
    try:
        if n <= DENSE_EIGEN_MAX:
            import scipy.linalg as la

            values = la.eigh(S.toarray(), mass.toarray(), eigvals_only=True, subset_by_index=[0, 1])
        else:
            shift = -1e-6 * float(abs(S.diagonal()).max() / max(mass.diagonal().max(), 1e-300))
            values = spla.eigsh(S.tocsc(), k=2, M=mass.tocsc(), sigma=shift, which="LM", return_eigenvectors=False,
                                v0=np.random.default_rng(0).standard_normal(n))
    except (spla.ArpackNoConvergence, np.linalg.LinAlgError, RuntimeError):
        return float("nan")
    return float(np.sort(values)[1])


def largest_eigenvalue(S: sp.spmatrix, M: np.ndarray | sp.spmatrix) -> float:
    """λ_max of the generalized symmetric problem S φ = λ M φ (S PSD, M SPD: a diagonal
    (n,) or a sparse (n, n) mass). NaN when ARPACK does not converge.

    Small problems (n ≤ DENSE_EIGEN_MAX) use LAPACK's dense ``eigh``. Larger ones use
    ARPACK with a seeded random start vector: the all-ones vector used before is the
    constant function, the kernel of S, and on a mesh with uniform ⋆0 (a regular
    octahedron) it is exactly an eigenvector of eigenvalue 0, which makes ARPACK stop with
    "starting vector is zero"."""
    n = S.shape[0]
    diagonal = not sp.issparse(M)
    if n <= DENSE_EIGEN_MAX:
        import scipy.linalg as la

        mass = np.diag(np.asarray(M, dtype=np.float64)) if diagonal else M.toarray()
        return float(la.eigh(S.toarray(), mass, eigvals_only=True, subset_by_index=[n - 1, n - 1])[0])
    v0 = np.random.default_rng(0).standard_normal(n)
    try:
        if diagonal:  # the symmetric M^-1/2 S M^-1/2: a standard problem, no factorization of M
            scale = sp.diags(1.0 / np.sqrt(M))
            A = (scale @ S @ scale).tocsr()
            return float(spla.eigsh(A, k=1, which="LA", tol=1e-8, return_eigenvectors=False, v0=v0,
                                    maxiter=20 * n)[0])
        return float(spla.eigsh(S, k=1, M=M.tocsc(), which="LA", tol=1e-8, return_eigenvectors=False, v0=v0,
                                maxiter=20 * n)[0])
    except (spla.ArpackNoConvergence, spla.ArpackError):  # an ARPACK failure is no estimate, never a traceback
        return float("nan")


def gershgorin_safe_dt(S: sp.spmatrix, M: np.ndarray) -> float:
    """2 / max_i (Σ_j |S_ij|) / M_i: a time step ≤ the explicit critical step 2/λ_max without an
    eigen-solve (Gershgorin's discs bound λ_max of S φ = λ M φ for a positive diagonal M (n,)).
    NaN when M is not a positive diagonal."""
    if sp.issparse(M) or M is None or np.any(np.asarray(M) <= 0):
        return float("nan")
    bound = float(np.max(np.asarray(abs(sp.csr_matrix(S)).sum(axis=1)).ravel() / np.asarray(M)))
    return 2.0 / bound if bound > 0 else float("inf")


def explicit_critical_dt(S: sp.spmatrix, M: np.ndarray) -> float:
    """dt_crit = 2 / λ_max for explicit Euler on v' = -M⁻¹ S v (λ_max: largest eigenvalue of
    S φ = λ M φ, :func:`largest_eigenvalue`; M the diagonal ⋆0 (n,) or a sparse Galerkin
    mass). NaN when it cannot be computed (⋆0 not positive, no convergence)."""
    if not sp.issparse(M) and np.any(np.asarray(M) <= 0):
        return float("nan")
    lam = largest_eigenvalue(S, M)
    if not np.isfinite(lam):
        return float("nan")
    return float(2.0 / lam) if lam > 0 else float("inf")


def resolution_dt(mean_edge_length: float) -> float:
    """dt_h = 2 h̄² / π² (length² units): the explicit critical step 2/λ_h of a mesh whose every
    edge had the mean length h̄ — λ_h = (π/h̄)² is the Laplacian's eigenvalue at the shortest
    wavelength such a mesh resolves (2 h̄, noise one edge long).

    A scale for the step of *implicit* Euler, which is stable at any step: one step damps the
    edge-scale mode by 1/(1 + dt λ_h). Unlike 2/λ_max, which the worst triangle sets (λ_max ∝
    cot of the smallest angle / its area), it follows the mesh's typical resolution: on the
    near-uniform icosphere dt_h ≈ 0.8 × 2/λ_max, on pymeshlab's bunny10k scan 370 × and on the cow
    55 × — where a step of 0.75 × 2/λ_max moves no vertex visibly.
    """
    return 2.0 * float(mean_edge_length) ** 2 / np.pi ** 2


class MeanCurvatureFlow:
    """The linearized flow ∂v/∂t = -L v on ``dec``'s mesh with one Euler scheme.

    Parameters
    ----------
    dec : decrun DEC of a triangle mesh; ⋆0 must be diagonal (M), S = ``dec.laplacian_symmetric(0)``
    scheme : ``explicit`` | ``implicit``
    dt : time step (length² units: L has units 1/length²)
    solver : a fresh decrun Solver; the implicit matrix M + dt S is factorized here, once
    """

    def __init__(self, dec, scheme: str, dt: float, solver=None):
        self.dec, self.scheme, self.dt = dec, scheme, float(dt)
        self.M = dec.star_diagonal_or_none(0)  # ⋆0: dual vertex areas, or None for a Galerkin ⋆0
        self.mass = dec.star(0)  # ⋆0 as a sparse matrix (the P1 mass matrix for operator=whitney)
        self.S = dec.laplacian_symmetric(0)  # d0ᵀ ⋆1 d0 (or the variant's stiffness), symmetric PSD
        self.L = dec.laplacian(0)  # M⁻¹ S, PSD; Δ_M = -L (a LinearOperator for a Galerkin ⋆0)
        row_sums = np.asarray(self.mass.sum(axis=1)).ravel()
        self.centroid_weights = row_sums / row_sums.sum()
        if scheme == "implicit":
            self.solver = solver
            self.solver.factorize(self.mass + self.dt * self.S)  # (M + dt S) v_{n+1} = M v_n

    def step(self, v: np.ndarray) -> np.ndarray:
        """v_{n+1} from v_n (n0, d)."""
        if self.scheme == "explicit":
            if self.M is not None:
                return v - self.dt * (self.L @ v)  # v_{n+1} = v_n + dt Δ_M v_n
            return v - self.dt * self.dec.star_solve(0, self.S @ v)  # M⁻¹ by the factorized ⋆0
        if self.M is not None:
            return self.solver.solve(self.M[:, None] * v)  # (M + dt S) v_{n+1} = M v_n
        return self.solver.solve(self.mass @ v)

    def centroid(self, v: np.ndarray) -> np.ndarray:
        """The ⋆0-weighted centroid (conserved by both schemes: 1ᵀ S = 0)."""
        return self.centroid_weights @ v

    def roughness(self, v: np.ndarray, centroid: np.ndarray) -> float:
        """R(v), the Rayleigh quotient of L about ``centroid`` (module docstring)."""
        w = v - centroid
        weighted = self.M[:, None] * w if self.M is not None else self.mass @ w
        denominator = float(np.einsum("ij,ij->", w, weighted))
        return float(np.einsum("ij,ij->", w, self.S @ w)) / denominator if denominator > 0 else float("inf")

    def distortion(self, v: np.ndarray, faces: np.ndarray) -> float:
        """ρ(v) = E(v) / (2 A(v)) ≥ 1 (module docstring)."""
        area = surface_area(v, faces)
        energy = float(np.einsum("ij,ij->", v, self.S @ v))
        return energy / (2.0 * area) if area > 0 else float("inf")

    def critical_dt(self) -> float:
        """dt_crit = 2/λ_max of explicit Euler (:func:`explicit_critical_dt`; the generalized
        problem with the SPD Galerkin mass when ⋆0 is not diagonal)."""
        return explicit_critical_dt(self.S, self.M if self.M is not None else self.mass)


@dataclass(frozen=True)
class TimeStep:
    """The time step of a smoothing run and the scales it was chosen from (length² units).

    dt : the step; None when the chosen unit does not exist on this mesh (``reason`` says why)
    unit : ``critical`` or ``resolution``, the unit ``factor`` multiplied (None: dt was given)
    critical : 2/λ_max of explicit Euler (NaN when not computed or not defined)
    resolution : 2h̄²/π² (:func:`resolution_dt`)
    safe : Gershgorin's bound ≤ ``critical`` (:func:`gershgorin_safe_dt`), only computed when
        the critical unit was asked for without the eigen-solve (else NaN)
    nonpositive_star0 : vertices with ⋆0 ≤ 0 (where 2/λ_max does not exist)
    seconds : the eigen-solve's wall time (s)
    """

    dt: float | None
    unit: str | None
    critical: float
    resolution: float
    safe: float = float("nan")
    nonpositive_star0: int = 0
    seconds: float = 0.0
    reason: str = ""


def choose_time_step(dec, scheme: str, *, dt: float | None = None, factor: float = 0.75, unit: str = "auto",
                     critical: bool = True) -> TimeStep:
    """The smoothing step: ``dt`` when given, else ``factor`` × the unit — ``critical`` 2/λ_max
    (explicit Euler's stability limit, one eigen-solve kept by ``dec``), ``resolution`` 2h̄²/π²
    (:func:`resolution_dt`), ``auto`` critical for the explicit and resolution for the implicit
    scheme. With ``critical`` the eigen-solve runs also when not needed for dt (the metric
    ``dt_over_critical``). Nothing is raised: a unit that does not exist (⋆0 ≤ 0, or the critical
    step without the eigen-solve) leaves ``dt`` None and names why in ``reason``."""
    if unit == "auto":
        unit = "critical" if scheme == "explicit" else "resolution"
    t0 = time.perf_counter()
    dt_crit = float("nan")
    if critical:  # 2/λ_max of S φ = λ ⋆0 φ, once per DEC
        dt_crit = dec.require(("mcf_critical_dt",), lambda: MeanCurvatureFlow(dec, "explicit", 1.0).critical_dt())
    seconds = time.perf_counter() - t0
    dt_resolution = resolution_dt(dec.K.mean_edge_length)
    M = dec.star_diagonal_or_none(0)
    nonpositive = int(np.sum(M <= 0)) if M is not None else 0
    common: dict[str, Any] = dict(critical=dt_crit, resolution=dt_resolution, nonpositive_star0=nonpositive,
                                  seconds=seconds)
    if dt is not None:
        return TimeStep(float(dt), None, **common)
    if unit == "resolution":
        return TimeStep(factor * dt_resolution, unit, **common)
    if not critical:
        safe = gershgorin_safe_dt(dec.laplacian_symmetric(0), M)
        return TimeStep(None, unit, safe=safe, reason="no critical step without the eigen-solve", **common)
    if not (np.isfinite(dt_crit) and dt_crit > 0):
        return TimeStep(None, unit, reason=f"⋆0 is not positive on {nonpositive} vertices", **common)
    return TimeStep(factor * dt_crit, unit, **common)


class SmoothingStepper:
    """The mean curvature flow as a :class:`decrun.methods.stepping.Stepper`: one step is
    ``flow.step`` then the rescale about ``centroid`` (``volume``: by ∛(V_0/V), ``area``: by
    √(A_0/A), ``none``), then the measures ``area``, ``volume``, ``roughness``, ``distortion``
    (NaN when the coordinates are not finite). It blows up when the coordinates are not
    finite, the volume cannot be rescaled (V ≤ 0), the area is not finite or the roughness
    exceeds ``blowup_factor`` × R_0; the diverging step is recorded (its measures NaN when
    the coordinates are). ``vertices`` (n0, d) is the input; state: ``v`` (n0, d), ``last_finite`` (n0, d) and the measures so
    far (``series``, for the figures and the final ratios: four floats per step).
    ``record_vertices``: the recorded values also hold the positions ``vertices`` (n0, d)."""

    record_divergent_step = True
    #: the measures so far grow by one a step (and hold NaN volumes on open surfaces)
    state_variable = ("series",)

    def __init__(self, flow, vertices, faces, centroid, rescale: str, has_volume: bool, blowup_factor: float,
                 record_vertices: bool = False):
        self.flow, self.faces, self.centroid = flow, faces, centroid
        self.record_vertices = bool(record_vertices)
        self.vertices = vertices  # the input (n0, d)
        self.rescale, self.has_volume, self.blowup_factor = rescale, has_volume, float(blowup_factor)
        self.first = self.measure(vertices)
        self.now = dict(self.first)
        self.series = {name: [value] for name, value in self.first.items()}
        self.v = vertices.copy()
        self.last_finite = self.v

    def measure(self, v) -> dict:
        """``area`` A(v), ``volume`` V(v) (NaN on open surfaces), ``roughness`` R(v) and
        ``distortion`` ρ(v) of positions ``v`` (n0, d) (module docstring)."""
        faces = self.faces
        return {"area": surface_area(v, faces),
                "volume": enclosed_volume(v, faces) if self.has_volume else float("nan"),
                "roughness": self.flow.roughness(v, self.centroid), "distortion": self.flow.distortion(v, faces)}

    def values(self) -> dict:
        """The measures of the current state (recorded every step), and its positions
        ``vertices`` (n0, d) with ``record_vertices``."""
        return {**self.now, "vertices": self.v} if self.record_vertices else self.now

    def step(self, n: int) -> str:
        """One flow step and the rescale; the reason it blew up, or ""."""
        v = self.flow.step(self.v)
        first, centroid = self.first, self.centroid
        reason = "" if np.all(np.isfinite(v)) else "non-finite coordinates"
        if not reason and self.rescale == "volume":
            volume = enclosed_volume(v, self.faces)
            if not volume > 0:  # flattened or turned inside out: cannot be rescaled
                reason = f"enclosed volume {volume:.3g} ≤ 0 cannot be rescaled"
            else:
                v = centroid + np.cbrt(first["volume"] / volume) * (v - centroid)
        elif not reason and self.rescale == "area":
            area = surface_area(v, self.faces)
            if area > 0:
                v = centroid + np.sqrt(first["area"] / area) * (v - centroid)
        finite = bool(np.all(np.isfinite(v)))
        self.now = self.measure(v) if finite else {name: float("nan") for name in first}
        for name, value in self.now.items():
            self.series[name].append(value)
        self.v = v
        if finite:
            self.last_finite = v
        if not reason and not np.isfinite(self.now["area"]):
            reason = "non-finite area"
        if not reason and not self.now["roughness"] <= self.blowup_factor * first["roughness"]:
            reason = f"roughness {self.now['roughness']:.3g} > app.blowup_factor × R_0"
        return reason

    def state_dict(self) -> dict:
        """The state a checkpoint keeps: positions, last finite positions, the measures."""
        return {"v": self.v, "last_finite": self.last_finite,
                "now": {name: float(value) for name, value in self.now.items()},
                "series": {name: np.asarray(values, dtype=np.float64) for name, values in self.series.items()}}

    def load_state(self, state: dict) -> None:
        """Resume from :meth:`state_dict`'s output."""
        self.v = np.array(state["v"], dtype=np.float64)
        self.last_finite = np.array(state["last_finite"], dtype=np.float64)
        self.now = {name: float(state["now"][name]) for name in self.first}
        self.series = {name: [float(x) for x in state["series"][name]] for name in self.first}
