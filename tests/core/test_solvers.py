"""Linear solvers behind one interface (decrun.core.solvers)."""

from __future__ import annotations

import builtins
import sys

import numpy as np
import pytest
import scipy.sparse as sp

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.core.plugins import builtin_names
from decrun.core.solvers import Solver, make_solver
from decrun.errors import ConfigError, SolverError

from meshes_for_tests import mesh

SOLVERS = builtin_names("decrun.core.solvers", Solver)

OPTIONAL = {"amg": "pyamg", "pardiso": "pypardiso"}  # extras decrun[amg], decrun[pardiso]


def _installed(name):
    try:
        __import__(OPTIONAL[name]) if name in OPTIONAL else None
        return True
    except ImportError:
        return False


ALL = [pytest.param(name, marks=pytest.mark.skipif(not _installed(name), reason=f"{OPTIONAL.get(name)} not installed"))
       for name in sorted(SOLVERS)]


@pytest.fixture(scope="module")
def heat_matrix():
    """The implicit smoothing matrix ⋆0 + dt d0ᵀ⋆1 d0 of an icosphere: sparse SPD."""
    m = mesh("icosphere", subdiv=3)
    dec = DEC(SimplicialComplex(m.vertices, m.faces))
    return (sp.diags(dec.star_diagonal(0)) + 0.01 * dec.laplacian_symmetric(0)).tocsr()


@pytest.mark.parametrize("name", ALL)
def test_every_solver_solves_an_spd_system_with_many_right_hand_sides(name, heat_matrix):
    rng = np.random.default_rng(0)
    x_true = rng.standard_normal((heat_matrix.shape[0], 3))
    b = heat_matrix @ x_true
    solver = make_solver(name)
    solver.factorize(heat_matrix)
    x = solver.solve(b)
    assert x.shape == b.shape
    np.testing.assert_allclose(x, x_true, rtol=1e-6, atol=1e-6)
    x0 = solver.solve(b[:, 0])
    assert x0.shape == (heat_matrix.shape[0],)
    np.testing.assert_allclose(x0, x_true[:, 0], rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("name", ALL)
def test_factorize_once_for_the_same_matrix(name, heat_matrix):
    solver = make_solver(name)
    solver.factorize(heat_matrix)
    solver.factorize(heat_matrix.copy())  # same values and pattern: cached
    assert solver.factorizations == 1
    changed = heat_matrix + sp.identity(heat_matrix.shape[0], format="csr")
    solver.factorize(changed)
    assert solver.factorizations == 2
    b = np.ones(heat_matrix.shape[0])
    np.testing.assert_allclose(changed @ solver.solve(b), b, rtol=1e-6, atol=1e-8)


def test_cg_tolerance_is_honoured_and_iterations_recorded(heat_matrix):
    b = np.random.default_rng(1).standard_normal(heat_matrix.shape[0])
    loose, tight = make_solver("cg", tol=1e-4), make_solver("cg", tol=1e-12)
    rel = []
    for solver in (loose, tight):
        x = solver.factorize(heat_matrix).solve(b)
        rel.append(np.linalg.norm(heat_matrix @ x - b) / np.linalg.norm(b))
    assert rel[0] <= 1e-4 and rel[1] <= 1e-12
    assert tight.iterations[0] > loose.iterations[0]


def test_cg_without_convergence_raises(heat_matrix):
    solver = make_solver("cg", tol=1e-14, maxiter=2)
    solver.factorize(heat_matrix)
    with pytest.raises(SolverError, match="no convergence"):
        solver.solve(np.ones(heat_matrix.shape[0]))


def test_direct_singular_matrix_raises():
    singular = sp.csr_matrix(np.array([[1.0, 1.0], [1.0, 1.0]]))
    with pytest.raises(SolverError):
        make_solver("direct").factorize(singular).solve(np.ones(2))


def test_solve_before_factorize_and_bad_shapes():
    for name in filter(_installed, sorted(SOLVERS)):
        with pytest.raises(SolverError, match="before factorize"):
            make_solver(name).solve(np.ones(3))
    with pytest.raises(SolverError, match="square"):
        make_solver("cg").factorize(sp.csr_matrix(np.ones((2, 3))))


def test_unknown_solver_and_bad_options():
    with pytest.raises(ConfigError, match="solver=gauss: unknown Solver; choose one of solver=amg \\| solver=auto \\| solver=cg \\| solver=cholmod \\| solver=direct \\| solver=iterative \\| solver=pardiso"):
        make_solver("gauss")
    with pytest.raises(ConfigError, match="solver=cg"):
        make_solver("cg", colour="blue")
    with pytest.raises(ConfigError, match="solver.tol"):
        make_solver("cg", tol=-1.0)
    with pytest.raises(ConfigError, match="solver.preconditioner"):
        make_solver("cg", preconditioner="ilu")


@pytest.mark.parametrize("name, module", [("amg", "pyamg"), ("pardiso", "pypardiso")])
def test_missing_optional_package_is_a_clear_solver_error(name, module, monkeypatch):
    real_import = builtins.__import__

    def fake_import(mod, *args, **kwargs):
        if mod == module or mod.startswith(module + "."):
            raise ImportError(f"No module named {module!r}")
        return real_import(mod, *args, **kwargs)

    monkeypatch.delitem(sys.modules, module, raising=False)
    monkeypatch.setattr(builtins, "__import__", fake_import)
    with pytest.raises(SolverError, match=f"pip install -e '.\\[{name}\\]'"):
        make_solver(name)


def test_auto_is_the_default_and_uses_cholesky_for_spd_and_lu_for_the_rest(heat_matrix):
    """solver=auto: CHOLMOD where A is symmetric positive definite, SuperLU otherwise — the
    answer agrees with SuperLU to round-off either way."""
    from decrun.core.solvers import solver_factory

    assert make_solver().name == "auto" and solver_factory()().name == "auto"
    rng = np.random.default_rng(2)
    b = rng.standard_normal(heat_matrix.shape[0])
    unsymmetric = (heat_matrix + 1e-3 * sp.triu(heat_matrix, 1)).tocsr()
    indefinite = (heat_matrix - 2 * heat_matrix.diagonal().mean() * sp.identity(heat_matrix.shape[0])).tocsr()
    indefinite = (indefinite + sp.identity(heat_matrix.shape[0]) * 3 * abs(indefinite.diagonal().min())).tocsr()
    indefinite.setdiag(np.where(np.arange(heat_matrix.shape[0]) == 0, -1.0, indefinite.diagonal()))
    for matrix, method in ((heat_matrix, "cholmod"), (unsymmetric, "superlu"), (indefinite, "superlu")):
        solver = make_solver("auto").factorize(matrix)
        assert solver.method == method
        expected = make_solver("direct").factorize(matrix).solve(b)
        np.testing.assert_allclose(solver.solve(b), expected, rtol=1e-9, atol=1e-12)


def test_indefinite_symmetric_matrix_falls_back_without_cholmod_noise(capfd):
    """A symmetric matrix with a positive diagonal that is not definite: CHOLMOD's own warning
    (printed by the C library) does not reach the terminal; auto answers with SuperLU."""
    A = sp.csr_matrix(np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 3.0]]))
    solver = make_solver("auto").factorize(A)
    np.testing.assert_allclose(A @ solver.solve(np.ones(3)), np.ones(3))
    assert solver.method == "superlu"
    captured = capfd.readouterr()
    assert "CHOLMOD" not in captured.out + captured.err


