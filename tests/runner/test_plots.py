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
