"""``app=parametrization``: conformal mesh parametrization (thesis ch. 5).

Solves the Dirichlet problem of eq. 5.2/5.3 for texture coordinates ``uv`` with a chosen
border (``circle`` | ``circle_arclength`` | ``conformal`` (eq. 5.8–5.9) | ``free``) and
interior weights (``dec`` = ⋆0⁻¹ d1^dual ⋆1 d0 | ``uniform`` (Tutte) | ``mean_value`` (Floater)),
several borders as in §5.2.3 — see :func:`decrun.methods.parametrization.parametrize` — and reports
the distortion and validity metrics of :mod:`decrun.methods.parametrization_metrics`.

Laplacian used: eq. 5.3's ⋆0⁻¹ d1^dual ⋆1 d0, the Laplace–Beltrami operator (= −Δ0 of
``dec.laplacian(0)``), rows normalized as after eq. 5.7.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from decrun.apps.base import App, Context, Figure, Output, Result
from decrun.errors import ConfigError, TopologyError
from decrun.methods.parametrization import (
    CAUCHY_RIEMANN,
    CONFORMAL,
    PINNED,
    Border,
    Holes,
    ReflexRows,
    Weights,
    SYMMETRIC_WEIGHTS,
    check_disk_topology,
    harmonic_matrix,
    parametrize,
)
from decrun.methods.parametrization_metrics import (
    angle_distortion,
    border_vertex_uv_angles,
    majority_orientation,
    parametrization_metrics,
    quasi_conformal_distortion,
    signed_uv_areas,
)


def hole_override(K) -> str:
    """The override cutting a ball around the vertex of largest z out of ``K`` (radius: a
    quarter of the bounding-box diagonal), e.g. ``mesh.hole_balls=[[0.0,0.0,1.0,0.5]]``."""
    x = np.asarray(K.vertices, dtype=np.float64)
    top = x[int(np.argmax(x[:, 2]))]
    radius = 0.25 * float(np.linalg.norm(x.max(axis=0) - x.min(axis=0)))
    return "mesh.hole_balls=[[" + ",".join(f"{c:.4g}" for c in (*top, radius)) + "]]"


@dataclass
class Parametrization(App):
    """Options of ``app=parametrization`` (conf/app/parametrization.yaml).

    border: circle | circle_arclength | conformal | free
    weights: dec | uniform | mean_value (interior rows; with ``free`` they solve the interior
        against the free border, ``dec`` is the least-squares conformal map itself)
    reflex_rows: cauchy_riemann (default: the DEC row closed by ⋆dx = dy on the border — exact
        on developable patches, where the thesis' rule is not) | harmonic (the thesis' rule,
        §5.2.3: ``app.reflex_rows=harmonic``) — the row of border vertices reflex under eq. 5.8
    exterior_border: index into the border loops sorted longest first; null = the longest
    checker_squares: squares per side of the checkerboard texture figure
    holes: auto | fill | conformal — inner borders closed by a virtual vertex each (``fill``:
        the disk theorem applies, so Tutte/Floater maps stay embeddings) or given eq. 5.9 rows
        (``conformal``, §5.2.3); ``auto`` fills under circle borders
    """

    name = "parametrization"
    one_piece = "one disk-like surface is mapped into [0, 1]²"
    headline_metrics = ("is_embedding", "flipped_triangles", "angle_distortion_mean_deg", "qc_distortion_max")
    form_degrees = (0,)
    border: Border = Border.conformal
    weights: Weights = Weights.dec
    reflex_rows: ReflexRows = ReflexRows.cauchy_riemann
    exterior_border: Optional[int] = None
    checker_squares: int = 10
    holes: Holes = Holes.auto

    def __post_init__(self):  # the closed sets, also for Python callers (strings)
        self.border = Border.of(self.border, "app.border")
        self.weights = Weights.of(self.weights, "app.weights")
        self.reflex_rows = ReflexRows.of(self.reflex_rows, "app.reflex_rows")
        self.holes = Holes.of(self.holes, "app.holes")

    def check_solver(self, solver, dec=None) -> None:
        """Pinned borders with symmetric weights give SPD systems (cg, amg apply); the
        conformal border's eq. 5.9 rows, the Cauchy–Riemann rows and the mean-value weights do
        not: those need solver=direct or solver=pardiso."""
        if not getattr(solver, "needs_spd", False):
            return
        reasons = []
        if self.weights not in SYMMETRIC_WEIGHTS:
            reasons.append(f"app.weights={self.weights} is not symmetric")
        if self.border == "conformal":
            reasons.append("app.border=conformal adds the eq. 5.9 rows coupling x and y")
        if dec is not None and self.border != "free" and len(dec.K.border_loops()) > 1 and not self.fills_holes:
            reasons.append("the holes' border rows are eq. 5.9 (§5.2.3), coupling x and y")
        if reasons:
            raise ConfigError(f"solver={solver.name}: app=parametrization solves unsymmetric systems here "
                              f"({'; '.join(reasons)}); use `solver=iterative` (GMRES with an incomplete LU), "
                              f"`solver=direct` (or `solver=pardiso`), or "
                              f"`app.border=circle` with app.weights=dec|uniform")

    @property
    def fills_holes(self) -> bool:
        """True when inner borders are closed by virtual vertices (``app.holes``)."""
        return self.holes == "fill" or (self.holes == "auto" and self.border in ("circle", "circle_arclength"))

    def check(self, K, dec) -> None:
        if not K.border_vertices().any() and K.embedding_dim == 3:
            raise TopologyError(f"app=parametrization needs a disk-like surface with a border; this mesh is closed "
                                f"(χ = {K.euler_characteristic}): cut a hole into it, e.g. "
                                f"`{hole_override(K)}`")
        check_disk_topology(K)

    def outputs(self) -> dict[str, Output]:
        """uv per vertex (the texture coordinates), row kinds per vertex, distortions per face."""
        return {"uv": Output("0", 2), "row_kind": Output("0"), "qc_distortion": Output("dual0"),
                "angle_distortion_deg": Output("dual0"), "flipped": Output("dual0")}

    def run(self, ctx: Context) -> Result:
        """Parametrize the mesh (a connected genus-0 triangle mesh with border) into [0, 1]².

        Fields: ``uv`` (n0, 2), ``row_kind`` (n0,), per triangle ``qc_distortion`` and
        ``angle_distortion_deg`` (n2,), ``flipped``. A map that is not an embedding says so in
        a warning (:func:`not_an_embedding`, with the override that gives one: the run's
        closing line and the metric ``warnings``) and in red on both figures. Metrics: see
        :func:`decrun.methods.parametrization_metrics.parametrization_metrics` plus
        ``solve_seconds``, ``negative_weights`` (off-diagonal entries < 0 in the harmonic
        matrix, violations of eq. 5.7), ``reflex_border_vertices_predicted`` (under
        α^mapped) and ``reflex_border_vertices_unconstrained`` (reflex in uv but pinned or
        given eq. 5.9 — a failed Gortler condition 5).
        """
        K, dec = ctx.complex, ctx.dec
        with ctx.task(f"parametrization ({self.border} border, {self.weights} weights)"):
            result = parametrize(dec, ctx.new_solver, border=str(self.border), weights=str(self.weights),
                                 exterior=self.exterior_border, reflex_rows=str(self.reflex_rows),
                                 holes=str(self.holes))
        faces = K.oriented_simplices()
        uv = result.uv
        metrics = parametrization_metrics(K.vertices, uv, faces, result.loops)

        A = harmonic_matrix(dec, self.weights).tocoo()
        off_diagonal = A.row != A.col
        border = np.concatenate(result.loops)
        uv_angle = border_vertex_uv_angles(uv, faces, K.num_simplices(0))
        reflex_uv = np.zeros(K.num_simplices(0), dtype=bool)
        reflex_uv[border] = uv_angle[border] > np.pi + 1e-9
        unconstrained = reflex_uv & np.isin(result.row_kind, [PINNED, CONFORMAL])
        metrics.update(
            solve_seconds=float(result.solve_seconds),
            negative_weights=int(np.sum(A.data[off_diagonal] < 0)),
            border_loops=len(result.loops),
            reflex_border_vertices_predicted=int(result.reflex_predicted),
            reflex_border_vertices_unconstrained=int(unconstrained.sum()),
            cauchy_riemann_rows=int(np.sum(result.row_kind == CAUCHY_RIEMANN)),
        )

        face_angle_error_deg = np.degrees(angle_distortion(K.vertices, uv, faces)).mean(axis=1)
        flipped = signed_uv_areas(uv, faces) * majority_orientation(uv, faces) < 0
        fields = {
            "uv": uv,
            "row_kind": result.row_kind,
            "qc_distortion": quasi_conformal_distortion(K.vertices, uv, faces),
            "angle_distortion_deg": face_angle_error_deg,
            "flipped": flipped,
        }
        title = f"border={self.border}, weights={self.weights}"
        warning = not_an_embedding(metrics)
        figures = {
            "uv_layout": Figure.of_kind("uv_layout", uv=uv, faces=faces, angle_distortion_deg=face_angle_error_deg,
                                        flipped=flipped, title=title, warning=warning),
            "checkerboard": Figure.of_kind("checkerboard", uv=uv, faces=faces, squares=int(self.checker_squares),
                                           title=title, warning=warning),
        }
        warnings = [f"{warning}; `app.border=circle` with `app.weights=mean_value` is one (Floater's map into a "
                    "convex border, holes filled: positive weights, an embedding by Tutte's theorem)"] if warning else []
        return Result(fields=fields, metrics=metrics, figures=figures, warnings=warnings)


def not_an_embedding(metrics: dict) -> str:
    """"" for an embedding (``metrics['is_embedding']``), else the short line that says why
    not: ``not an embedding: 16 flipped, 2 border self-intersections`` (the nonzero counts of
    flipped and degenerate triangles and border self-intersections, and a wrong border winding)."""
    if metrics["is_embedding"]:
        return ""
    counts = [f"{metrics[key]} {what}" for key, what in (("flipped_triangles", "flipped triangles"),
                                                         ("degenerate_triangles", "degenerate triangles"),
                                                         ("border_self_intersections", "border self-intersections"))
              if metrics.get(key)]
    if metrics.get("border_winding_ok") is False:
        counts.append("border winding wrong")
    return "not an embedding: " + (", ".join(counts) or "see the metrics")
