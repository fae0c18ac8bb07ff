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

from decrun.methods.parametrization import (
    CAUCHY_RIEMANN,
    CONFORMAL,
    PINNED,
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
from decrun.runner.results import Result


@dataclass
class Config:
    """Schema of ``cfg.app`` for the parametrization.

    border: circle | circle_arclength | conformal | free
    weights: dec | uniform | mean_value (interior rows; with ``free`` they solve the interior
        against the free border, ``dec`` is the least-squares conformal map itself)
    reflex_rows: harmonic (thesis §5.2.3) | cauchy_riemann (DEC row closed by ⋆dx = dy on the
        border; exact on flat meshes) — the row of border vertices reflex under eq. 5.8
    exterior_border: index into the border loops sorted longest first; null = the longest
    checker_squares: squares per side of the checkerboard texture figure
    """

    name: str = "parametrization"
    border: str = "conformal"
    weights: str = "dec"
    reflex_rows: str = "harmonic"
    exterior_border: Optional[int] = None
    checker_squares: int = 10


def _figures(K, uv, faces, face_angle_error_deg, flipped, checker_squares: int, title: str) -> dict:
    from decrun.runner.plots import new_figure, plot_surface

    figures = {}
    fig = new_figure(5.0, 5.0)
    ax = fig.add_subplot()
    mappable = plot_surface(ax, uv, faces, face_angle_error_deg, cmap="magma", vmin=0.0,
                            vmax=max(1.0, float(np.nanmax(face_angle_error_deg))), linewidth=0.15,
                            title=f"uv layout, {title}")
    if flipped.any():
        plot_surface(ax, uv, faces[flipped], np.ones(int(flipped.sum())), cmap="cool", linewidth=0.3)
    fig.colorbar(mappable, ax=ax, shrink=0.7, label="angle distortion (deg, mean per triangle)")
    figures["uv_layout"] = fig

    centroid = uv[faces].mean(axis=1)
    checker = (np.floor(centroid[:, 0] * checker_squares) + np.floor(centroid[:, 1] * checker_squares)) % 2
    fig = new_figure(5.0, 5.0)
    ax = fig.add_subplot(projection="3d" if K.vertices.shape[1] == 3 else None)
    plot_surface(ax, K.vertices, faces, checker, cmap="gray", vmin=-0.3, vmax=1.0, title=f"checkerboard, {title}")
    if K.vertices.shape[1] == 3:
        # look at the surface along its area-weighted mean normal (the open side faces away)
        p = K.vertices[faces]
        normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]).sum(axis=0)
        if np.linalg.norm(normal) > 0:
            normal = normal / np.linalg.norm(normal)
            ax.view_init(elev=float(np.degrees(np.arcsin(np.clip(normal[2], -1, 1)))),
                         azim=float(np.degrees(np.arctan2(normal[1], normal[0]))))
    figures["checkerboard"] = fig
    return figures


def run(complex, dec, solver, cfg, progress=None) -> Result:
    """Parametrize ``complex`` (a connected genus-0 triangle mesh with border) into [0, 1]².

    Raises :class:`decrun.errors.TopologyError` (closed, several components, genus > 0) before
    any solve. Fields: ``uv`` (n0, 2), ``row_kind`` (n0,), per triangle ``qc_distortion`` and
    ``angle_distortion_deg`` (n2,). Metrics: see :func:`parametrization_metrics` plus
    ``solve_seconds``, ``negative_weights`` (off-diagonal entries < 0 in the harmonic matrix,
    violations of eq. 5.7), ``reflex_border_vertices_predicted`` (under α^mapped) and
    ``reflex_border_vertices_unconstrained`` (reflex in uv but pinned or given eq. 5.9 — a
    failed Gortler condition 5).
    """
    K = complex
    result = parametrize(dec, solver, border=cfg.border, weights=cfg.weights,
                         exterior=cfg.exterior_border, reflex_rows=cfg.reflex_rows)
    faces = K.oriented_simplices()
    uv = result.uv
    metrics = parametrization_metrics(K.vertices, uv, faces, result.loops)

    A = harmonic_matrix(dec, cfg.weights).tocoo()
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
    title = f"border={cfg.border}, weights={cfg.weights}"
    figures = _figures(K, uv, faces, face_angle_error_deg, flipped, int(cfg.checker_squares), title)
    return Result(fields=fields, metrics=metrics, figures=figures)