def test_cholmod_refuses_what_it_cannot_factorize_and_names_direct():
    with pytest.raises(SolverError, match="not symmetric.*use solver=direct"):
        make_solver("cholmod").factorize(sp.csr_matrix(np.array([[4.0, 1.0], [0.0, 3.0]])))
    with pytest.raises(SolverError, match="not positive definite.*use solver=direct"):
        make_solver("cholmod").factorize(sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 1.0]])))


def test_asymmetry_is_max_of_a_minus_its_transpose_over_max_a(heat_matrix):
    """cholmod.asymmetry = max |A − Aᵀ| / max |A| exactly, whichever way it is computed: the
    entry-by-entry path (canonical CSR, Aᵀ with A's pattern) and the A − Aᵀ path (another
    pattern, unsorted indices) — checked against the dense definition."""
    from decrun.core.solvers.cholmod import asymmetry

    def dense(A):
        D = A.toarray()
        return float(np.abs(D - D.T).max() / np.abs(D).max())

    A = heat_matrix.copy()
    A.sort_indices()
    assert asymmetry(A) == dense(A) == 0.0
    skewed = A.copy()  # same pattern, one value pair off by 1e-9 of the largest entry
    row, column = 3, int(skewed.indices[skewed.indptr[3]])
    row, column = (row, column) if row != column else (3, int(skewed.indices[skewed.indptr[3] + 1]))
    skewed[row, column] = skewed[row, column] + 1e-9 * np.abs(A.data).max()
    assert skewed.has_canonical_format and asymmetry(skewed) == pytest.approx(dense(skewed), rel=1e-12)
    assert asymmetry(skewed) == pytest.approx(1e-9, rel=1e-6)
    lopsided = (A + 1e-3 * sp.triu(A, 1)).tocsr()  # a value pair off
    pattern = (A + sp.csr_matrix(([0.5], ([0], [A.shape[0] - 1])), shape=A.shape)).tocsr()  # one entry without its pair
    unsorted = sp.csr_matrix((pattern.data[::-1].copy(), pattern.indices[::-1].copy(),
                              (pattern.nnz - pattern.indptr[::-1]).copy()), shape=A.shape)  # rows and entries reversed
    for matrix in (lopsided, pattern, unsorted):
        assert asymmetry(matrix) == pytest.approx(dense(matrix), rel=1e-12)
    assert not unsorted.has_sorted_indices and asymmetry(unsorted) > 0


