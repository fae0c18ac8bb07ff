"""The mesh post step ``lloyd`` (decrun/runner/mesh/post.py): Lloyd's iteration towards the spherical
centroidal Voronoi tessellation, the grid TRiSK is run on in MPAS."""

from __future__ import annotations

import numpy as np
import pytest

from decrun.core.sphere_lloyd import lloyd_sphere
from decrun.errors import MeshError
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import prepare


def _mesh(overrides):
    run = prepare(compose_config(["app=shallow_water", "figures=false", "progress=false", *overrides]))
    return run.dec.K


def test_lloyd_moves_the_icosphere_to_a_centroidal_grid_on_the_same_sphere():
    """mesh.lloyd=2000 at subdiv 2: same triangles, every vertex on the sphere of radius a (1e-12), and a fixed
    point of one more Lloyd step (the generators are their cells' projected centroids: moves < 1e-11 a),
    which the plain icosphere is not (its vertices move by > 1e-3 a)."""
    plain = _mesh(["mesh.subdiv=2"])
    smoothed = _mesh(["mesh.subdiv=2", "mesh.lloyd=2000"])
    radius = 6.37122e6
    assert np.array_equal(plain.simplices(2), smoothed.simplices(2))
    assert np.abs(np.linalg.norm(smoothed.vertices, axis=1) / radius - 1).max() < 1e-12
    triangles = smoothed.simplices(2)
    _, again = lloyd_sphere(smoothed.vertices, triangles, 1)
    _, first = lloyd_sphere(plain.vertices, triangles, 1)
    assert again["last_move"] < 1e-11 and first["last_move"] > 1e-3


def test_lloyd_on_a_mesh_that_is_not_a_centred_sphere_is_refused_in_one_line():
    with pytest.raises(MeshError, match="mesh.lloyd: needs a sphere centred at the origin") as refused:
        _mesh(["mesh=torus", "mesh.lloyd=10"])
    assert "use mesh.lloyd=0" in str(refused.value) and "\n" not in str(refused.value)


@pytest.mark.slow
def test_tc2_on_the_lloyd_grid_through_the_cli_gives_the_centroidal_error():
    """TC2 (α = 0, subdiv 4, dt = 1600 s, 5 days) on mesh.lloyd=1000: l2(h) 5.936e-4 (the twin's on the same
    grid; 1.35e-3 on the plain icosphere)."""
    from decrun.runner.job.run import run_experiment

    metrics = run_experiment(compose_config(["+experiment=williamson_tc2", "mesh.subdiv=4", "app.dt=1600",
                                             "mesh.lloyd=1000", "figures=false", "progress=false"])).result.metrics
    assert metrics["stable"] and metrics["l2_h"] == pytest.approx(5.9356e-4, rel=1e-3)
