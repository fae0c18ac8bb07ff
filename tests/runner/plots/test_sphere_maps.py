"""Longitude–latitude maps of fields on the sphere (issue 49, item 5): the resampling is exact for
affine fields and second order for smooth ones, the maps put TC2's extremes where the formula
does, a model's ``plots:`` entries become map and error-map files through the real command, and
every bad option is one line naming ``app.plots.<name>.<key>`` whose fix runs."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

import numpy as np
import pytest

from decrun.errors import DecrunError
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import prepare, run_experiment
from decrun.runner.plots.lonlat import SphereInterpolator, directions, lonlat_grid, on_triangles, regrid
from decrun.runner.plots.sphere import contour_levels, error_map, mapped, sphere_map

from cli_processes import decrun
from meshes_for_tests import complex_of, icosphere

ROOT = Path(__file__).resolve().parents[3]


def sphere_maps_script():
    """scripts/sphere_maps.py: the test cases' formulas (TC2, TC5, Galewsky) and the docs' maps."""
    spec = importlib.util.spec_from_file_location("sphere_maps", ROOT / "scripts" / "sphere_maps.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def random_directions(count: int, seed: int = 0) -> np.ndarray:
    p = np.random.default_rng(seed).normal(size=(count, 3))
    return p / np.linalg.norm(p, axis=1, keepdims=True)


def piercing_points(V: np.ndarray, F: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Independently of the interpolator: for every direction p the point where the ray from the
    centre through p crosses the (flat) triangle it passes through, by testing every triangle."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    normal = np.cross(b - a, c - a)  # its orientation follows the corners' order, as the edge tests do
    t = np.einsum("ij,ij->i", normal, a)[None, :] / (p @ normal.T)  # (q, t) ray parameter of each plane
    x = t[..., None] * p[:, None, :]
    edges = [np.einsum("qtj,tj->qt", x - s[None], np.cross(normal, e - s)) for s, e in ((a, b), (b, c), (c, a))]
    inside = (edges[0] >= -1e-12) & (edges[1] >= -1e-12) & (edges[2] >= -1e-12) & (t > 0)
    assert inside.any(axis=1).all()
    return x[np.arange(len(p)), inside.argmax(axis=1)]


def test_the_interpolant_is_exact_for_constants_and_affine_fields_of_the_piercing_point():
    V, F = icosphere(2)
    p = random_directions(1500)
    interpolator = SphereInterpolator(V, F)
    located = interpolator.locate(p)
    assert (located.triangle >= 0).all()
    np.testing.assert_allclose(interpolator.interpolate(np.full(len(V), 3.5), located), 3.5, rtol=1e-14)
    c = np.array([0.3, -1.2, 0.7])
    exact = 0.25 + piercing_points(V, F, p) @ c
    np.testing.assert_allclose(interpolator.interpolate(0.25 + V @ c, located), exact, rtol=0, atol=1e-13)


def test_values_per_triangle_are_met_at_the_circumcentres_and_constants_are_kept():
    K = complex_of("icosphere", subdiv=2, noise=0.0)
    triangles = K.simplices(2)
    interpolator = on_triangles(K.vertices, triangles)
    values = np.random.default_rng(1).normal(size=len(triangles))
    centres = interpolator.points  # the circumcentres on the sphere, in the triangles' order
    np.testing.assert_allclose(interpolator.interpolate(values, interpolator.locate(centres)), values, atol=1e-12)
    grid = regrid(K.vertices, triangles, np.full(len(triangles), -2.0), *lonlat_grid(resolution=5.0))
    np.testing.assert_allclose(grid, -2.0, rtol=1e-14)


@pytest.mark.parametrize("on", ["vertices", "triangles"])
def test_a_degree_two_harmonic_is_resampled_at_second_order(on):
    """f = xy (l = 2) at the vertices (or at the circumcentres, per triangle) of icospheres 3, 4,
    5, against f at the grid points: the max error falls by 4 per refinement (h halves)."""
    longitudes, latitudes = lonlat_grid(resolution=2.0)
    exact = np.prod(directions(longitudes, latitudes)[..., :2], axis=-1)
    errors = []
    for subdiv in (3, 4, 5):
        K = complex_of("icosphere", subdiv=subdiv, noise=0.0)
        points = K.vertices if on == "vertices" else sphere_maps_script().circumcentres(K)
        points = points / np.linalg.norm(points, axis=1, keepdims=True)
        grid = regrid(K.vertices, K.simplices(2), points[:, 0] * points[:, 1], longitudes, latitudes)
        errors.append(np.abs(grid - exact).max())
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert (orders > 1.85).all(), (errors, orders)


@pytest.mark.parametrize("alpha", [0.0, np.pi / 4])
def test_the_map_of_tc2_puts_the_extremes_where_the_formula_does(alpha):
    """TC2's depth is largest on the great circle normal to the flow's axis n = (−sin α, 0, cos α)
    and smallest at ±n: the poles and the equator for α = 0, (180°, 45°N) and (0°, 45°S) for π/4."""
    script = sphere_maps_script()
    K = complex_of("icosphere", subdiv=4, noise=0.0, radius=script.EARTH_RADIUS)
    h = script.tc2_depth(K.vertices, alpha)
    longitudes, latitudes, grid = mapped(K, h, resolution=1.0)
    nodes = directions(longitudes, latitudes)
    axis = np.array([-np.sin(alpha), 0.0, np.cos(alpha)])
    highest = nodes[np.unravel_index(np.nanargmax(grid), grid.shape)]
    lowest = nodes[np.unravel_index(np.nanargmin(grid), grid.shape)]
    assert abs(highest @ axis) < 0.03  # on the great circle, within the mesh's spacing
    assert abs(lowest @ axis) > 0.999  # at ±n
    assert np.nanmax(grid) == pytest.approx(h.max(), rel=1e-3) and np.nanmin(grid) == pytest.approx(h.min(), rel=1e-3)
    fig = sphere_map(K, h, name="h", unit="m", time=5 * 86400.0, title="TC2")
    ax, bar = fig.axes
    assert ax.get_title() == "TC2, day 5" and bar.get_ylabel() == "h (m)"
    assert ax.get_xlim() == (-180.0, 180.0) and ax.get_ylim() == (-90.0, 90.0) and ax.get_aspect() == 1.0
    labels = [t.get_text() for t in ax.get_xticklabels()]
    assert labels[:3] == ["180°", "150°W", "120°W"] and "0°" in labels and labels[-1] == "180°"
    assert [t.get_text() for t in ax.get_yticklabels()] == ["90°S", "60°S", "30°S", "0°", "30°N", "60°N", "90°N"]


def test_levels_windows_and_the_error_map_title():
    assert contour_levels(np.array([-3e-5, 1.2e-4]), True, value_range=(-1e-4, 1e-4), interval=2e-5) == \
        pytest.approx(np.linspace(-1e-4, 1e-4, 11))
    assert contour_levels(np.array([1093.0, 2998.0]), False, interval=500.0) == pytest.approx([1000, 1500, 2000,
                                                                                                  2500, 3000])
    with pytest.raises(ValueError, match="at most 200"):
        contour_levels(np.array([0.0, 1.0]), False, interval=1e-4)
    K = complex_of("icosphere", subdiv=3, noise=0.0)
    fig = sphere_map(K, K.vertices[:, 2], name="z", latitudes=(0, 90), center_longitude=90.0, time=1.0,
                     time_unit="model")
    ax = fig.axes[0]
    assert ax.get_xlim() == (-90.0, 270.0) and ax.get_ylim() == (0.0, 90.0) and ax.get_title() == "z, t = 1"
    assert fig.axes[1].get_xlabel() == "z"  # a wide window: the colour bar lies under the map
    reference = K.vertices[:, 2] + 2.0
    areas = np.full(len(reference), 4 * np.pi / len(reference))
    error = 1e-5 * K.vertices[:, 0]
    fig = error_map(K, reference + error, reference, areas, name="h", reference_name="h_T", unit="m")
    l2 = np.sqrt(areas @ error ** 2 / (areas @ reference ** 2))
    assert f"l2 = {l2:.3g}" in fig.axes[0].get_title() and fig.axes[0].get_title().startswith("h − h_T")
    assert fig.axes[1].get_ylabel() == "h − h_T (10⁻⁵ m)"
    with pytest.raises(ValueError, match="sphere centred at the origin"):
        mapped(complex_of("icosphere", subdiv=2, noise=0.3), K.vertices[:162, 0])  # conf/mesh/icosphere.yaml: noisy


def test_the_docs_maps_are_drawn_from_the_formulas(tmp_path):
    """TC2 at α = π/4, TC5's h + b over the mountain and Galewsky's vorticity on subdiv 4: the
    files are written (the docs' two small), and Galewsky's map shows the jet between 0° and 90°N in its levels."""
    script = sphere_maps_script()
    assert script.main(["--out", str(tmp_path), "--subdiv", "4", "--all"]) == 0
    for name in ("sphere_tc2_alpha45", "sphere_tc5_surface", "sphere_galewsky_vorticity"):
        path = tmp_path / f"{name}.png"
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert name == "sphere_tc2_alpha45" or path.stat().st_size < 150_000  # the docs' two: small
    K = script.sphere(4)
    zeta = script.galewsky_vorticity(script.circumcentres(K))
    assert zeta.max() > 1e-4 > -1e-4 < zeta.min() < 0  # beyond the top level: the bar's end is extended


HEAT = ["app=heat", "mesh.subdiv=3", "app.t_end=0.01", "app.animation=false",
        'app.equations=["dt(u) = k * laplacian(u)", "exact_u = exp(-6*k*t)*x*y", "w = d(d(u))", "grad_u = d(u)"]']


def test_a_model_asks_for_maps_from_yaml_through_the_real_command(tmp_path):
    proc = decrun(*HEAT, "+app.plots.m={map: u, unit: K, time_unit: model, latitudes: [0, 90]}",
                  "+app.plots.e={error_map: u, reference: exact_u, time_unit: model}", "hydra.run.dir=run",
                  cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    for name in ("m", "e"):
        assert (tmp_path / "run" / f"{name}.png").read_bytes()[:4] == b"\x89PNG"


BAD = [  # (the plot, the key refused, a fix that runs or None)
    ("{map: u, latitudes: [90, 0]}", "latitudes", "app.plots.m.latitudes=[0,90]"),
    ("{map: u, levels: [1, 0.5]}", "levels", "app.plots.m.levels=[-1e-4,0,1e-4]"),
    ("{map: u, range: [1, -1]}", "range", "app.plots.m.range=[-1e-4,1e-4]"),
    ("{map: u, range: [-1, 1], interval: 0.3}", "interval", "app.plots.m.interval=0.285714"),
    ("{map: u, interval: -1}", "interval", "app.plots.m.interval=1"),
    ("{map: u, levels: [0, 1], range: [0, 1]}", "range", None),
    ("{map: u, center_longitude: 270}", "center_longitude", "app.plots.m.center_longitude=-90"),
    ("{map: u, resolution: 0}", "resolution", "app.plots.m.resolution=0.5"),
    ("{map: u, time_unit: days}", "time_unit", "app.plots.m.time_unit=model"),
    ("{map: nothing}", "map", "app.plots.m.map=exact_u"),
    ("{map: grad_u, unit: m}", "map", "app.plots.m.map=exact_u"),
    ("{map: u, arrows: u}", "arrows", None),
    ("{map: u, reference: u}", "reference", None),
    ("{error_map: u}", "reference", None),
    ("{error_map: u, reference: w}", "reference", "app.plots.m.reference=exact_u"),
    ("{error_map: u, reference: exact_u, outline: u}", "outline", None),
    ("{color: u, map: u}", None, None),
    ("{color: u, arrows: u, unit: m}", "unit", None),
    ("{map: u, colour: blue}", "colour", None),  # an unknown key of the plot, not of app
]


@pytest.mark.parametrize("plot, key, fix", BAD, ids=[f"{i}_{b[1]}" for i, b in enumerate(BAD)])
def test_each_bad_option_is_one_line_naming_its_key_and_the_fix_runs(plot, key, fix):
    overrides = [*HEAT, f"+app.plots.m={plot}", "figures=false"]
    with pytest.raises(DecrunError) as refused:
        prepare(compose_config(overrides))
    message = str(refused.value)
    assert "\n" not in message and message.startswith(f"app.plots.m.{key}:" if key else "app.plots.m:"), message
    hints = re.findall(r"`([^`]+)`", message)
    if fix is not None:
        assert fix in hints, message
        assert run_experiment(compose_config([*overrides, fix])).result.metrics["status"] == "ok"


def test_a_map_of_a_mesh_off_the_sphere_is_refused_before_any_work_with_a_mesh_that_fits():
    overrides = ["app=heat", "mesh=icosphere", "mesh.subdiv=2", "app.t_end=0.01", "+app.plots.m={map: u}",
                 "figures=false"]
    with pytest.raises(DecrunError, match=r"^app.plots.m.map: a longitude–latitude map needs a mesh on a sphere "
                                          r"centred at the origin, but its vertices' distances.*`mesh=icosphere_clean`"):
        prepare(compose_config(overrides))
    assert run_experiment(compose_config([*overrides, "mesh=icosphere_clean"])).result.metrics["status"] == "ok"


def test_integrated_forms_are_mapped_as_their_densities():
    """A dual 2-form U = ⋆0 u is shown as ⋆0⁻¹ U = u; a top form as ⋆2 ω, per triangle."""
    from decrun.apps.model_plots import pointwise
    from decrun.core.dec import DEC
    from decrun.methods.model.kinds import dual, primal

    K = complex_of("icosphere", subdiv=2, noise=0.0)
    dec = DEC(K)
    u = K.vertices[:, 0] * K.vertices[:, 1]
    np.testing.assert_allclose(pointwise(dec, dual(2), dec.star(0) @ u), u, rtol=1e-13, atol=1e-15)
    density = np.random.default_rng(2).normal(size=K.num_simplices(2))
    np.testing.assert_allclose(pointwise(dec, primal(2), density * dec.primal_volumes(2)), density, rtol=1e-12)
    np.testing.assert_array_equal(pointwise(dec, primal(0), u), u)
