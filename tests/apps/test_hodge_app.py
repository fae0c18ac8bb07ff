"""Hodge decomposition app (§6.3.4–6.3.6): analytic fields with known parts, the flat torus,
dim ker Δ1 = Betti_1, and the result.h5 input."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from decrun.apps import hodge as app
from decrun.apps.base import FieldOnEdges, Result
from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.forms import sample_density, sample_vector_field
from decrun.core.hodge import harmonic_basis, hodge_decomposition
from decrun.core.stars import HodgeStar
from decrun.errors import ConfigError
from decrun.runner.results import write_result

from meshes_for_tests import complex_of, kuhn_cube, mesh


@pytest.fixture(scope="module")
def sphere():
    return complex_of(source="icosphere", subdiv=3)


def fractions(dec, omega):
    parts = hodge_decomposition(dec, omega)
    total = dec.inner(1, omega, omega)
    return {name: dec.inner(1, getattr(parts, name), getattr(parts, name)) / total
            for name in ("exact", "coexact", "harmonic")}


def test_gradient_on_sphere_is_exact_only(sphere):
    """The constant vector a is the gradient of a·x; sampled along edges it is exactly d0(a·x)."""
    dec = DEC(sphere)
    f = fractions(dec, sample_vector_field(sphere, np.array([0.3, -0.5, 1.0])))
    assert f["exact"] == pytest.approx(1.0, abs=1e-12)
    assert f["coexact"] < 1e-20 and f["harmonic"] < 1e-20


def test_rotated_gradient_on_sphere_is_coexact(sphere):
    """⋆ of an exact form is coexact: exactly for the discrete δ2 β, up to sampling error for
    the smooth rotated gradient n × ∇z = (x/|x|) × e_z."""
    dec = DEC(sphere)
    beta = sample_density(sphere, lambda x: x[:, 2] + x[:, 0] ** 2)
    f = fractions(dec, dec.codifferential(2) @ beta)
    assert f["coexact"] == pytest.approx(1.0, abs=1e-12) and f["exact"] < 1e-20 and f["harmonic"] < 1e-20
    smooth = fractions(dec, sample_vector_field(sphere, app.analytic_field("rotated_gradient", [0, 0, 1])))
    assert smooth["coexact"] > 0.999 and smooth["exact"] < 1e-3 and smooth["harmonic"] < 1e-12


@dataclass
class FlatTorusStar(HodgeStar):
    """Hodge stars of the flat torus R²/(N a, M b) triangulated by the equilateral lattice
    (a = (1, 0), b = (½, √3/2)): every triangle is equilateral with side 1, so ⋆0 = √3/2
    (hexagonal Voronoi cell), ⋆1 = 1/√3 (dual edge 1/√3 over edge 1), ⋆2 = 4/√3. The
    complex's vertex positions (a torus in R³) only serve the combinatorics. A star variant
    passed to DEC as an object, through the same seam as the built-in ones."""

    name = "flat_torus"
    STARS = {0: np.sqrt(3) / 2, 1: 1 / np.sqrt(3), 2: 4 / np.sqrt(3)}

    def diagonal(self, dec, k):
        return np.full(dec.K.num_simplices(k), self.STARS[k])


def flat_torus(N: int = 12, M: int = 10):
    i, j = np.meshgrid(np.arange(N), np.arange(M), indexing="ij")
    index = lambda a, b: (a % N) * M + (b % M)  # noqa: E731
    tri = np.concatenate([
        np.stack([index(i, j), index(i + 1, j), index(i, j + 1)], -1).reshape(-1, 3),
        np.stack([index(i + 1, j), index(i + 1, j + 1), index(i, j + 1)], -1).reshape(-1, 3),
    ])
    u, v = 2 * np.pi * i.ravel() / N, 2 * np.pi * j.ravel() / M
    xyz = np.stack([(2 + np.cos(v)) * np.cos(u), (2 + np.cos(v)) * np.sin(u), np.sin(v)], 1)
    K = SimplicialComplex(xyz, tri, orient="fix")
    lattice = np.stack([i.ravel(), j.ravel()], 1)
    return K, lattice, (N, M)


def test_constant_field_on_flat_torus_is_harmonic():
    K, lattice, (N, M) = flat_torus()
    dec = DEC(K, star=FlatTorusStar())
    edges = K.simplices(1)
    step = lattice[edges[:, 1]] - lattice[edges[:, 0]]
    step = (step + [N // 2, M // 2]) % [N, M] - [N // 2, M // 2]  # the short way around
    a, b = np.array([1.0, 0.0]), np.array([0.5, np.sqrt(3) / 2])
    vectors = step[:, :1] * a + step[:, 1:] * b
    for X in (np.array([1.0, 0.0]), np.array([0.3, -0.8])):
        omega = vectors @ X
        parts = hodge_decomposition(dec, omega)
        scale = np.abs(omega).max()
        assert np.abs(parts.exact).max() < 1e-10 * scale
        assert np.abs(parts.coexact).max() < 1e-10 * scale
        assert np.allclose(parts.harmonic, omega, atol=1e-10 * scale)
    assert harmonic_basis(dec).shape[1] == 2 == K.betti_numbers()[1]


@pytest.mark.parametrize(
    "options, betti",
    [
        (dict(source="icosphere", subdiv=2), 0),
        (dict(source="torus", major_segments=24, minor_segments=12, noise=0.05), 2),
        (dict(source="planar", max_area=0.004, noise=0.05,
              holes=[[[0.2, 0.2], [0.4, 0.2], [0.4, 0.4], [0.2, 0.4]], [[0.6, 0.6], [0.8, 0.6], [0.8, 0.8], [0.6, 0.8]]]), 2),
    ],
    ids=["sphere", "torus", "square_two_holes"],
)
def test_app_orthogonality_and_harmonic_dimension(options, betti, run_app):
    K = complex_of(**options)
    result, _ = run_app(app.Hodge(input="random", seed=1), K)
    m = result.metrics
    assert m["orthogonality_max"] < 1e-10
    assert m["harmonic_dimension"] == m["betti_1"] == betti and m["harmonic_dimension_matches_betti"]
    if betti:
        assert m["harmonic_curl_relative"] < 1e-8 and m["harmonic_codifferential_relative"] < 1e-8
    else:  # γ is round-off: its ratios would be ratios of round-off, so they are absent
        assert "harmonic_curl_relative" not in m and "harmonic_codifferential_relative" not in m
    assert sum(m[f"energy_fraction_{p}"] for p in ("exact", "coexact", "harmonic")) == pytest.approx(1.0, abs=1e-9)
    assert (m["energy_fraction_harmonic"] > 1e-6) == (betti > 0)
    assert set(result.figures) == {"hodge_parts"}
    assert result.fields["exact_vectors"].shape == (K.num_simplices(2), 3)


def test_app_reads_a_previous_result(tmp_path, sphere):
    """input=result decomposes the 1-form stored by an earlier run on the same mesh."""
    from decrun.runner.job.context import RunContext

    omega = sample_vector_field(sphere, np.array([0.0, 0.0, 1.0]))
    path = write_result(tmp_path / "result.h5", Result(fields={"omega": FieldOnEdges(omega)}),
                        vertices=sphere.vertices, simplices=sphere.oriented_simplices(), edges=sphere.simplices(1))
    cfg = app.Hodge(input="result", input_path=str(path), harmonic_dimension=False)

    def run(K, cfg):
        return cfg.run(RunContext(cfg, K, DEC(K)))

    result = run(sphere, cfg)
    assert np.array_equal(result.fields["omega"].values, omega)
    assert result.metrics["energy_fraction_exact"] == pytest.approx(1.0, abs=1e-12)
    other = complex_of(source="icosphere", subdiv=2)
    with pytest.raises(ConfigError, match="app.input_field"):
        run(other, cfg)
    with pytest.raises(ConfigError, match="app.input_path"):
        run(sphere, app.Hodge(input="result", input_path=str(tmp_path / "missing.h5")))


def test_app_rejects_flux_boundary_and_bad_config(sphere, run_app):
    with pytest.raises(ConfigError, match="boundary=flux: app=hodge supports boundary=none \\(the Hodge decomposition"):
        run_app(app.Hodge(), sphere, boundary="flux")
    with pytest.raises(ConfigError, match="app.input"):
        app.Hodge(input="file")
    with pytest.raises(ConfigError, match="app.analytic"):
        app.Hodge(analytic="curl")


def _hodge_run(decrun_cli, run, *overrides):
    import json

    proc = decrun_cli("app=hodge", *overrides, f"hydra.run.dir={run}")
    assert proc.returncode == 0, proc.stderr
    return json.loads((run / "metrics.json").read_text())


def test_a_zero_harmonic_part_is_drawn_empty_on_the_shared_scale_and_has_no_ratios(decrun_cli, tmp_path):
    """On the sphere (Betti_1 = 0) the harmonic part is round-off (energy ~1e-30): the ratios
    ‖dγ‖/‖dω‖, ‖δγ‖/‖δω‖ of round-off are absent, and the figure draws that panel without
    arrows on ω's grey scale, shared by all four panels (one colour bar)."""
    from decrun.core.complex import SimplicialComplex
    from decrun.runner.plots.fields import hodge_parts_figure
    from decrun.runner.results import read_result
    from decrun.runner.results.reading import read_mesh

    run = tmp_path / "run"
    m = _hodge_run(decrun_cli, run)
    assert m["betti_1"] == 0 and m["energy_fraction_harmonic"] < 1e-20
    assert "harmonic_curl_relative" not in m and "harmonic_codifferential_relative" not in m
    assert (run / "hodge_parts.png").is_file()
    result = read_result(run / "result.h5")
    K = SimplicialComplex(*read_mesh(run / "result.h5"))
    vectors = {k: v for k, v in result.fields.items() if k.endswith("_vectors")}
    energy = {p: m[f"energy_fraction_{p}"] for p in ("exact", "coexact", "harmonic")}
    fig = hodge_parts_figure(K, vectors, energy)
    panels = fig.axes[:4]
    scale = 2.0 * np.percentile(np.linalg.norm(vectors["omega_vectors"], axis=1), 95)
    assert [ax.field_clim for ax in panels] == [(0.0, pytest.approx(scale))] * 4  # one grey scale
    assert len(fig.axes) == 5  # and one colour bar
    # 3-D quiver: a Line3DCollection of 3 segments per arrow (matplotlib keeps them in _segments3d)
    arrows = [sum(len(getattr(c, "_segments3d", [])) for c in ax.collections) // 3 for ax in panels]
    assert arrows[0] > 100 and arrows[1] > 100 and arrows[2] > 100 and arrows[3] == 0
    assert "zero to round-off" in panels[3].get_title()


def test_a_torus_keeps_its_harmonic_ratios(decrun_cli, tmp_path):
    """Betti_1 = 2: the harmonic part of the mixed field is real (2.9 % of the energy) and its ratios are reported
    at round-off size — with the default operator=whitney, where mixed_area's ⋆1 is 0."""
    m = _hodge_run(decrun_cli, tmp_path / "run", "mesh=torus", "figures=false", "app.analytic=mixed")
    assert m["harmonic_dimension"] == m["betti_1"] == 2
    assert 0.01 < m["energy_fraction_harmonic"] < 0.05
    assert m["harmonic_curl_relative"] < 1e-12 and m["harmonic_codifferential_relative"] < 1e-12


# ---------------------------------------------------------------------------- volumes
def _tunnel(n=5):
    return kuhn_cube(n, keep_cell=lambda c: ~((abs(c[:, 0] - .5) < .2) & (abs(c[:, 1] - .5) < .2)))


def _cavity(n=5):
    return kuhn_cube(n, keep_cell=lambda c: np.abs(c - 0.5).max(axis=1) > 0.15)


@pytest.mark.parametrize("mesh, degree, betti", [(_tunnel, 1, 1), (_cavity, 1, 0), (_tunnel, 2, 0), (_cavity, 2, 1)])
def test_hodge_on_tetrahedra_harmonic_dimension_is_betti(mesh, degree, betti):
    """Tunnel: Betti_1 = 1, cavity: Betti_2 = 1 (Galerkin stars: Kuhn cubes have zero
    circumcentric ⋆1); the three parts are ⋆-orthogonal to round-off and γ is harmonic."""
    from decrun.apps.base import Context

    K = SimplicialComplex(*mesh())
    cfg = app.Hodge(degree=degree, input="random")
    dec = DEC(K, star="whitney")
    cfg.check_dimension(K)
    cfg.check_operators(dec)
    cfg.check(K, dec)
    result = cfg.run(Context(cfg, K, dec))
    m = result.metrics
    assert m[f"betti_{degree}"] == betti == m["harmonic_dimension"] and m["harmonic_dimension_matches_betti"]
    assert m["orthogonality_max"] < 1e-10 and m["reconstruction_error_relative"] < 1e-12
    if betti:
        assert m["harmonic_curl_relative"] < 1e-8 and m["harmonic_codifferential_relative"] < 1e-8
    else:  # γ is round-off: ratios of round-off are absent
        assert "harmonic_curl_relative" not in m and "harmonic_codifferential_relative" not in m
    assert result.fields["omega_vectors"].shape == (K.num_simplices(3), 3)


def test_flux_of_a_constant_field_is_exact_and_whitney_reproduces_it():
    """A constant field a is curl(½ a × x): its flux 2-form is d of a 1-form (exact only), and
    the Whitney 2-form interpolation gives a back in every tetrahedron."""
    from decrun.core.forms import sample_flux, whitney_sharp2

    K = SimplicialComplex(*kuhn_cube(3))
    a = np.array([0.3, -1.0, 0.5])
    omega = sample_flux(K, a)
    np.testing.assert_allclose(whitney_sharp2(K, omega), np.broadcast_to(a, (K.num_simplices(3), 3)), atol=1e-12)
    np.testing.assert_allclose(DEC(K).d(2) @ omega, 0, atol=1e-13)  # div a = 0: closed
    parts = hodge_decomposition(DEC(K, star="whitney"), omega, k=2)
    assert np.linalg.norm(parts.coexact) + np.linalg.norm(parts.harmonic) < 1e-10 * np.linalg.norm(omega)


def test_hodge_degree_two_on_a_surface_is_refused_with_the_fix():
    from decrun.errors import TopologyError

    K = complex_of(source="icosphere", subdiv=1)
    with pytest.raises(TopologyError, match="app.degree=1"):
        app.Hodge(degree=2).check(K, DEC(K))


# ---------------------------------------------------------------------------- the default field
def _on_z_axis_edges(run):
    """Edges of the stored mesh with both ends on the z axis (x = y = 0)."""
    from decrun.runner.results.reading import read_mesh

    vertices, simplices = read_mesh(run / "result.h5")
    K = SimplicialComplex(vertices, simplices)
    on_axis = np.linalg.norm(K.vertices[:, :2], axis=1) < 1e-12
    return int(on_axis[K.simplices(1)].all(axis=1).sum())


@pytest.mark.parametrize("overrides, mixed_fails", [
    (["mesh=cube"], False),
    (["mesh=sample", "mesh.sample=cube"], True),  # pymeshlab's 12-triangle cube: diagonals cross the z axis
    (["mesh=box", "mesh.cells=3"], True),  # edges on the z axis
    (["mesh=box", "mesh.cells=3", "app.degree=2"], False),  # (fluxes sample no point on the axis)
    (["mesh=bunny"], False),
    (["mesh=torus"], False),
    (["mesh=planar"], False),
], ids=lambda o: " ".join(o) if isinstance(o, list) else "")
def test_the_default_field_runs_on_the_users_mesh_with_exact_and_coexact_parts(overrides, mixed_fails, decrun_cli,
                                                                               tmp_path):
    """issue 27.1: `decrun app=hodge` on cubes, a tetrahedral box with edges on the z axis (where
    the old default `mixed`'s toroidal part is infinite), the scanned bunny, a torus and a holed
    planar domain: the default `frame` field has a nonzero exact and a nonzero coexact part, a
    harmonic part exactly where Betti_k > 0, and the decomposition passes Theorem 5's checks."""
    m = _hodge_run(decrun_cli, tmp_path / "run", *overrides, "figures=false")
    assert m["input"] == "frame"
    assert m["energy_fraction_exact"] > 0.01 and m["energy_fraction_coexact"] > 0.01  # degree 2 box: 2.1 % coexact
    assert m["orthogonality_max"] < 1e-10 and m["reconstruction_error_relative"] < 1e-12
    k = m["degree"]
    assert m["harmonic_dimension_matches_betti"] and m["harmonic_dimension"] == m[f"betti_{k}"]
    if m[f"betti_{k}"]:
        assert m["energy_fraction_harmonic"] > 1e-4
        assert m["harmonic_curl_relative"] < 1e-10 and m["harmonic_codifferential_relative"] < 1e-10
    else:
        assert m["energy_fraction_harmonic"] < 1e-20
    if "mesh=box" in overrides:
        assert _on_z_axis_edges(tmp_path / "run") > 0  # the case the issue names
    if mixed_fails:
        proc = decrun_cli("app=hodge", *overrides, "app.analytic=mixed", "figures=false", "hydra.run.dir=old")
        assert proc.returncode != 0 and "the toroidal part is singular on the z axis" in proc.stderr


def _rotation(seed=3):
    q, r = np.linalg.qr(np.random.default_rng(seed).standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def test_the_frame_field_moves_with_the_mesh():
    """Translating and rotating the bunny's vertices leaves the sampled 1-form unchanged: the
    field is built from the vertices' centroid, principal axes and RMS radius only. (The bunny's
    frame is unique: distinct variances, nonzero third moments along e1 and e2.)"""
    bunny = mesh(source="bunny", sample="bunny10k_textured")
    K = SimplicialComplex(bunny.vertices, bunny.simplices, orient="fix")
    c, E, s = app.mesh_frame(K.vertices)
    r = K.vertices - c
    variances = np.sort(np.linalg.eigvalsh(r.T @ r / len(r)))[::-1]
    assert np.all(np.diff(variances) < -1e-3 * variances[0])
    assert np.all(np.abs(((r @ E[:2].T / s) ** 3).mean(axis=0)) > 1e-3)
    np.testing.assert_allclose(E @ E.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(E) == pytest.approx(1.0)
    R, t = _rotation(), np.array([3.0, -7.0, 0.5])
    moved = SimplicialComplex(bunny.vertices @ R.T + t, bunny.simplices, orient="fix")
    cfg = app.Hodge()
    omega = app.input_form(K, cfg)
    np.testing.assert_allclose(app.input_form(moved, cfg), omega, rtol=0, atol=1e-10 * np.abs(omega).max())
    c2, E2, s2 = app.mesh_frame(moved.vertices)
    np.testing.assert_allclose(E2, E @ R.T, atol=1e-10)
    assert s2 == pytest.approx(s) and np.allclose(c2, R @ c + t)


def test_the_frame_field_is_finite_everywhere_and_its_gradient_term_is_exact():
    """No singular point or axis: finite at the centroid, on every coordinate axis and far away.
    The field minus its rotation and bounded parts is d0 of s(u1 + u2²/2) exactly (Gauss
    quadrature of order 3 integrates the linear integrand along each edge exactly)."""
    K = complex_of(source="cube", refine="loop", refine_iterations=2)
    X = app.analytic_field("frame", app.DEFAULT_VECTOR, K.vertices)
    c, E, s = app.mesh_frame(K.vertices)
    probes = np.concatenate([c[None], np.zeros((1, 3)), np.eye(3) * 1e3, [[0, 0, 0.5], [0, 0, -2.0]]])
    assert np.all(np.isfinite(X(probes)))
    u = lambda x: (x - c) @ E.T / s  # noqa: E731
    gradient = lambda x: X(x) - np.cross(E[2], x - c) / s - np.sin(np.pi * u(x)[:, :1]) * E[1]  # noqa: E731
    phi = s * (u(K.vertices)[:, 0] + u(K.vertices)[:, 1] ** 2 / 2)
    np.testing.assert_allclose(sample_vector_field(K, gradient, order=3), DEC(K).d(0) @ phi, atol=1e-13)


def test_frame_refuses_a_vector_it_would_not_use():
    with pytest.raises(ConfigError, match="app.vector=.*`app.analytic=gradient`"):
        app.Hodge(vector=[1.0, 0.0, 0.0])
    assert app.Hodge(analytic="gradient", vector=[1.0, 0.0, 0.0]).vector == [1.0, 0.0, 0.0]