def test_gmres_stops_at_the_backward_error_on_the_galerkin_saddle_point():
    """The Galerkin coexact solve ([M dᵀ; d −εI], refined against ε = 0) with solver=iterative:
    GMRES + ILU reaches the backward error in a few iterations per solve, and its second
    refinement round — a shifted singular system whose attainable residual is ~ u‖A‖‖x‖ —
    stops there too instead of running every restart cycle to maxiter (4,755 iterations
    before). The coexact part matches solver=direct to 1e-10."""
    from decrun.core.hodge import _GalerkinCoexact

    from meshes_for_tests import remeshed_torus

    dec = DEC(SimplicialComplex(*remeshed_torus(0.12)), star="whitney")
    omega = np.random.default_rng(1).standard_normal((dec.K.num_simplices(1), 2))
    iterative = make_solver("iterative")
    coexact, _ = _GalerkinCoexact(dec, 1, iterative).solve(omega)
    reference, _ = _GalerkinCoexact(dec, 1, make_solver("direct")).solve(omega)
    assert set(iterative.methods_used) == {"gmres"}
    assert max(iterative.iterations) < 100, iterative.iterations
    assert np.abs(coexact - reference).max() <= 1e-10 * np.abs(reference).max()


def test_amg_accepts_a_backward_stable_solve_of_a_shifted_singular_system():
    """A refinement round of SingularSolve hands the solver A + εI (A a Laplacian, kernel the
    constants) and a residual with a constant component: x ~ that component / ε, and no
    iteration reaches a residual relative to ‖b‖ (this raised after 500 iterations, the
    full-suite failure of the hodge row with amg). Accepted now by its backward error, and
    refused, as before, when even that is not reached."""
    pytest.importorskip("pyamg")
    import scipy.sparse.linalg as spla

    from decrun.core.primitives import grid_triangles

    laplacian = DEC(SimplicialComplex(*grid_triangles(20))).laplacian_symmetric(0).tocsr()
    n = laplacian.shape[0]
    shifted = (laplacian + sp.identity(n) * 1e-10 * abs(laplacian.diagonal()).mean()).tocsc()
    b = laplacian @ np.random.default_rng(0).standard_normal(n) * 1e-11 + 1e-12 * np.ones(n)
    solver = make_solver("amg")
    solver.factorize(shifted)
    x = solver.solve(b)
    norm = np.sqrt(spla.norm(shifted, 1) * spla.norm(shifted, np.inf))
    assert np.linalg.norm(b - shifted @ x) / (norm * np.linalg.norm(x) + np.linalg.norm(b)) <= 1e-10
    assert np.linalg.norm(x) > 1e6 * np.linalg.norm(b)  # the kernel component, amplified by 1/ε
    strict = make_solver("amg", tol=1e-16, maxiter=3)
    strict.factorize(shifted)
    with pytest.raises(SolverError, match="no convergence"):
        strict.solve(b)


@pytest.mark.parametrize("name", ALL)
def test_every_solver_solves_an_empty_system(name):
    """A 0×0 system (every unknown fixed by the border, e.g. the parametrization of one
    triangle) has the empty solution; CHOLMOD and pyamg refuse a 0×0 matrix themselves."""
    solver = make_solver(name).factorize(sp.csr_matrix((0, 0)))
    for b in (np.zeros(0), np.zeros((0, 2))):
        x = solver.solve(b)
        assert x.shape == b.shape and x.dtype == np.float64
    with pytest.raises(SolverError, match="right-hand side has 1 rows"):
        solver.solve(np.ones(1))
    solver.factorize(sp.identity(2, format="csr"))  # the same solver takes a real system afterwards
    np.testing.assert_allclose(solver.solve(np.array([1.0, 2.0])), [1.0, 2.0], atol=1e-8)


