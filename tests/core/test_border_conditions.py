"""Dirichlet, Neumann and Robin borders for 0-forms (decrun.core.boundary.conditions), with
plain DEC matrices: exact identities (Green's identity for linear u, the border measures,
#48's flux difference) and manufactured solutions whose spatial order is measured over three
refinements on triangles (the unit square) and tetrahedra (the unit cube)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla
import triangle

from decrun.core.boundary import conditions as bc
from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC

from meshes_for_tests import kuhn_cube, random_tets, square_lattice

ORDER = 1.8


def square(n: int) -> SimplicialComplex:
    return SimplicialComplex(*square_lattice(n), orient="fix")


def cube(n: int) -> SimplicialComplex:
    return SimplicialComplex(*kuhn_cube(n), orient="fix")


def disc(n: int) -> SimplicialComplex:
    """The unit disc's inscribed 4n-gon meshed by ``triangle`` with triangles of side ≈ 2π/(4n)
    (the domain is the polygon: data on it are evaluated on its edges, with their normals)."""
    angle = np.linspace(0, 2 * np.pi, 4 * n, endpoint=False)
    ring = np.arange(4 * n)
    domain = {"vertices": np.stack([np.cos(angle), np.sin(angle)], 1),
              "segments": np.stack([ring, (ring + 1) % (4 * n)], 1)}
    side = 2 * np.pi / (4 * n)
    result = triangle.triangulate(domain, f"pq30a{0.5 * side**2:.8f}")
    return SimplicialComplex(result["vertices"], result["triangles"].astype(np.int64), orient="fix")


MESHES = {2: (square, (8, 16, 32)), 3: (cube, (4, 8, 16)), "disc": (disc, (16, 32, 64))}


def orders(errors) -> np.ndarray:
    """Observed orders between successive halvings of h."""
    errors = np.asarray(errors)
    return np.log2(errors[:-1] / errors[1:])


def l2(dec: DEC, e: np.ndarray) -> float:
    return float(np.sqrt(dec.star_diagonal(0) @ e**2))


# ------------------------------------------------------------------ manufactured solutions
def steady(p):
    """u = eˣ sin y cos z + xy(z) in 2-D (z = 0) or 3-D: (u, ∇u, Δu) at points p (m, d)."""
    x, y = p[:, 0], p[:, 1]
    z = p[:, 2] if p.shape[1] == 3 else np.zeros_like(x)
    cubic = p.shape[1] == 3
    w = 1.0 if cubic else 2.0                                     # sin(w y): Δ = (1 − w² − [1]) eˣ…
    e = np.exp(x) * np.sin(w * y) * np.cos(z)
    extra = x * y * (z if cubic else 1.0)
    u = e + extra
    grad = np.stack([e + y * (z if cubic else 1), w * np.exp(x) * np.cos(w * y) * np.cos(z) + x * (z if cubic else 1),
                     -np.exp(x) * np.sin(w * y) * np.sin(z) + x * y], axis=1)[:, :p.shape[1]]
    return u, grad, (1 - w**2 - (1 if cubic else 0)) * e


def border_data(K, function):
    """(faces, normals, quadrature, ∂u/∂n at the quadrature points)."""
    faces = bc.border_faces(K)
    normals = bc.outward_normals(K, faces)
    quadrature = bc.border_quadrature(K, faces)
    _, grad, _ = function(quadrature.points)
    return faces, normals, quadrature, np.einsum("qd,qd->q", grad, normals[quadrature.face])


def solve_steady(K, kind: str) -> float:
    """−Δu = f with the border ``kind``; the ⋆0-weighted L2 error at the vertices."""
    dec = DEC(K)
    stiffness = dec.laplacian_symmetric(0)
    star0 = dec.star_diagonal(0)
    exact, _, laplacian = steady(K.vertices)
    _, _, quadrature, flux = border_data(K, steady)
    right = star0 * -laplacian
    if kind == "neumann":                                         # S u = ⋆0 f + b, Σ ⋆0 u fixed
        b = right + bc.border_load(K, quadrature, flux)
        b -= star0 * b.sum() / star0.sum()                        # into S's range (Σ b = O(h²) before)
        pin = bc.Condensation(np.arange(K.num_simplices(0)) == 0)  # consistent: any one value will do
        u = pin.expand(spla.spsolve(pin.matrix(stiffness).tocsc(), pin.right_side(stiffness, b, [0.0])), [0.0])
        u += (star0 @ (exact - u)) / star0.sum()
    elif kind == "robin":                                         # (S + R) u = ⋆0 f + ∫ value
        alpha = 1.0 + quadrature.points[:, 0] ** 2
        value = flux + alpha * steady(quadrature.points)[0]
        system = (stiffness + bc.robin_matrix(K, quadrature, alpha)).tocsc()
        u = spla.spsolve(system, right + bc.border_load(K, quadrature, value))
    else:                                                         # Dirichlet on x = 0, Neumann elsewhere
        condensation = bc.Condensation(K.border_vertices() & (K.vertices[:, 0] < 1e-12))
        values = exact[condensation.fixed_index]
        b = right + bc.border_load(K, quadrature, flux)
        free = spla.spsolve(condensation.matrix(stiffness).tocsc(), condensation.right_side(stiffness, b, values))
        u = condensation.expand(free, values)
    return l2(dec, u - exact)


@pytest.mark.parametrize("dim", [2, 3, "disc"])
@pytest.mark.parametrize("kind", ["neumann", "robin", "mixed"])
def test_poisson_with_borders_converges_at_second_order(dim, kind):
    make, sizes = MESHES[dim]
    errors = [solve_steady(make(n), kind) for n in sizes]
    assert orders(errors).min() >= ORDER, (kind, dim, errors, orders(errors))


# ------------------------------------------------------------------ heat equations, Crank–Nicolson
def moving(p, t):
    """u = e^{−dπ²t} Π sin(π x_k) + t x: (u, u_t − Δu = x, u_t); on the border g = t x (moving)."""
    d = p.shape[1]
    mode = np.exp(-d * np.pi**2 * t) * np.prod(np.sin(np.pi * p), axis=1)
    return mode + t * p[:, 0], p[:, 0], -d * np.pi**2 * mode + p[:, 0]


def sliding(p, t):
    """u = t x + y, linear in space and time: (u, u_t − Δu = x, u_t)."""
    return t * p[:, 0] + p[:, 1], p[:, 0], p[:, 0]


def crank_nicolson(mass, stiff, y, source, dt: float, steps: int):
    """M y' = L y + s(t): (M − dt/2 L) y⁺ = (M + dt/2 L) y + dt/2 (s(t) + s(t + dt)), factorized once."""
    solve = spla.factorized((mass - dt / 2 * stiff).tocsc())
    explicit = (mass + dt / 2 * stiff).tocsr()
    for step in range(steps):
        y = solve(explicit @ y + dt / 2 * (source(step * dt) + source((step + 1) * dt)))
    return y


