"""solver=iterative: the Krylov method fits the matrix (CG for SPD, GMRES + ILU for symmetric
indefinite, GMRES with an incomplete LU for unsymmetric) and every solve meets the backward
error tol, so the answers match a direct LU."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.solvers import make_solver
from decrun.core.solvers.iterative import choose_method, is_symmetric
from decrun.errors import ConfigError, SolverError

from meshes_for_tests import mesh


@pytest.fixture(scope="module")
def cot_laplacian():
    """d0ᵀ ⋆1 d0 of a noisy icosphere (circumcentric: some cot weights negative) and ⋆0."""
    m = mesh("icosphere", subdiv=3)
    rng = np.random.default_rng(1)
    V = m.vertices + 0.03 * rng.standard_normal(m.vertices.shape)  # edges ~0.1 long
    dec = DEC(SimplicialComplex(V, m.faces), star="circumcentric")
    assert (dec.star_diagonal(1) < 0).any()
    return sp.csr_matrix(dec.laplacian_symmetric(0)), dec.star_diagonal(0)


def _solve(A, b, **options):
    solver = make_solver("iterative", **options).factorize(A)
    return solver.solve(b), solver


def test_spd_system_runs_cg_and_matches_lu(cot_laplacian):
    S, star0 = cot_laplacian
    A = (sp.diags(star0) + 1e-3 * S).tocsr()  # implicit heat step: SPD
    b = np.random.default_rng(0).standard_normal(A.shape[0])
    x, solver = _solve(A, b)
    assert solver.methods_used == ["cg"] and 0 < solver.iterations[0] < 100
    exact = spla.spsolve(A.tocsc(), b)
    assert np.abs(x - exact).max() <= 1e-10 * np.abs(exact).max()


def test_symmetric_indefinite_system_runs_minres(cot_laplacian):
    S, star0 = cot_laplacian
    A = (S - 30.0 * sp.diags(star0)).tocsr()  # shifted into the spectrum: indefinite, positive diagonal
    eigenvalues = np.linalg.eigvalsh(A.toarray())
    assert eigenvalues.min() < 0 < eigenvalues.max()
    assert choose_method(A) == [("cg", "jacobi"), ("gmres", "ilu"), ("minres", "jacobi")]
    b = np.random.default_rng(0).standard_normal(A.shape[0])
    x, solver = _solve(A, b, method="minres")
    assert solver.methods_used == ["minres"]
    exact = spla.spsolve(A.tocsc(), b)
    assert np.abs(x - exact).max() <= 1e-9 * np.abs(exact).max()
    assert np.linalg.norm(b - A @ x) <= 1e-10 * np.linalg.norm(b) * np.linalg.cond(A.toarray())


def test_unsymmetric_system_runs_gmres_with_an_incomplete_lu(cot_laplacian):
    S, star0 = cot_laplacian
    n = S.shape[0]
    upwind = sp.diags(np.ones(n - 1), 1, shape=(n, n))  # an unsymmetric convection-like term
    A = (sp.diags(star0) + 1e-3 * S + 0.01 * upwind).tocsr()
    assert not is_symmetric(A)
    assert choose_method(A)[0] == ("gmres", "ilu")
    b = np.random.default_rng(0).standard_normal((n, 2))
    x, solver = _solve(A, b)
    assert solver.methods_used == ["gmres", "gmres"] and max(solver.iterations) < 20
    exact = spla.spsolve(A.tocsc(), b)
    assert np.abs(x - exact).max() <= 1e-10 * np.abs(exact).max()


def test_a_zero_diagonal_gets_gmres_and_bad_options_are_config_errors():
    saddle = sp.csr_matrix(np.array([[2.0, 1.0], [1.0, 0.0]]))
    assert choose_method(saddle)[0] == ("gmres", "ilu")
    x, _ = _solve(saddle, np.array([1.0, 2.0]))
    np.testing.assert_allclose(x, [2.0, -3.0], rtol=1e-12)
    with pytest.raises(ConfigError, match="solver.method"):
        make_solver("iterative", method="lsqr")
    with pytest.raises(ConfigError, match="solver.preconditioner=jacobi"):
        make_solver("iterative", method="minres", preconditioner="ilu")


def test_no_convergence_is_an_error_naming_the_method():
    A = sp.csr_matrix(sp.diags(np.linspace(1.0, 1e6, 400)))
    with pytest.raises(SolverError, match="cg: backward error .* after 2 iterations.*`solver=direct`"):
        make_solver("iterative", maxiter=1, refinements=1, method="cg", preconditioner="none").factorize(A).solve(
            np.ones(400))


@pytest.fixture(scope="module")
def coexact_torus():
    """d1 ⋆1⁻¹ d1ᵀ on a noisy torus (circumcentric: negative ⋆1 entries, so negative diagonal
    entries), the coexact system of ``app=hodge mesh=torus mesh.noise=0.05 operator=circumcentric``."""
    m = mesh("torus")
    rng = np.random.default_rng(0)
    V = m.vertices + 0.0075 * rng.standard_normal(m.vertices.shape)
    dec = DEC(SimplicialComplex(V, m.simplices, orient="fix"), star="circumcentric")
    d = sp.csr_matrix(dec.d(1))
    A = (d @ dec.star_inv(1) @ d.T).tocsr()
    assert A.diagonal().min() < 0 and is_symmetric(A)
    return A, d, d @ rng.standard_normal((d.shape[1], 4))


def test_symmetric_indefinite_shifted_singular_system_fails_over_to_gmres_early(coexact_torus):
    """The eigsh shift-invert of SingularSolve runs ~100 solves here: each must take a few GMRES
    iterations (MINRES + Jacobi took ~1,400 per solve; GMRES with the first, drop_tol 1e-5,
    incomplete LU ~40 until the tighter ILU), and the answer is direct's."""
    from decrun.core.solvers import SingularSolve

    A, d, B = coexact_torus
    assert choose_method(A)[0] == ("gmres", "ilu")
    solver = make_solver("iterative", ilu_drop_tol=1e-4)
    x = SingularSolve(A, solver, project=False).solve(B)
    exact = SingularSolve(A, make_solver("direct"), project=False).solve(B)
    assert set(solver.methods_used) == {"gmres"} and np.mean(solver.iterations) <= 5
    assert solver.ilu_drop_tols_used[:1] == [1e-4 / 1e3]  # tightened after a slow solve
    # α, β agree up to the kernel: compare δβ-like d1ᵀ x (the kernel of A is ker d1ᵀ)
    assert np.abs(d.T @ (x - exact)).max() <= 1e-8 * np.abs(d.T @ exact).max()
