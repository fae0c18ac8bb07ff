"""The model language's operators, through the language (parse → type → compile → evaluate):
equal to DEC's own to round-off, and the exact identities of the operators the language adds
(∧, ♯, ♭, average, interior, Lie) — mathematics, not shapes.

Measured (these tests hold them): with the averaging 0∧k wedge and Hirani's 1∧1 wedge the
Leibniz rule d(f∧β) = df∧β + f∧dβ holds to round-off for *every* 1-form β, closed or not
(relative error ≤ 1e-14 on planar meshes of 78 … 5005 triangles: no O(h) term), and
d(fg) = df∧g + f∧dg for 0-forms exactly (an identity of the edge average)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.forms import sample_vector_field
from decrun.core.solvers import solver_factory
from decrun.methods.model import FieldSpec, ModelSpec, compile_model
from decrun.methods.model.compiler import Compiler
from decrun.methods.model.kinds import NUMBER, VECTOR, dual, primal
from decrun.methods.model.language import parse_expression
from decrun.methods.model.operators import Discrete
from decrun.runner.job.plugins import option

from meshes_for_tests import jittered_lattice, kuhn_cube, remeshed_torus

#: meshes whose ⋆ are all invertible (no zero ⋆1: no right angle opposite a border edge, no
#: cyclic quad), so that every operator with ⋆⁻¹ is meaningful on them
MESHES = {
    "sphere": lambda: _source("icosphere", subdiv=2, noise=0.0),  # closed, curved
    "torus": lambda: remeshed_torus(0.15),  # closed, Betti_1 = 2
    "lattice": lambda: jittered_lattice(8, 7),  # planar (2-D coordinates), a border, no obtuse angle
}
#: and meshes for the operators without ⋆⁻¹
MORE = {
    "planar": lambda: _source("planar"),  # a square with a square hole (⋆1 = 0 at its corners)
    "grid": lambda: _source("grid", nx=5, ny=5),  # right triangles in 3-D coordinates z = 0
    "tets": lambda: kuhn_cube(2),
}


def _source(name, **options):
    mesh = option("mesh", name, **options).load()
    return mesh.vertices, mesh.simplices


@lru_cache(maxsize=None)
def complex_of(name: str) -> SimplicialComplex:
    return SimplicialComplex(*{**MESHES, **MORE}[name](), orient="fix")


@lru_cache(maxsize=None)
def dec_of(name: str, star: str = "circumcentric") -> DEC:
    return DEC(complex_of(name), star=star)


def env_of(K, values) -> dict:
    zeros = np.zeros(K.num_simplices(0))
    coordinates = [K.vertices[:, i] if i < K.embedding_dim else zeros for i in range(3)]
    return {"x": coordinates[0], "y": coordinates[1], "z": coordinates[2], "pi": np.pi, "t": 0.0, "dt": 0.1,
            "h": K.mean_edge_length, **values}


def evaluate(dec: DEC, text: str, **fields):
    """``text`` compiled by the language on ``dec`` and evaluated; ``fields``: name → (kind, value)."""
    compiler = Compiler(Discrete(dec), {name: kind for name, (kind, _) in fields.items()})
    closure = compiler.compile(parse_expression(text, "test"), "test")
    return closure(env_of(dec.K, {name: value for name, (_, value) in fields.items()}))


def random_form(dec: DEC, kind, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).standard_normal(kind.size(dec.K))


def close(actual, expected, rtol=1e-12):
    """|actual − expected| ≤ rtol · max |expected| (round-off relative to the size of the values)."""
    actual, expected = np.asarray(actual, dtype=np.float64), np.asarray(expected, dtype=np.float64)
    assert actual.shape == expected.shape, (actual.shape, expected.shape)
    scale = max(np.abs(expected).max(initial=0.0), 1e-300)
    error = np.abs(actual - expected).max(initial=0.0) / scale
    assert error <= rtol, f"relative error {error:.3g} > {rtol:g}"


# ------------------------------------------------------------------------------- DEC's operators
CASES = [(mesh, star, k) for mesh in MESHES for star in ("circumcentric", "mixed_area") for k in (0, 1, 2)] + \
        [(mesh, "whitney", k) for mesh in MESHES for k in (0, 1, 2)]


@pytest.mark.parametrize("mesh, star, k", CASES)
def test_laplacian_is_minus_dec_laplacian(mesh, star, k):
    """laplacian(u) = −DEC.laplacian(k) u and laplace_de_rham(u) = +DEC.laplacian(k) u, through
    the folded-matrix path (an operator applied to a name) and the evaluated path (to a term)."""
    dec = dec_of(mesh, star)
    u = random_form(dec, primal(k), seed=k)
    expected = dec.laplacian(k) @ u
    for text, sign in (("laplacian(u)", -1), ("laplacian(1*u)", -1), ("Δu", -1), ("laplace_de_rham(u)", 1),
                       ("laplace_de_rham(u + 0*u)", 1)):
        close(evaluate(dec, text, u=(primal(k), u)), sign * expected)


def test_laplacian_of_0_forms_is_the_cotan_formula_with_laplace_beltrami_sign():
    """An independent check of the sign and weights: (Δu)_i = (1/⋆0_i) Σ_ij ½(cot α + cot β)(u_j − u_i),
    the cotangents computed here; on the unit sphere Δ(xy) ≈ −6 xy (l = 2) and ⟨u, Δu⟩ ≤ 0."""
    dec = dec_of("sphere")
    K = dec.K
    u = random_form(dec, primal(0), seed=3)
    tri = K.simplices(2)
    cot = cotangents(K.vertices[tri])
    out = np.zeros(K.num_simplices(0))
    for corner in range(3):  # the angle at `corner` weighs the opposite edge (i, j)
        i, j = (corner + 1) % 3, (corner + 2) % 3
        flow = 0.5 * cot[:, corner] * (u[tri[:, j]] - u[tri[:, i]])
        np.add.at(out, tri[:, i], flow)
        np.add.at(out, tri[:, j], -flow)
    close(evaluate(dec, "laplacian(u)", u=(primal(0), u)), out / dec.star_diagonal(0))
    assert evaluate(dec, "inner(u, laplacian(u))", u=(primal(0), u)) < 0
    assert evaluate(dec, "inner(u, laplace_de_rham(u))", u=(primal(0), u)) > 0
    ratio = evaluate(dec, "inner(x*y, laplacian(x*y)) / inner(x*y, x*y)")
    assert -6.3 < ratio < -5.7, ratio


@pytest.mark.parametrize("mesh", [*MESHES, *MORE])
def test_d_of_d_is_zero_primal_and_dual(mesh):
    dec = dec_of(mesh)
    n = dec.n
    for k in range(n - 1):
        u = random_form(dec, primal(k))
        for text in ("d(d(u))", "d(d(1*u))"):
            value = evaluate(dec, text, u=(primal(k), u))
            assert value.shape == (primal(k + 2).size(dec.K),)
            assert np.abs(value).max() <= 1e-14 * np.abs(u).max()
        if k + 2 <= n and mesh in MESHES:  # δδ = 0 too, with the ⋆⁻¹ in between
            b = random_form(dec, primal(k + 2), 3)
            assert np.abs(evaluate(dec, "codifferential(codifferential(b))", b=(primal(k + 2), b))).max() \
                <= 1e-12 * np.abs(evaluate(dec, "codifferential(b)", b=(primal(k + 2), b))).max()
        w = random_form(dec, dual(k), seed=1)
        assert np.abs(evaluate(dec, "d(d(w))", w=(dual(k), w))).max() <= 1e-14 * np.abs(w).max()
        # and on the dual of a primal form: d ⋆ then d again
        v = random_form(dec, primal(n - k), 2)
        starred = dec.star(n - k) @ v
        assert np.abs(evaluate(dec, "d(d(star(v)))", v=(primal(n - k), v))).max() <= 1e-14 * np.abs(starred).max()


@pytest.mark.parametrize("star", ["circumcentric", "mixed_area", "whitney"])
@pytest.mark.parametrize("mesh", MESHES)
def test_codifferential_is_the_adjoint_of_d(mesh, star):
    """⟨d a, b⟩ = ⟨a, δ b⟩ under the ⋆ inner product (eq. 4.14, 4.15), with the variant's stars
    (Whitney's Galerkin ⋆ through factorized solves) — on closed meshes and with a border."""
    dec = dec_of(mesh, star)
    for k in (1, 2):
        a, b = random_form(dec, primal(k - 1), 1), random_form(dec, primal(k), 2)
        left = evaluate(dec, "inner(d(a), b)", a=(primal(k - 1), a), b=(primal(k), b))
        right = evaluate(dec, "inner(a, codifferential(b))", a=(primal(k - 1), a), b=(primal(k), b))
        scale = evaluate(dec, "norm(d(a)) * norm(b)", a=(primal(k - 1), a), b=(primal(k), b))
        assert abs(left - right) <= 1e-12 * scale, (k, left, right)
        close(evaluate(dec, "δ(b)", b=(primal(k), b)), dec.codifferential(k) @ b)


@pytest.mark.parametrize("star", ["circumcentric", "mixed_area", "whitney"])
@pytest.mark.parametrize("mesh", [*MESHES, "tets"])
def test_star_star_is_the_sign_and_inv_star_undoes_star(mesh, star):
    if mesh == "tets" and star != "whitney":
        pytest.skip("the Kuhn cube's circumcentric ⋆1, ⋆2 have zeros (cospherical corners); Whitney's are SPD")
    dec = dec_of(mesh, star)
    n = dec.n
    for k in range(n + 1):
        u = random_form(dec, primal(k), k)
        sign = (-1) ** (k * (n - k))
        close(evaluate(dec, "star(star(u))", u=(primal(k), u)), sign * u)
        close(evaluate(dec, "⋆(⋆(1*u))", u=(primal(k), u)), sign * u)
        close(evaluate(dec, "inv_star(star(u))", u=(primal(k), u)), u)
        close(evaluate(dec, "star(u)", u=(primal(k), u)), dec.star(k) @ u)
        w = random_form(dec, dual(n - k), k + 10)
        close(evaluate(dec, "star(inv_star(w))", w=(dual(n - k), w)), w)
        # ⋆ is an isometry from primal k-forms to dual (n−k)-forms
        v = random_form(dec, primal(k), k + 20)
        assert np.isclose(evaluate(dec, "inner(star(u), star(v))", u=(primal(k), u), v=(primal(k), v)),
                          evaluate(dec, "inner(u, v)", u=(primal(k), u), v=(primal(k), v)), rtol=1e-11, atol=1e-12)


@pytest.mark.parametrize("star", ["circumcentric", "mixed_area", "barycentric", "whitney"])
@pytest.mark.parametrize("mesh", [*MESHES, "planar", "grid"])
def test_integral_is_the_sum_of_star0_u(mesh, star):
    dec = dec_of(mesh, star)
    K = dec.K
    u = random_form(dec, primal(0), 4)
    assert np.isclose(evaluate(dec, "integral(u)", u=(primal(0), u)), (dec.star(0) @ u).sum(), rtol=1e-13)
    # every variant's ⋆0 partitions the area: ∫ 1 = area of the mesh
    assert np.isclose(evaluate(dec, "integral(1 + 0*x)"), K.top_volumes.sum(), rtol=1e-12)
    r = random_form(dec, dual(0), 5)
    assert np.isclose(evaluate(dec, "integral(r)", r=(dual(0), r)), K.top_volumes @ r, rtol=1e-13)
    s = random_form(dec, primal(2), 6)
    assert np.isclose(evaluate(dec, "integral(s)", s=(primal(2), s)), s.sum(), rtol=1e-13)


def test_operators_through_a_compiled_model():
    """The same identities with compile_model (fields, definitions and metrics in YAML terms)."""
    dec = dec_of("torus")
    spec = ModelSpec(fields={"u": FieldSpec(0, "random"), "w": FieldSpec(1, ["-y", "x*z", "y*z"])},
                     equations=["dt(u) = laplacian(u)", "lap = laplacian(w)", "dd = d(d(u))", "ss = star(star(w))",
                                "adj = inner(d(u), w) - inner(u, codifferential(w))"],
                     metrics={"mass": "integral(u)", "adjoint_gap": "adj"})
    model = compile_model(spec, dec, solver_factory("direct"))
    env = model.environment({"u": model.initial_values["u"]}, 0.0)
    u, w = env["u"], env["w"]
    close(env["lap"], -(dec.laplacian(1) @ w))
    assert np.abs(env["dd"]).max() <= 1e-14 * np.abs(u).max()
    close(env["ss"], -w)
    assert abs(env["adj"]) <= 1e-12 * np.linalg.norm(w) * np.linalg.norm(u) * 10
    assert np.isclose(model.metric_values(env)["mass"], (dec.star(0) @ u).sum(), rtol=1e-13)
    close(model.derivative(env)["u"], -(dec.laplacian(0) @ u))


# ------------------------------------------------------------------------------- wedge
def signed_areas(K) -> np.ndarray:
    """∫_σ dx∧dy over each oriented triangle of a planar complex (rows of K.oriented_simplices())."""
    p = K.vertices[K.oriented_simplices()]
    return 0.5 * ((p[:, 1, 0] - p[:, 0, 0]) * (p[:, 2, 1] - p[:, 0, 1]) - (p[:, 1, 1] - p[:, 0, 1]) * (p[:, 2, 0] - p[:, 0, 0]))


def test_dx_wedge_dy_is_the_signed_area():
    dec = dec_of("planar")
    K = dec.K
    area = signed_areas(K)
    close(evaluate(dec, "d(x) ^ d(y)"), area, rtol=1e-13)
    close(evaluate(dec, "wedge(d(y), d(x))"), -area, rtol=1e-13)
    # 1-forms sampled from constant vector fields a, b: (a♭ ∧ b♭) = (a1 b2 − a2 b1) |σ|
    a, b = np.array([0.3, -1.7]), np.array([2.2, 0.4])
    alpha, beta = sample_vector_field(K, a), sample_vector_field(K, b)
    close(evaluate(dec, "alpha ∧ beta", alpha=(primal(1), alpha), beta=(primal(1), beta)),
          (a[0] * b[1] - a[1] * b[0]) * area, rtol=1e-12)
    # the 2-form agrees with the sampled density 1 (the same orientation convention)
    assert np.all(area > 0)
    close(evaluate(dec, "d(x) ^ d(y)"), K.top_volumes, rtol=1e-13)


@pytest.mark.parametrize("mesh", ["sphere", "torus"])
def test_dx_wedge_dy_on_a_surface_is_the_flux_of_ez(mesh):
    """On a surface in R³, dx∧dy on each oriented triangle = the flux of (0, 0, 1) through it, as
    the initial value of a 2-form samples it (the same orientation)."""
    dec = dec_of(mesh)
    spec = ModelSpec(fields={"u": FieldSpec(0, 0), "ez": FieldSpec(2, ["0", "0", "1"])},
                     equations=["dt(u) = laplacian(u)", "w = d(x) ^ d(y)"])
    model = compile_model(spec, dec, solver_factory("direct"))
    env = model.environment({"u": model.initial_values["u"]}, 0.0)
    close(env["w"], model.initial_values["ez"], rtol=1e-13)


def test_dx_wedge_dy_on_tetrahedra_is_the_projected_area():
    """In 3-D, 1∧1 is a 2-form on the (sorted) triangles: ∫ dx∧dy = the signed area of the
    triangle's projection on the xy-plane."""
    dec = dec_of("tets")
    p = dec.K.vertices[dec.K.simplices(2)]
    projected = 0.5 * np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    close(evaluate(dec, "d(x) ^ d(y)"), projected[:, 2], rtol=1e-13)
    close(evaluate(dec, "d(y) ^ d(z)"), projected[:, 0], rtol=1e-13)
    close(evaluate(dec, "d(z) ^ d(x)"), projected[:, 1], rtol=1e-13)


@pytest.mark.parametrize("mesh", [*MESHES, "planar", "tets"])
def test_wedge_is_antisymmetric_on_1_forms_and_commutes_with_0_forms(mesh):
    dec = dec_of(mesh)
    alpha, beta = random_form(dec, primal(1), 1), random_form(dec, primal(1), 2)
    f, g = random_form(dec, primal(0), 3), random_form(dec, primal(0), 4)
    fields = dict(a=(primal(1), alpha), b=(primal(1), beta), f=(primal(0), f), g=(primal(0), g))
    close(evaluate(dec, "a ^ b", **fields), -evaluate(dec, "b ^ a", **fields))
    assert np.abs(evaluate(dec, "a ^ a", **fields)).max() <= 1e-15 * np.abs(alpha).max() ** 2
    close(evaluate(dec, "f ^ a", **fields), evaluate(dec, "a ^ f", **fields))
    close(evaluate(dec, "f ^ g", **fields), f * g)
    # bilinear
    close(evaluate(dec, "(2*a + b) ^ (a - 3*b)", **fields), evaluate(dec, "-6 * a ^ b + b ^ a", **fields))
    # f ∧ a = the mean of f over each edge times a
    edges = dec.K.simplices(1)
    close(evaluate(dec, "f ^ a", **fields), 0.5 * (f[edges[:, 0]] + f[edges[:, 1]]) * alpha)


@pytest.mark.parametrize("mesh", [*MESHES, "planar", "tets"])
def test_leibniz_rule(mesh):
    """d(f∧β) = df∧β + f∧dβ to round-off for any 1-form β (for β = dg: d(f∧dg) = df∧dg), and
    d(fg) = df∧g + f∧dg for 0-forms."""
    dec = dec_of(mesh)
    f, g = random_form(dec, primal(0), 1), random_form(dec, primal(0), 2)
    beta = random_form(dec, primal(1), 3)
    fields = dict(f=(primal(0), f), g=(primal(0), g), b=(primal(1), beta))
    close(evaluate(dec, "d(f ^ d(g))", **fields), evaluate(dec, "d(f) ^ d(g)", **fields), rtol=1e-13)
    close(evaluate(dec, "d(f ^ b)", **fields), evaluate(dec, "d(f) ^ b + f ^ d(b)", **fields), rtol=1e-13)
    close(evaluate(dec, "d(f*g)", **fields), evaluate(dec, "d(f) ^ g + f ^ d(g)", **fields), rtol=1e-13)


def test_leibniz_rule_has_no_mesh_dependent_error():
    """On refined planar meshes with smooth f and a non-closed β (sampled from a smooth field) the
    Leibniz defect stays at round-off (no O(h) term)."""
    errors = []
    for max_area in (0.02, 0.005, 0.00125):
        mesh = option("mesh", "planar", holes=[], max_area=max_area).load()
        K = SimplicialComplex(mesh.vertices, mesh.simplices)
        dec = DEC(K)
        f = np.sin(2 * K.vertices[:, 0]) * np.cos(K.vertices[:, 1]) + K.vertices[:, 0] ** 2
        beta = sample_vector_field(K, lambda p: np.stack([np.cos(p[:, 1]) + p[:, 0] * p[:, 1],
                                                          np.sin(3 * p[:, 0]) * p[:, 1]], 1), order=5)
        fields = dict(f=(primal(0), f), b=(primal(1), beta))
        lhs = evaluate(dec, "d(f ^ b)", **fields)
        rhs = evaluate(dec, "d(f) ^ b + f ^ d(b)", **fields)
        assert evaluate(dec, "norm(d(b))", **fields) > 0.1  # β is not closed
        errors.append(np.abs(lhs - rhs).sum() / np.abs(lhs).sum())
    assert max(errors) < 1e-13, errors


# ------------------------------------------------------------------------------- ♯ ♭ interior Lie average norm
def test_sharp_of_d_is_the_gradient():
    """sharp(d(f)) = ∇f of the piecewise-linear f: (2, −3) for f = 2x − 3y + 1 on a planar mesh; on
    the sphere the projection of the ambient gradient onto each triangle's plane."""
    dec = dec_of("planar")
    gradient = evaluate(dec, "sharp(d(2*x - 3*y + 1))")
    assert gradient.shape == (dec.K.num_simplices(2), 2)
    close(gradient, np.tile([2.0, -3.0], (dec.K.num_simplices(2), 1)), rtol=1e-12)
    dec = dec_of("sphere")
    K = dec.K
    p = K.vertices[K.simplices(2)]
    normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    a = np.array([0.5, -1.0, 2.0])
    tangential = a - np.einsum("fd,d->f", normal, a)[:, None] * normal
    close(evaluate(dec, "sharp(d(0.5*x - y + 2*z))"), tangential, rtol=1e-12)
    dec = dec_of("tets")  # in a volume ♯ d f is the full gradient
    close(evaluate(dec, "sharp(d(0.5*x - y + 2*z))"), np.tile(a, (dec.K.num_simplices(3), 1)), rtol=1e-12)
    X = np.random.default_rng(16).standard_normal((dec.K.num_simplices(3), 3))
    close(evaluate(dec, "interior(X, d(0.5*x - y + 2*z))", X=(VECTOR, X)), X @ a, rtol=1e-12)


@pytest.mark.parametrize("mesh", ["planar", "lattice", "sphere", "torus"])
def test_flat_of_sharp_of_d_is_d(mesh):
    """♭♯ d f = d f exactly for a linear f, and in fact for any f: ∇f_T · e = f_b − f_a on every
    edge of T, so every triangle at an edge agrees."""
    dec = dec_of(mesh)
    f = random_form(dec, primal(0), 7)
    close(evaluate(dec, "flat(sharp(d(f)))", f=(primal(0), f)), dec.d(0) @ f, rtol=1e-12)
    close(evaluate(dec, "♭(♯(d(3*x - y + 2)))"), dec.d(0) @ (3 * dec.K.vertices[:, 0] - dec.K.vertices[:, 1]),
          rtol=1e-12)


def cotangents(p) -> np.ndarray:
    """(m, 3) cotangent of the angle at each corner of the triangles p (m, 3, d), d = 2 or 3."""
    out = np.empty(p.shape[:2])
    for corner in range(3):
        a, b = p[:, (corner + 1) % 3] - p[:, corner], p[:, (corner + 2) % 3] - p[:, corner]
        cross = np.linalg.norm(np.cross(a, b), axis=1) if p.shape[2] == 3 else np.abs(a[:, 0] * b[:, 1]
                                                                                      - a[:, 1] * b[:, 0])
        out[:, corner] = np.einsum("fd,fd->f", a, b) / cross
    return out


def cotan_divergence(K, X) -> np.ndarray:
    """The integrated divergence of a piecewise-constant field X at the vertices (the cotan
    formula): in each triangle (i, j, k) vertex i gets ½ (cot θ_k (p_j − p_i)·X + cot θ_j (p_k − p_i)·X)."""
    tri = K.simplices(2)
    p = K.vertices[tri]
    cot = cotangents(p)
    out = np.zeros(K.num_simplices(0))
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        np.add.at(out, tri[:, i], 0.5 * (cot[:, k] * np.einsum("fd,fd->f", p[:, j] - p[:, i], X)
                                         + cot[:, j] * np.einsum("fd,fd->f", p[:, k] - p[:, i], X)))
    return out


@pytest.mark.parametrize("star", ["circumcentric", "mixed_area"])
@pytest.mark.parametrize("mesh", ["planar", "lattice", "sphere", "torus"])
def test_minus_codifferential_of_flat_is_the_cotan_divergence(mesh, star):
    dec = dec_of(mesh, star)
    K = dec.K
    X = np.random.default_rng(8).standard_normal((K.num_simplices(2), K.embedding_dim))
    expected = cotan_divergence(K, X) / dec.star_diagonal(0)
    close(evaluate(dec, "-codifferential(flat(X))", X=(VECTOR, X)), expected, rtol=1e-11)
    # the divergence of a constant field integrates to the flux through the border (0 on closed meshes)
    if mesh == "sphere":
        assert abs(evaluate(dec, "integral(-codifferential(flat(X)))", X=(VECTOR, X))) <= 1e-12 * np.abs(X).sum()


def test_lie_and_interior_of_linear_functions():
    """lie(X, f) = X·∇f exactly for linear f and constant X (a planar mesh); interior(X, d(f)) = X·∇f
    per triangle for any X."""
    dec = dec_of("planar")
    K = dec.K
    X = np.tile([0.5, -2.0], (K.num_simplices(2), 1))
    close(evaluate(dec, "lie(X, 3*x - y + 2)", X=(VECTOR, X)), np.full(K.num_simplices(0), 3.5), rtol=1e-12)
    Y = np.random.default_rng(9).standard_normal((K.num_simplices(2), 2))
    close(evaluate(dec, "interior(Y, d(3*x - y + 2))", Y=(VECTOR, Y)), Y @ [3.0, -1.0], rtol=1e-12)
    # a constant field written in the language: X = 0.5 ∇x − 2 ∇y
    close(evaluate(dec, "lie(0.5*sharp(d(x)) - 2*sharp(d(y)), 3*x - y + 2)"), np.full(K.num_simplices(0), 3.5),
          rtol=1e-12)
    # lie is interior(X, d f) brought to the vertices (area-weighted mean of the triangles at each vertex)
    f = random_form(dec, primal(0), 10)
    per_triangle = evaluate(dec, "interior(Y, d(f))", Y=(VECTOR, Y), f=(primal(0), f))
    weights = np.zeros(K.num_simplices(0))
    total = np.zeros(K.num_simplices(0))
    for corner in range(3):
        np.add.at(total, K.simplices(2)[:, corner], K.top_volumes * per_triangle)
        np.add.at(weights, K.simplices(2)[:, corner], K.top_volumes)
    close(evaluate(dec, "lie(Y, f)", Y=(VECTOR, Y), f=(primal(0), f)), total / weights, rtol=1e-12)


def test_average_and_norms():
    dec = dec_of("sphere")
    K = dec.K
    u = random_form(dec, primal(0), 11)
    edges = K.simplices(1)
    close(evaluate(dec, "average(u)", u=(primal(0), u)), 0.5 * (u[edges[:, 0]] + u[edges[:, 1]]))
    midpoint = 0.5 * (K.vertices[edges[:, 0]] + K.vertices[edges[:, 1]])
    close(evaluate(dec, "average(2*x - z)"), 2 * midpoint[:, 0] - midpoint[:, 2])
    # norm of a vector field: its length per triangle; of a form: √⟨u, u⟩
    planar = dec_of("planar")
    close(evaluate(planar, "norm(sharp(d(2*x - 3*y)))"), np.full(planar.K.num_simplices(2), np.sqrt(13.0)))
    w = random_form(dec, primal(1), 12)
    assert np.isclose(evaluate(dec, "norm(w)", w=(primal(1), w)), np.sqrt(w @ (dec.star(1) @ w)), rtol=1e-13)
    r = random_form(dec, dual(1), 13)
    assert np.isclose(evaluate(dec, "norm(r)", r=(dual(1), r)), np.sqrt(r @ (r / dec.star_diagonal(1))), rtol=1e-13)
    Y = np.random.default_rng(14).standard_normal((K.num_simplices(2), 3))
    assert np.isclose(evaluate(dec, "inner(Y, Y)", Y=(VECTOR, Y)), K.top_volumes @ (Y ** 2).sum(axis=1), rtol=1e-13)
    assert evaluate(dec, "norm(u)", u=(primal(0), u)) == pytest.approx(np.sqrt(u @ (dec.star(0) @ u)), rel=1e-13)
    assert evaluate(dec, "max(u) - min(u)", u=(primal(0), u)) == pytest.approx(u.max() - u.min())
    assert evaluate(dec, "mean(u)", u=(primal(0), u)) == pytest.approx(u.mean())
    assert NUMBER == Compiler(Discrete(dec), {"u": primal(0)}).kind(parse_expression("norm(u)", "k"), "k")


LINEAR_TERMS = {
    0: ["laplacian(u)", "2*laplacian(u) - u/3", "codifferential(d(u))", "inv_star(star(u))", "star(star(u))",
        "laplacian(laplacian(u))", "-(1 + x**2)*laplacian(u) + pi*u", "codifferential(average(x)*d(u))",
        "laplace_de_rham(u) + laplacian(u)"],
    1: ["laplacian(u)", "d(codifferential(u)) + codifferential(d(u))", "-laplace_de_rham(u)", "star(star(u))",
        "average(x)*u - 2*u", "d(codifferential(u))/4 - u*dt"],
}


@pytest.mark.parametrize("star", ["circumcentric", "mixed_area", "whitney"])
@pytest.mark.parametrize("k", [0, 1])
def test_linear_blocks_equal_the_evaluated_terms(k, star):
    """What implicit integrators and solves assemble (Compiler.split: ⋆⁻¹A blocks) is what the
    explicit evaluation computes, term by term; a term that has no sparse block (a Galerkin ⋆⁻¹
    inside a chain) stays in the explicit rest, and the sum is the same."""
    dec = dec_of("sphere", star)
    K = dec.K
    compiler = Compiler(Discrete(dec), {"u": primal(k)}, varying={"u"})
    compiler.static_env = env_of(K, {})
    u = random_form(dec, primal(k), 15)
    env = env_of(K, {"u": u})
    for text in LINEAR_TERMS[k]:
        tree = parse_expression(text, "e")
        expected = compiler.compile(tree, "e")(env)
        blocks, rest = compiler.split(tree, {"u"})
        value = Discrete(dec).matrix(blocks["u"])(u) if blocks else 0.0
        for sign, term in rest:
            value = value + sign * compiler.compile(term, "e")(env)
        close(value, expected, rtol=1e-11)
        if star != "whitney" or text in ("laplacian(u)", "2*laplacian(u) - u/3") and k == 0:
            assert not rest, (text, rest)  # diagonal stars: everything is one sparse block