def p1_mass(K) -> sp.csr_matrix:
    """The consistent (Galerkin) P1 mass of a triangle mesh: |T|/12 (1 + δ_ij)."""
    T = K.simplices(2)
    local = (np.ones((3, 3)) + np.eye(3)) / 12
    values = K.top_volumes[:, None, None] * local
    rows, cols = np.repeat(T, 3, axis=1), np.tile(T, (1, 3))
    return sp.csr_matrix((values.reshape(len(T), 9).ravel(), (rows.ravel(), cols.ravel())),
                         shape=(K.num_simplices(0),) * 2)


def heat_with_moving_border(K, exact=moving, mass=None, with_rate: bool = True, dt: float = 1e-3,
                            t_end: float = 0.05) -> float:
    """u_t = Δu + s with u = g(x, t) on the border, condensed; the L2 error at t_end."""
    dec = DEC(K)
    stiff = -dec.laplacian_symmetric(0)
    mass = dec.star(0) if mass is None else mass
    condensation = bc.Condensation(K.border_vertices())
    border = K.vertices[condensation.fixed_index]
    load = (mass @ exact(K.vertices, 0.0)[1])[condensation.free_index]     # s = x, constant in t

    def source(t):
        values, _, rate = exact(border, t)
        return condensation.source(stiff, mass, values, rate if with_rate else np.zeros_like(rate)) + load

    steps = int(round(t_end / dt))
    y0 = exact(K.vertices, 0.0)[0][condensation.free_index]
    y = crank_nicolson(condensation.matrix(mass), condensation.matrix(stiff), y0, source, dt, steps)
    u = condensation.expand(y, exact(border, t_end)[0])
    return l2(dec, u - exact(K.vertices, t_end)[0])


