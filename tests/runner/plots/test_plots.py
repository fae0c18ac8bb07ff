"""Figures that do not mislead: shared axes before/after, checker squares sized to the map."""

from __future__ import annotations

import numpy as np
import pytest

from decrun.core.primitives import grid_triangles
from decrun.runner.plots.common import before_after
from decrun.runner.plots.parametrization import checker_square_size

from meshes_for_tests import icosphere


def test_before_after_panels_share_one_box_so_a_shrunk_result_looks_shrunk():
    V, F = icosphere(2)
    fig = before_after(V, 0.1 * V, F)  # the result collapsed to a tenth
    a, b = fig.axes[:2]
    for get in ("get_xlim", "get_ylim", "get_zlim"):
        assert getattr(a, get)() == pytest.approx(getattr(b, get)())
    assert a.get_xlim() == pytest.approx((-1, 1), abs=0.05)  # the box of the larger mesh
    separate = before_after(V, 0.1 * V, F, share_axes=False)
    assert separate.axes[1].get_xlim() == pytest.approx((-0.1, 0.1), abs=0.01)


def test_checker_squares_follow_the_median_scale_of_the_map():
    V, F = grid_triangles(60, 60)  # the unit square, planar, fine enough for 10 squares
    uv = np.asarray(V, dtype=np.float64)  # the identity map: isometric, scale 1 everywhere
    assert checker_square_size(uv, uv, F, squares=10) == pytest.approx(0.1, rel=1e-12)
    # a map that shrinks everything 100-fold gets squares 100 times smaller: still 10 per side
    assert checker_square_size(uv, 0.01 * uv, F, squares=10) == pytest.approx(0.001, rel=1e-12)
    # the median decides: shrinking a quarter of the triangles 100-fold leaves it at 0.1
    shrunk = uv.copy()
    corner = (uv[:, 0] < 0.45) & (uv[:, 1] < 0.45)
    shrunk[corner] *= 0.01
    assert checker_square_size(uv, shrunk, F, squares=10) == pytest.approx(0.1, rel=1e-12)
    # a coarse mesh (12 × 12 vertices, median edge 1/11): squares of 4 median edge lengths
    V, F = grid_triangles(11, 11)
    coarse = np.asarray(V, dtype=np.float64)
    assert checker_square_size(coarse, coarse, F, squares=10) == pytest.approx(4 / 11, rel=1e-9)


def test_a_flat_mesh_with_3d_vertices_is_drawn_from_above_and_a_curved_one_in_3d():
    """mesh=grid has z = 0 vertices: its fields (the Halfar error map) are maps, drawn in 2-D."""
    from decrun.runner.plots.common import surface_figure

    V, F = grid_triangles(6, 5)
    flat = np.column_stack([V[:, :2], np.full(len(V), 2.0)])
    curved = np.column_stack([V[:, :2], V[:, 0] ** 2])
    values = V[:, 0] - V[:, 1]
    assert surface_figure(flat, F, values).axes[0].name == "rectilinear"
    assert surface_figure(curved, F, values).axes[0].name == "3d"


def test_field_arrows_are_as_long_as_their_spacing_and_the_legend_names_every_mark():
    """Arrows stand for √(A/N) of the visible area each (0.8 of it; at least 0.9 edge lengths,
    the old length): on a fine mesh they grow with the spacing, on a coarse one they stay.
    The figure's legend names every kind of mark it drew: arrows, singularities, sources,
    sinks, vortices, stroke faces."""
    from decrun.core.complex import SimplicialComplex
    from decrun.runner.plots.fields import arrow_length, field_figure

    assert arrow_length(0.01, 1.0, 100) == pytest.approx(0.08)  # fine: the spacing 0.1 decides
    assert arrow_length(0.2, 1.0, 100) == pytest.approx(0.18)  # coarse: the edge length decides
    assert arrow_length(0.2, 0.0, 0) == pytest.approx(0.18)
    K = SimplicialComplex(*icosphere(2))
    faces = K.simplices(2)
    centre = K.vertices[faces].mean(axis=1)
    vectors = np.cross([0.0, 0.0, 1.0], centre)  # rotation about z: index +1 at both poles
    vertex_index = np.zeros(K.num_simplices(0))
    face_index = np.zeros(len(faces))
    face_index[[np.argmax(centre[:, 2]), np.argmin(centre[:, 2])]] = 1
    fig = field_figure(K, vectors, vertex_index, face_index, stroke_faces=[0, 1], source_vertices=[0, 5],
                       source_divergences=[1.0, -1.0], vortex_faces=[7])
    (legend,) = fig.legends
    labels = [text.get_text() for text in legend.get_texts()]
    for word in ("direction of u", "singularity of index +1", "source", "sink", "vortex", "stroke faces"):
        assert any(word in label for label in labels), (word, labels)
    assert not any("−1" in label for label in labels)  # no index −1 drawn: not in the legend


