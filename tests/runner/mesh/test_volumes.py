"""Tetrahedral meshes end to end: the volume sources (box, tetrahedralize, TetGen/meshio files)
through the apps, checked against Betti numbers and analytic spectra."""

from __future__ import annotations

import json

import meshio
import numpy as np
import pytest

from decrun.core.primitives import kuhn_cube
from decrun.errors import ConfigError, DegenerateSimplexError
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import run_experiment

from meshes_for_tests import kuhn_cells

TUNNEL = "mesh.tunnels=[[0.4,0.4,-1,0.6,0.6,2]]"
CAVITY = "mesh.cavities=[[0.4,0.4,0.4,0.6,0.6,0.6]]"


def run(*overrides):
    done = run_experiment(compose_config(list(overrides)))
    return done.result.metrics, done.mesh


def test_spectrum_of_the_default_box_through_the_cli(decrun_cli, tmp_path):
    done = decrun_cli("app=spectrum", "mesh=box", "figures=false")
    assert done.returncode == 0, done.stderr
    metrics = json.loads(next(tmp_path.glob("outputs/runs/*/metrics.json")).read_text())
    assert metrics["analytic_domain"] == "box(1, 1, 1)"
    assert metrics["eigenvalue_relative_error_max"] < 0.1 and metrics["kernel_dimension_matches_betti"]


@pytest.mark.parametrize("degree, holes, betti", [(1, [TUNNEL], 1), (2, [CAVITY], 1), (1, [CAVITY], 0),
                                                   (2, [TUNNEL], 0)])
def test_hodge_on_box_with_tunnel_or_cavity(degree, holes, betti):
    metrics, mesh = run("app=hodge", "mesh=box", "mesh.cells=5", *holes, "operator=whitney", "app.input=random",
                        f"app.degree={degree}", "figures=false")
    assert mesh.simplices.shape[1] == 4
    assert metrics[f"betti_{degree}"] == betti == metrics["harmonic_dimension"]
    assert metrics["orthogonality_max"] < 1e-10
    if betti:
        assert metrics["harmonic_curl_relative"] < 1e-8
    else:  # no harmonic part: its relative metrics would be ratios of round-off, so they are absent
        assert metrics["energy_fraction_harmonic"] <= 1e-16 and "harmonic_curl_relative" not in metrics


def test_tetrahedralized_solid_torus_has_one_harmonic_one_form():
    metrics, mesh = run("app=hodge", "mesh=tetrahedralize", "mesh.surface=torus",
                        "mesh.surface_options={major_segments:16,minor_segments:8}", "operator=whitney",
                        "app.input=random")
    assert mesh.meta["tetrahedralize"]["input_triangles"] == 256
    assert metrics["betti_1"] == 1 == metrics["harmonic_dimension"] and metrics["orthogonality_max"] < 1e-10


def test_tetrahedralized_ball_converges_to_the_neumann_spectrum():
    errors = []
    for volume in (0.01, 0.002):
        metrics, _ = run("app=spectrum", "mesh=tetrahedralize", "mesh.keep_surface=true",
                         "mesh.surface_options={subdiv:2}", f"mesh.max_volume={volume}", "app.count=9")
        assert metrics["analytic_domain"] == "ball(1)"
        errors.append(metrics["eigenvalue_relative_error_max"])
    assert errors[1] < 0.6 * errors[0] and errors[1] < 0.08, errors


def test_tetgen_node_ele_files_read_like_the_other_volume_formats(tmp_path):
    V, T = kuhn_cube(3)
    meshio.write(str(tmp_path / "cube.node"), meshio.Mesh(V, [("tetra", T)]), file_format="tetgen")
    for name in ("cube.node", "cube.ele"):
        metrics, mesh = run("mesh=file", f"mesh.path={tmp_path / name}", "app=spectrum", "figures=false")
        assert mesh.meta["file_format"] == "meshio-" + name.split(".")[1]
        np.testing.assert_array_equal(np.sort(np.sort(mesh.simplices, axis=1), axis=0),
                                      np.sort(np.sort(T, axis=1), axis=0))
        assert metrics["analytic_domain"] == "box(1, 1, 1)"


def test_zero_volume_tetrahedron_is_named_without_the_surface_repair_hint(tmp_path, decrun_cli):
    V, T = kuhn_cube(3)
    T[7] = [0, 1, 2, 3]  # vertices 0, 1, 2 lie on one line
    path = tmp_path / "flat.vtu"
    meshio.write(str(path), meshio.Mesh(V, [("tetra", T)]))
    with pytest.raises(DegenerateSimplexError, match="tetrahedron 7 has zero volume") as info:
        run("mesh=file", f"mesh.path={path}", "app=spectrum")
    assert "mesh.repair" not in str(info.value)
    done = decrun_cli("mesh=file", f"mesh.path={path}", "app=spectrum")
    assert done.returncode != 0 and "tetrahedron 7 has zero volume" in done.stderr
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize("override, message", [
    ("mesh.tunnels=[[0.4,0.4,0.2,0.6,0.6,0.8]]", "must run through the box"),
    ("mesh.cavities=[[0.0,0.1,0.1,0.3,0.3,0.3]]", "must lie inside the box"),
    ("mesh.surface=nowhere", "neither a file nor a sample"),
])
def test_volume_source_options_are_checked_before_any_work(override, message):
    source = "mesh=tetrahedralize" if "surface" in override else "mesh=box"
    with pytest.raises(ConfigError, match=message):
        run(source, override, "app=spectrum")