@pytest.mark.parametrize("dim", [2, 3])
def test_heat_with_moving_dirichlet_values_converges_at_second_order(dim):
    make, sizes = MESHES[dim]
    errors = [heat_with_moving_border(make(n)) for n in sizes]
    assert orders(errors).min() >= ORDER, (dim, errors, orders(errors))


def test_a_consistent_mass_needs_the_rate_of_the_border_values():
    """With the Galerkin P1 mass, M_FD ∂g/∂t belongs in the free rows: u = t x + y lies in the
    P1 space and Crank–Nicolson is exact for it when the term is kept (round-off), not when
    dropped; the moving-border solution keeps its second order."""
    K = square(8)
    assert heat_with_moving_border(K, sliding, mass=p1_mass(K)) < 1e-12
    assert heat_with_moving_border(K, sliding, mass=p1_mass(K), with_rate=False) > 1e-5
    errors = [heat_with_moving_border(square(n), mass=p1_mass(square(n))) for n in (8, 16, 32)]
    assert orders(errors).min() >= ORDER, (errors, orders(errors))
    with pytest.raises(ValueError, match="∂g/∂t"):
        bc.Condensation(K.border_vertices()).source(sp.eye(K.num_simplices(0)), p1_mass(K),
                                                    np.zeros(int(K.border_vertices().sum())), None)


def decaying(p, t):
    """u = e^{−t} (cos x cosh y + z² − x²) (harmonic in space): (u, ∇u, u_t − Δu = −u)."""
    x, y = p[:, 0], p[:, 1]
    z = p[:, 2] if p.shape[1] == 3 else 0.0
    quadratic = (z**2 - x**2) if p.shape[1] == 3 else 0.0
    u = np.exp(-t) * (np.cos(x) * np.cosh(y) + quadratic)
    grad = np.exp(-t) * np.stack([-np.sin(x) * np.cosh(y) - (2 * x if p.shape[1] == 3 else 0 * x),
                                  np.cos(x) * np.sinh(y), 2 * z + 0 * x], axis=1)[:, :p.shape[1]]
    return u, grad, -u


def robin_heat(K, dt: float = 2e-3, t_end: float = 0.1) -> float:
    """u_t = Δu + s with ∂u/∂n + 2u = value(x, t) on the whole border; L2 error at t_end."""
    dec = DEC(K)
    faces = bc.border_faces(K)
    normals = bc.outward_normals(K, faces)[bc.border_quadrature(K, faces).face]
    quadrature = bc.border_quadrature(K, faces)
    alpha = np.full(quadrature.weights.shape, 2.0)
    stiff = -(dec.laplacian_symmetric(0) + bc.robin_matrix(K, quadrature, alpha))
    star0 = dec.star_diagonal(0)

    def source(t):
        u, grad, _ = decaying(quadrature.points, t)
        value = np.einsum("qd,qd->q", grad, normals) + alpha * u
        return bc.border_load(K, quadrature, value) + star0 * decaying(K.vertices, t)[2]

    y = crank_nicolson(dec.star(0), stiff, decaying(K.vertices, 0.0)[0], source, dt, int(round(t_end / dt)))
    return l2(dec, y - decaying(K.vertices, t_end)[0])


@pytest.mark.parametrize("dim", [2, 3, "disc"])
def test_heat_with_a_robin_border_converges_at_second_order(dim):
    make, sizes = MESHES[dim]
    errors = [robin_heat(make(n)) for n in sizes]
    assert orders(errors).min() >= ORDER, (dim, errors, orders(errors))


# ------------------------------------------------------------------ identities
def tilted_square(n: int) -> SimplicialComplex:
    """The unit square turned into a plane of 3-D space (a surface mesh: n = 2, d = 3)."""
    V, T = square_lattice(n, jitter=0.2, seed=3)
    axes = np.array([[0.6, 0.0, 0.8], [0.0, 1.0, 0.0]])
    return SimplicialComplex(V @ axes, T, orient="fix")