def test_the_snapshot_colour_scale_is_set_inside_and_the_figure_says_what_lies_beyond():
    """A ±30 odd-even pattern on the border (an outflow's) no longer sets the colours of a
    field of size 1 inside; the note names the rule and the values beyond (where, how many),
    and the colour bar gets end arrows."""
    from decrun.core.complex import SimplicialComplex
    from decrun.runner.plots.snapshots import colour_scale, snapshot_grid

    V, F = grid_triangles(10)
    K = SimplicialComplex(V, F)
    border = K.border_vertices()
    w = np.sin(np.pi * V[:, 0]) * np.sin(np.pi * V[:, 1]) + 0.01  # ≤ 1.01 inside
    w[border] = 30.0 * (-1.0) ** np.arange(border.sum())
    frames = np.stack([w, 0.5 * w])
    _, lo, hi, extend, note = colour_scale(K, frames, "vorticity")
    inside = np.abs(frames[:, ~border])
    assert lo == -hi and hi == pytest.approx(np.percentile(inside, 95)) and hi < 1.02
    share = (np.abs(frames) > hi).mean()
    assert extend == "both"
    assert f"±{hi:.3g} = the 95th percentile of |vorticity| at the interior vertices" in note
    assert f"{share:.1%} of the values lie beyond (up to 30 at the border)" in note
    fig = snapshot_grid(K, {"vorticity": frames, "time": np.array([0.0, 1.0])}, count=2)
    assert fig.get_supxlabel() == note and fig.axes[-1].get_label() == "<colorbar>"
    sphere = SimplicialComplex(*icosphere(1))
    *_, closed = colour_scale(sphere, np.ones((1, sphere.num_simplices(0))), "w")
    assert "at all vertices" in closed and "no value lies beyond" in closed


def test_a_sphere_with_a_hole_is_seen_from_its_hole_and_a_cap_from_its_convex_side():
    """Fig. 5.8's checkerboard looked along the mean normal of a sphere with a small hole,
    which points away from the hole; a nearly closed surface is now seen from its border,
    an open cap still along its mean normal (from outside)."""
    from decrun.core.complex import SimplicialComplex
    from decrun.runner.plots.parametrization import view_direction

    V, F = icosphere(3)
    centre = V[F].mean(axis=1)
    for keep, expected in ((centre[:, 0] < 0.9, [1.0, 0.0, 0.0]), (centre[:, 0] > 0.3, [1.0, 0.0, 0.0]),
                           (centre[:, 1] > -0.85, [0.0, -1.0, 0.0])):
        faces = F[keep]
        used = np.unique(faces)
        K = SimplicialComplex(V[used], np.searchsorted(used, faces), orient="fix")
        towards = view_direction(K.vertices, K.oriented_simplices(), K.border_vertices())
        assert towards @ np.asarray(expected) > 0.99, (expected, towards)