BACKENDS = [pytest.param(backend, marks=pytest.mark.skipif(
    backend not in __import__("decrun.core.solvers.cholmod", fromlist=["x"]).installed_backends(),
    reason=f"{backend} not installed")) for backend in ("sksparse", "cholespy")]


@pytest.mark.parametrize("backend", BACKENDS)
def test_each_cholmod_binding_solves_to_round_off_and_refuses_the_indefinite(backend, heat_matrix):
    """scikit-sparse (supernodal) and cholespy (simplicial) factorize the same SPD matrix to the
    same answer as SuperLU; both refuse an indefinite one naming solver=direct."""
    rng = np.random.default_rng(5)
    b = rng.standard_normal((heat_matrix.shape[0], 2))
    solver = make_solver("cholmod", backend=backend).factorize(heat_matrix)
    expected = make_solver("direct").factorize(heat_matrix).solve(b)
    np.testing.assert_allclose(solver.solve(b), expected, rtol=1e-10, atol=1e-13)
    with pytest.raises(SolverError, match="not positive definite.*use solver=direct"):
        make_solver("cholmod", backend=backend).factorize(sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 1.0]])))


def test_auto_binding_is_the_fastest_installed(monkeypatch):
    from decrun.core.solvers import cholmod

    installed = cholmod.installed_backends()
    assert list(installed) == [b for b in cholmod.PREFERENCE if b in installed]
    monkeypatch.setattr(cholmod, "installed_backends", lambda: (cholmod.CholmodBackend.cholespy,))
    assert cholmod._backend("auto") == "cholespy"
    with pytest.raises(ConfigError, match=r"solver.backend=sksparse: sksparse is not installed .*libsuitesparse-dev"
                                          r".*; use solver.backend=cholespy$"):
        make_solver("cholmod", backend="sksparse")
    with pytest.raises(ConfigError, match="solver.backend"):
        make_solver("cholmod", backend="umfpack")


def test_missing_binding_hint_is_an_override_that_runs(tmp_path):
    """Without scikit-sparse, solver.backend=sksparse is one line whose hint runs."""
    import subprocess

    from cli_processes import decrun, env

    args = ["app=heat", "mesh.subdiv=1", "app.t_end=0.002", "solver=cholmod", "progress=false", "figures=false"]
    code = ("import sys; sys.modules['sksparse'] = None; sys.modules['sksparse.cholmod'] = None; "
            "from decrun.__main__ import console_main; sys.argv = ['decrun'] + sys.argv[1:]; console_main()")
    done = subprocess.run([sys.executable, "-c", code, *args, "solver.backend=sksparse",
                           f"hydra.run.dir={tmp_path / 'a'}"], cwd=tmp_path, env=env(), capture_output=True, text=True)
    assert done.returncode == 1 and done.stderr.count("\n") == 1, done.stderr
    hint = done.stderr.strip().rpartition("use ")[2]
    assert hint == "solver.backend=cholespy"
    done = decrun(*args, hint, f"hydra.run.dir={tmp_path / 'b'}", cwd=tmp_path)
    assert done.returncode == 0, done.stderr


def _hodge_systems():
    """The two singular Poisson systems of the Hodge decomposition of 1-forms on a closed,
    perturbed icosphere with the lumped Whitney stars (app=hodge's with solver=amg): the
    0-form Laplacian d0ᵀ ⋆1 d0 (kernel: the constants) and d1 ⋆1⁻¹ d1ᵀ on 2-forms (kernel:
    the constant 2-form of the oriented closed surface)."""
    from decrun.core.stars.whitney import Whitney

    m = mesh("icosphere", subdiv=2, noise=0.05)
    dec = DEC(SimplicialComplex(m.vertices, m.faces), star=Whitney(lumped=True))
    d0, d1 = dec.d(0), dec.d(1)
    star1 = dec.star_diagonal(1)
    return [(d0.T @ sp.diags(star1) @ d0).tocsr(), (d1 @ sp.diags(1.0 / star1) @ d1.T).tocsr()]