IDENTITY_MESHES = {
    "jittered square": lambda: SimplicialComplex(*square_lattice(9, jitter=0.25, seed=1), orient="fix"),
    "tilted square": lambda: tilted_square(7),
    "Kuhn cube": lambda: cube(3),
    "random tetrahedra": lambda: SimplicialComplex(*random_tets(70, seed=2), orient="fix"),
}


@pytest.mark.parametrize("name", list(IDENTITY_MESHES))
def test_green_identity_is_exact_for_linear_fields(name):
    """For linear u the cot Laplacian is exact: S u = b with b the Neumann load of g = ∂u/∂n,
    on every vertex, border ones included — whatever the mesh quality (obtuse, random)."""
    K = IDENTITY_MESHES[name]()
    gradient = np.array([0.3, -1.2, 0.7])[:K.vertices.shape[1]]
    _, normals, quadrature, _ = border_data(K, steady)
    flux = (normals @ gradient)[quadrature.face]
    load = bc.border_load(K, quadrature, flux)
    residual = DEC(K).laplacian_symmetric(0) @ (K.vertices @ gradient) - load
    assert np.abs(residual).max() < 1e-9 * np.abs(load).max()
    assert np.abs(load[~K.border_vertices()]).max() == 0


@pytest.mark.parametrize("name, total", [("jittered square", 4.0), ("tilted square", 4.0), ("Kuhn cube", 6.0)])
def test_border_measures_sum_to_the_border_and_live_on_it(name, total):
    K = IDENTITY_MESHES[name]()
    measures = bc.border_measures(K)
    assert measures.sum() == pytest.approx(total, rel=1e-12)
    assert np.array_equal(measures != 0, K.border_vertices())


def test_border_measures_of_a_cube_are_the_circumcentric_shares():
    """Kuhn cube, n cells a side (h = 1/n): a vertex inside a face has h², one inside a cube
    edge has 2 · h²/2 split as the circumcentres fall on the hypotenuses, a corner its shares."""
    n = 4
    K = cube(n)
    measures = bc.border_measures(K)
    x = K.vertices
    on_walls = ((x < 1e-12) | (x > 1 - 1e-12)).sum(axis=1)
    assert np.allclose(measures[on_walls == 1], 1 / n**2)
    assert measures[on_walls == 2].sum() + measures[on_walls == 3].sum() == pytest.approx(
        6.0 - measures[on_walls == 1].sum())


@pytest.mark.parametrize("name", ["jittered square", "Kuhn cube"])
def test_outward_normals_are_the_walls_normals(name):
    K = IDENTITY_MESHES[name]()
    faces = bc.border_faces(K)
    normals = bc.outward_normals(K, faces)
    centers = K.vertices[faces.vertices].mean(axis=1)
    expected = np.where(centers < 1e-12, -1.0, 0.0) + np.where(centers > 1 - 1e-12, 1.0, 0.0)
    assert np.allclose(normals, expected)


def test_surface_normals_lie_in_the_surface_and_point_out():
    K = tilted_square(6)
    faces = bc.border_faces(K)
    normals = bc.outward_normals(K, faces)
    plane_normal = np.cross([0.6, 0.0, 0.8], [0.0, 1.0, 0.0])
    assert np.allclose(normals @ plane_normal, 0)
    assert np.allclose(np.linalg.norm(normals, axis=1), 1)
    edge = K.vertices[faces.vertices[:, 1]] - K.vertices[faces.vertices[:, 0]]
    assert np.allclose(np.einsum("bd,bd->b", normals, edge), 0)
    away = K.vertices[faces.vertices[:, 0]] - K.vertices[faces.opposite]
    assert (np.einsum("bd,bd->b", normals, away) > 0).all()


