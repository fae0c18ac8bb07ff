"""Newton's Jacobian in a sparsity pattern made once (methods/model/jacobian_assembly.py): equal
to the general sparse assembly L + M ∂R/∂y (restricted to the free values) on reaction–diffusion
models with Dirichlet values condensed out, each Jacobian's values its own, and a model whose
derivative is a sparse matrix (Halfar's flux) still assembled in general."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from test_model_operators import dec_of

from decrun.core.solvers import solver_factory
from decrun.methods.model import FieldSpec, ModelSpec, compile_model
from decrun.methods.model.problem import ModelProblem

CASES = {
    "gray_scott": ({"u": FieldSpec(0, "1 - 0.3*x", dirichlet="1 - 0.3*x"), "v": FieldSpec(0, "0.25 + 0.1*y")},
                   ["dt(v) = 4e-4*laplacian(v) + u*v**2 - 0.1*v", "dt(u) = 8e-4*laplacian(u) - u*v**2 + 0.035*(1 - u)"]),
    "allen_cahn": ({"u": FieldSpec(0, "0.1*sin(7*x)*cos(5*y)")}, ["dt(u) = 1e-2*laplacian(u) + u - u**3"]),
    "coupled_only": ({"a": FieldSpec(0, "0.5 + 0.1*x"), "b": FieldSpec(0, "0.2 + 0.3*y", dirichlet=0.2)},
                     ["dt(a) = laplacian(a) + cosh(b)", "dt(b) = 0.5*laplacian(b) - a*b"]),
}


def _general(problem: ModelProblem, y: np.ndarray) -> sp.csr_matrix:
    rest = problem.rest_jacobian(problem.full(y), 0.0)
    full = problem.stiff_full + sp.block_diag([problem.evolution.mass[u] for u in problem.evolution.names]) @ rest
    return sp.csr_matrix(full)[problem.free][:, problem.free]


@pytest.mark.parametrize("name", list(CASES))
def test_the_pattern_assembly_equals_the_general_one(name):
    fields, equations = CASES[name]
    model = compile_model(ModelSpec(fields=fields, equations=equations, dt=0.1), dec_of("lattice"),
                          solver_factory("auto"))
    problem = ModelProblem(model)
    y = problem.free_values(model.initial_values) * (1 + 0.1 * np.random.default_rng(0).standard_normal(problem.size))
    J = problem.jacobian(y, 0.0)
    assert problem._pattern() is not None  # the pattern path was taken
    reference = _general(problem, y)
    assert abs(J - reference).max() <= 1e-13 * abs(reference).max()
    second = problem.jacobian(2 * y, 0.0)
    assert abs(J - reference).max() <= 1e-13 * abs(reference).max()  # the second did not change the first
    assert abs(second - _general(problem, 2 * y)).max() <= 1e-13 * abs(reference).max()


def test_a_sparse_derivative_takes_the_general_assembly():
    """Halfar's flux −δ(Γ ū^{n+2} |∇u|² d u): ∂R/∂u is a sparse matrix, J = L + M ∂R/∂u in general."""
    model = compile_model(ModelSpec(fields={"u": FieldSpec(0, "1 + 0.2*x*y")},
                                    equations=["dt(u) = -codifferential(average(cell_average(u)**5 * "
                                               "norm(sharp(d(u)))**2) * d(u))"], dt=0.1),
                          dec_of("lattice"), solver_factory("auto"))
    problem = ModelProblem(model)
    y = problem.free_values(model.initial_values)
    J = problem.jacobian(y, 0.0)
    assert not problem._assembly_made  # never built: the derivative was not a diagonal
    assert abs(J - _general(problem, y)).max() <= 1e-13 * abs(J).max()