def test_a_hole_that_removes_no_cell_is_an_error():
    with pytest.raises(ConfigError, match=r"mesh.cavities\[0\]: .* contains no cell centre"):
        run("mesh=box", "mesh.cells=5", "mesh.cavities=[[0.1,0.1,0.1,0.3,0.3,0.3]]", "app=spectrum")


def _two_cavities_meeting_along_an_edge(n):
    """kuhn_cube(n) without two cells that share only an edge: b2 = 2 (two regions inside),
    though the inner border is one connected, pinched surface."""
    return kuhn_cells(n, removed={(n // 2 - 1, n // 2 - 1, n // 2), (n // 2, n // 2, n // 2)})


def test_hodge_on_a_file_whose_cavities_meet_along_an_edge(tmp_path, decrun_cli):
    """The harmonic 2-forms of a solid with two cavities meeting along an edge: dimension 2 =
    Betti_2 (the border-surface count said 1, and Betti_1 = -1). On a mesh too large for the
    rank computation the run still succeeds: betti_2 is absent and the log says why."""
    small = tmp_path / "pinched.vtu"
    V, T = _two_cavities_meeting_along_an_edge(4)
    meshio.write(str(small), meshio.Mesh(V, [("tetra", T)]))
    done = decrun_cli("mesh=file", f"mesh.path={small}", "app=hodge", "app.degree=2", "figures=false",
                      f"hydra.run.dir={tmp_path / 'small'}")
    assert done.returncode == 0, done.stderr
    metrics = json.loads((tmp_path / "small" / "metrics.json").read_text())
    assert metrics["betti_2"] == 2 and metrics["harmonic_dimension"] == 2
    assert metrics["harmonic_dimension_matches_betti"] is True

    large = tmp_path / "pinched_large.vtu"
    V, T = _two_cavities_meeting_along_an_edge(9)  # 4362 tetrahedra: above the rank limit
    meshio.write(str(large), meshio.Mesh(V, [("tetra", T)]))
    done = decrun_cli("mesh=file", f"mesh.path={large}", "app=hodge", "app.degree=2", "figures=false",
                      f"hydra.run.dir={tmp_path / 'large'}")
    assert done.returncode == 0, done.stderr
    metrics = json.loads((tmp_path / "large" / "metrics.json").read_text())
    assert metrics["harmonic_dimension"] == 2
    assert "betti_2" not in metrics and "harmonic_dimension_matches_betti" not in metrics
    assert "betti_2 not computed" in done.stderr and "border surface is pinched" in done.stderr


def _backquoted(message: str) -> str:
    import re

    return re.search(r"`([^`]+)`", message).group(1)


def test_a_max_volume_making_billions_of_tetrahedra_is_refused_before_tetgen(decrun_cli, monkeypatch):
    """volume / max_volume bounds the count from below: 1e-12 in the unit ball is ~7e12
    tetrahedra, refused with a max_volume that fits before TetGen allocates anything."""
    import tetgen

    def not_started(*args, **kwargs):
        raise AssertionError("TetGen started")

    monkeypatch.setattr(tetgen, "TetGen", not_started)
    with pytest.raises(ConfigError) as info:
        run("mesh=tetrahedralize", "mesh.max_volume=1e-12", "app=spectrum")
    message = str(info.value)
    assert message.startswith("mesh.max_volume=1e-12: the surface encloses a volume of 4.15")
    assert "about 7.5e+12 tetrahedra" in message and "more than mesh.max_tetrahedra=4000000" in message
    assert _backquoted(message) == "mesh.max_volume=3.2e-06"
    monkeypatch.undo()
    # the same refusal under a smaller limit, through the command line; its override runs
    done = decrun_cli("mesh=tetrahedralize", "mesh.max_volume=1e-9", "mesh.max_tetrahedra=20000", "app=spectrum",
                      "figures=false", "hydra.run.dir=refused")
    assert done.returncode == 1 and "Traceback" not in done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert line.startswith("error: mesh.max_volume=1e-09:") and "or raise mesh.max_tetrahedra" in line
    metrics, mesh = run("mesh=tetrahedralize", _backquoted(line), "mesh.max_tetrahedra=20000", "app=spectrum",
                        "app.count=3", "figures=false")
    assert metrics["status"] == "ok" and 5_000 < len(mesh.simplices) <= 20_000


def test_more_tetrahedra_than_estimated_is_refused_naming_the_limit_that_accepts_them():
    """On a coarse ball TetGen makes 2.9 × volume / max_volume (the estimate says 1.8, and
    the surface's triangles, not max_volume, set the size): the count after TetGen is
    checked too, and the limit it names accepts the mesh."""
    with pytest.raises(ConfigError, match="mesh.max_volume=0.004153: TetGen made 2.[0-9]+e\\+03 tetrahedra, more than "
                                          "mesh.max_tetrahedra=2000") as info:
        run("mesh=tetrahedralize", "mesh.max_volume=0.004153", "mesh.max_tetrahedra=2000", "app=spectrum")
    fix = _backquoted(str(info.value))
    metrics, mesh = run("mesh=tetrahedralize", "mesh.max_volume=0.004153", fix, "app=spectrum", "app.count=3",
                        "figures=false")
    assert metrics["status"] == "ok" and fix == f"mesh.max_tetrahedra={len(mesh.simplices)}"