def test_the_flux_adaptation_adds_the_neumann_load_of_u_itself():
    """#48 item 4: under ``boundary=flux``, −δ_1 d0 u − L u (L = −⋆0⁻¹ S, ``laplacian``) = ⋆0⁻¹ b(∂u_h/∂n) with ∂u_h/∂n the
    P1 gradient of u in each border edge's triangle — zero inside, O(1/h) on the border."""
    K = SimplicialComplex(*square_lattice(10, jitter=0.2, seed=4), orient="fix")
    flux = DEC(K, boundary="flux")
    u = np.sin(3 * K.vertices[:, 0]) + K.vertices[:, 1] ** 2
    laplacian = -(flux.laplacian(0) @ u)                          # the language's sign: −⋆0⁻¹ S
    difference = -(flux.codifferential(1) @ (flux.d(0) @ u)) - laplacian
    faces = bc.border_faces(K)
    corners = K.vertices[K.simplices(2)[faces.owner]]
    spans = corners[:, 1:] - corners[:, :1]
    values = u[K.simplices(2)[faces.owner]]
    gradient = np.linalg.solve(spans, (values[:, 1:] - values[:, :1])[..., None])[..., 0]
    quadrature = bc.border_quadrature(K, faces)
    g = np.einsum("bd,bd->b", gradient, bc.outward_normals(K, faces))[quadrature.face]
    expected = bc.border_load(K, quadrature, g) / flux.star_diagonal(0)
    assert np.allclose(difference, expected, atol=1e-10 * np.abs(expected).max())
    assert np.abs(expected[K.border_vertices()]).max() > 1.0


def test_condensation_solves_the_full_system_with_fixed_values():
    rng = np.random.default_rng(0)
    n = 12
    B = sp.random(n, n, density=0.4, random_state=1)
    A = (B @ B.T + n * sp.eye(n)).tocsr()
    fixed = np.zeros(n, dtype=bool)
    fixed[[0, 5, 7]] = True
    values, b = rng.normal(size=3), rng.normal(size=n)
    condensation = bc.Condensation(fixed)
    u = condensation.expand(spla.spsolve(condensation.matrix(A).tocsc(), condensation.right_side(A, b, values)), values)
    assert np.allclose(u[fixed], values)
    assert np.allclose((A @ u - b)[~fixed], 0, atol=1e-12)


def test_the_barycentric_share_of_a_border_triangle_breaks_green_identity_on_tetrahedra():
    """Why Γ_i is the circumcentric share: with |T|/3 per vertex instead, S u ≠ b for linear u
    on random (Delaunay) tetrahedra, whose border triangles are not the dual cells' faces."""
    K = IDENTITY_MESHES["random tetrahedra"]()
    gradient = np.array([0.3, -1.2, 0.7])
    faces = bc.border_faces(K)
    corners = K.vertices[faces.vertices]
    area = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1) / 2
    flux = bc.outward_normals(K, faces) @ gradient
    barycentric = np.bincount(faces.vertices.ravel(), np.repeat(area * flux / 3, 3), minlength=K.num_simplices(0))
    residual = DEC(K).laplacian_symmetric(0) @ (K.vertices @ gradient) - barycentric
    assert np.abs(residual).max() > 1e-3 * np.abs(barycentric).max()


@pytest.mark.parametrize("name", list(IDENTITY_MESHES))
def test_the_hat_quadrature_makes_green_identity_exact_for_the_galerkin_stiffness(name):
    """For a Galerkin ⋆0 (operator=whitney) the border load is ∫_∂Ω g φ_i (hat_quadrature): the P1
    stiffness of a linear u is exactly it (integration by parts with Δu = 0), on random tetrahedra
    too, and the hats' border masses ∫_∂Ω φ_i sum to the border's measure."""
    K = IDENTITY_MESHES[name]()
    gradient = np.array([0.3, -1.2, 0.7])[:K.vertices.shape[1]]
    faces = bc.border_faces(K)
    quadrature = bc.hat_quadrature(K, faces)
    load = bc.border_load(K, quadrature, (bc.outward_normals(K, faces) @ gradient)[quadrature.face])
    residual = DEC(K, star="whitney").laplacian_symmetric(0) @ (K.vertices @ gradient) - load
    assert np.abs(residual).max() < 1e-12 * np.abs(load).max()
    assert bc.border_load(K, quadrature, 1.0).sum() == pytest.approx(bc.border_measures(K).sum(), rel=1e-12)
    assert np.array_equal(bc.border_load(K, quadrature, 1.0) > 0, K.border_vertices())
