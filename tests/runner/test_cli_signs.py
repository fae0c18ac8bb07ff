"""Negative and sign checks through the real ``decrun`` command (the second, independent home
of what tests/methods and tests/apps check on the functions): an overlapping parametrization
of a mesh file is reported as no embedding, and a reversed source reverses the designed flow
stored in result.h5."""

from __future__ import annotations

import json

import h5py
import numpy as np
import pytest

from decrun.core.complex import SimplicialComplex
from decrun.runner.results import read_mesh, read_result

from meshes_for_tests import flux_through_circle, spiral_strip


def write_obj(path, vertices, faces):
    with open(path, "w") as handle:
        handle.writelines(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in vertices)
        handle.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in faces)


def run_dirs(tmp_path):
    return sorted((tmp_path / "outputs" / "runs").iterdir())


@pytest.mark.parametrize("turns, overlapping", [(1.5, True), (0.75, False)])
def test_overlapping_parametrization_of_a_mesh_file_is_no_embedding(tmp_path, decrun_cli, turns, overlapping):
    """A helical ramp (1.5 turns, no interior vertex: intrinsically flat) laid out by the free
    border is its flat strip, which overlaps itself: no flip, no degenerate triangle, border
    turning once — only the border crossing itself says it is no embedding. 0.75 turns embed."""
    write_obj(tmp_path / "strip.obj", *spiral_strip(turns=turns, rise=0.03))
    proc = decrun_cli("app=parametrization", "mesh=file", "mesh.path=strip.obj", "app.border=free")
    assert proc.returncode == 0, proc.stderr
    metrics = json.loads((run_dirs(tmp_path)[0] / "metrics.json").read_text())
    assert metrics["flipped_triangles"] == 0 and metrics["degenerate_triangles"] == 0
    assert metrics["border_winding_ok"] is True
    assert metrics["angle_distortion_max_deg"] < 1e-6  # the layout is isometric
    assert (metrics["border_self_intersections"] > 0) is overlapping
    assert metrics["is_embedding"] is (not overlapping)


def test_a_reversed_source_reverses_the_flow_in_result_h5(tmp_path, decrun_cli):
    """decrun app=vector_field with a source, then a sink, at the centre of the unit square
    (boundary=none): the Whitney flux of the stored 1-form through circles around it is
    q (1 − πr²) — positive out of the source, the exact negative for the sink."""
    common = ["app=vector_field", "mesh=planar", "mesh.holes=[]", "mesh.max_area=0.002", "boundary=none"]
    radii = np.array([0.15, 0.3])
    flux = {}
    for q in (1.0, -1.0):
        proc = decrun_cli(*common, f"app.sources=[{{point:[0.5,0.5],divergence:{q}}}]")
        assert proc.returncode == 0, proc.stderr
        run = run_dirs(tmp_path)[-1]
        vertices, faces = read_mesh(run / "result.h5")
        K = SimplicialComplex(vertices, faces)
        with h5py.File(run / "result.h5", "r") as f:  # the 1-form is stored with its edge list
            np.testing.assert_array_equal(f["mesh"]["edges"][()], K.simplices(1))
        omega = np.asarray(read_result(run / "result.h5").fields["omega"], dtype=np.float64)
        flux[q] = np.array([flux_through_circle(K, omega, [0.5, 0.5], r) for r in radii])
    np.testing.assert_allclose(flux[1.0], 1 - np.pi * radii**2, atol=0.05)
    np.testing.assert_allclose(flux[-1.0], -flux[1.0], rtol=1e-9)