def test_sub_pixel_uv_triangles_are_drawn_in_their_own_colour_not_grey_edges():
    """A layout whose centre is squeezed (a free border's far side of a sphere): the edges of
    triangles below 10 pixels take their face colour (the centre showed flat grey), the
    others keep thin grey edges."""
    from decrun.core.complex import SimplicialComplex
    from decrun.runner.plots.parametrization import edge_widths, uv_layout

    V, F = grid_triangles(20)
    uv = V[:, :2] - 0.5
    radius = np.linalg.norm(uv, axis=1, keepdims=True)
    uv = uv * radius**3 * 8  # triangles near the centre shrink by orders of magnitude
    widths = edge_widths(uv, F, 440.0)
    p = uv[F]
    a, b = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    size = np.sqrt(np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])) * 440.0 / np.ptp(uv, axis=0).max()
    assert np.all(widths[size >= 10] == 0.15) and np.all(widths[size < 10] == 0) and 0 < (widths == 0).sum() < len(F)
    K = SimplicialComplex(V, F)
    fig = uv_layout(K, uv, F, np.linspace(0, 5, len(F)), np.zeros(len(F), bool))
    surface = fig.axes[0].collections[0]
    small = widths == 0
    np.testing.assert_allclose(surface.get_edgecolors()[small], surface.get_facecolors()[small])
    assert np.allclose(surface.get_edgecolors()[~small][:, :3], 0.35)


def test_the_roughness_floor_is_the_smallest_nonzero_eigenvalue_and_the_series_draws_it():
    """R ≥ λ1: on the unit sphere λ1 ≈ 2 (x, y, z: l = 1), so a smoothed sphere's roughness
    ratio levels off above λ1/R0, never at 0; the series figure draws and names the bound."""
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC
    from decrun.methods.mean_curvature_flow import smallest_positive_eigenvalue
    from decrun.runner.plots.common import plot_series

    for subdiv, tolerance in ((1, 0.2), (3, 0.01)):  # dense and ARPACK paths
        dec = DEC(SimplicialComplex(*icosphere(subdiv)))
        S, M = dec.laplacian_symmetric(0), dec.star(0)
        floor = smallest_positive_eigenvalue(S, M)
        assert floor == pytest.approx(2.0, rel=tolerance)
        x = dec.K.vertices - np.asarray(M @ dec.K.vertices).sum(axis=0) / M.sum()  # M-orthogonal to constants
        assert np.einsum("ij,ij->", x, S @ x) / np.einsum("ij,ij->", x, M @ x) >= floor * (1 - 1e-9)
    fig = plot_series({"roughness": np.array([4.0, 3.0, 2.2])}, floors={"roughness": (0.5, "bound")})
    (legend,) = fig.legends
    assert [t.get_text() for t in legend.get_texts()] == ["roughness / initial", "bound = 0.5"]
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)  # the legend lies under the axes: it hides no part of a curve
    assert legend.get_window_extent(renderer).y1 <= fig.axes[0].get_window_extent(renderer).y0
    assert [line.get_ydata()[0] for line in fig.axes[0].lines][1] == 0.5


def _light_fraction_of_a_fine_grid(n: int = 120) -> float:
    """plot_surface of a fine n × n grid in viridis (whose colours all have a dark channel),
    drawn as the snapshots draw it (no edge lines): the fraction of pixels inside the square
    that are light — seams between the triangles where the white background shows through."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from decrun.runner.plots.common import plot_surface

    vertices, faces = grid_triangles(n)
    figure = Figure(figsize=(4, 4), dpi=100)
    canvas = FigureCanvasAgg(figure)
    ax = figure.add_axes((0, 0, 1, 1))
    plot_surface(ax, vertices, faces, np.sin(3 * vertices[:, 0]) * np.cos(2 * vertices[:, 1]), linewidth=0.0)
    canvas.draw()
    image = np.asarray(canvas.buffer_rgba())[..., :3].astype(int)
    inside = image[20:-20, 20:-20]
    return float((inside.min(axis=2) > 150).mean())


def test_a_fine_grid_is_drawn_without_a_moire_of_light_seams():
    """Issue 48: the gallery's Gray–Scott square was covered by light lines (anti-aliasing seams
    between triangles drawn without edge lines). Measured: no light pixel (before: 1.9 % of them)."""
    assert _light_fraction_of_a_fine_grid() < 0.001


def test_edge_lines_are_drawn_on_small_meshes_only():
    from decrun.runner.plots.common import EDGE_LINES_MAX_FACES, _edges

    assert _edges(100, None, 0.1, "0.35") == ("0.35", 0.1)
    assert _edges(EDGE_LINES_MAX_FACES + 1, None, 0.1, "0.35")[0] == "face"  # a fine mesh: no grey web
    assert _edges(EDGE_LINES_MAX_FACES + 1, "black", 0.1, "0.35") == ("black", 0.1)  # asked for: drawn