@pytest.mark.parametrize("setup_seed", range(6))
def test_a_singular_solve_with_amg_survives_a_constant_part_and_any_hierarchy(setup_seed, monkeypatch):
    """amg on the Hodge decomposition's singular systems of a closed surface: a right-hand
    side with a constant part of 1e3 (beside a consistent part of size ~1), several columns,
    the hierarchy built from several random states (pyamg's setup draws from numpy's global
    state). The constant part is removed from b and from every refinement residual (it is not
    in im A), and the solution is the direct solver's, W-orthogonal to the constants. Without
    the projection some of these hierarchies did not converge (relative residual 8.47 in a
    full-suite run)."""
    pytest.importorskip("pyamg")
    from decrun.core.solvers import SingularSolve, amg, constant_kernel

    monkeypatch.setattr(amg, "SETUP_SEED", setup_seed, raising=False)
    np.random.seed(setup_seed)  # where pyamg's setup draws unless the solver sets its own seed
    rng = np.random.default_rng(setup_seed)
    for A in _hodge_systems():
        n = A.shape[0]
        (ones,) = constant_kernel(A).toarray().T
        assert np.array_equal(ones, np.ones(n)) and np.abs(A @ ones).max() < 1e-12 * abs(A).max()
        consistent = A @ rng.standard_normal((n, 4))
        b = consistent + 1e3 * rng.standard_normal(4)  # a constant of ~1e3 in each column
        answer = SingularSolve(A, make_solver("direct"), project=False).solve(b)
        singular = SingularSolve(A, make_solver("amg"), project=False)
        x = singular.solve(b)
        np.testing.assert_allclose(A @ x, consistent, atol=1e-8 * np.abs(consistent).max())
        np.testing.assert_allclose(x, answer, atol=1e-8 * np.abs(answer).max())
        assert np.abs(ones @ x).max() < 1e-9 * np.abs(x).max()  # W = I: orthogonal to the constants
        part = np.linalg.norm(b - b.mean(axis=0), axis=0)
        np.testing.assert_allclose(singular.kernel_part, np.sqrt(1 - (part / np.linalg.norm(b, axis=0)) ** 2),
                                   rtol=1e-9)


def test_the_amg_hierarchy_is_the_same_whatever_the_random_state_and_leaves_it_alone():
    """The same matrix gives the same solution bit for bit after any use of numpy's global
    random state, and building the hierarchy does not move that state."""
    pytest.importorskip("pyamg")
    A = _hodge_systems()[0]
    b = A @ np.random.default_rng(1).standard_normal(A.shape[0])
    shifted = (A + sp.identity(A.shape[0]) * 1e-3 * A.diagonal().mean()).tocsc()
    answers = []
    for seed in (0, 1, 2):
        np.random.seed(seed)
        expected = np.random.rand()
        np.random.seed(seed)
        solver = make_solver("amg")
        solver.factorize(shifted)
        assert np.random.rand() == expected  # the caller's random state, as it was
        answers.append(solver.solve(b))
    assert all(np.array_equal(answers[0], other) for other in answers[1:])


def test_the_constant_kernel_of_many_pieces_is_sparse_and_projected_per_piece():
    """A Laplacian of 3000 separate paths has 3000 constants in its kernel: ``constant_kernel``
    is a sparse indicator (one nonzero a row, not n × 3000 dense), and ``SingularSolve`` removes
    each piece's mean from b and from x."""
    from decrun.core.solvers import SingularSolve, constant_kernel

    pieces, length = 3000, 4
    path = sp.diags([-np.ones(length - 1), np.r_[1.0, 2 * np.ones(length - 2), 1.0], -np.ones(length - 1)],
                    [-1, 0, 1])
    A = sp.block_diag([path] * pieces, format="csr")
    n = A.shape[0]
    Z = constant_kernel(A)
    assert sp.issparse(Z) and Z.shape == (n, pieces) and Z.nnz == n
    np.testing.assert_array_equal(np.asarray(Z.sum(axis=0)).ravel(), np.full(pieces, length))
    rng = np.random.default_rng(1)
    consistent = A @ rng.standard_normal(n)
    b = consistent + np.repeat(rng.standard_normal(pieces), length)  # a constant on each piece
    solve = SingularSolve(A, make_solver("direct"), project=False)
    x = solve.solve(b)
    np.testing.assert_allclose(A @ x, consistent, atol=1e-9)
    np.testing.assert_allclose(x.reshape(pieces, length).mean(axis=1), 0.0, atol=1e-12)  # W = I
    assert solve.kernel_part > 0.1
