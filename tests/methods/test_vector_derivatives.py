"""The derivative rules of ♯, |·|, normalize, ♭, interior, ∧, flux_field and lie
(methods/model/vector_derivatives.py):
each exact Jacobian against central differences of the evaluator itself on a random state, to
1e-6 relative — on a planar lattice, a closed sphere (3-D vectors) and under the intrinsic ♯."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from test_model_operators import dec_of, env_of

from decrun.methods.model.compiler import Compiler
from decrun.methods.model.jacobian import derivative
from decrun.methods.model.kinds import primal
from decrun.methods.model.language import parse_expression
from decrun.methods.model.operators import Discrete

EXPRESSIONS = [
    "codifferential(average(cell_average(u)**5 * norm(sharp(d(u)))**2) * d(u))",  # Halfar's flux, n = 3
    "norm(sharp(d(u))) * cell_average(v)",
    "codifferential(flat(sharp(d(u**2))))",
    "codifferential(flat(normalize(sharp(d(u)))))",
    "interior(sharp(d(u)), d(v)) + interior(d(v), d(u**2))",
    "interior(d(u), d(u))",
    "star(wedge(u, d(v)) ^ d(u))",
    "star(d(u**2) ^ d(v)) + star(d(v) ^ d(u))",
    "wedge(u, d(u)) + wedge(d(v), u*u)",
    "codifferential(flat(flux_field(d(u**2))))",
    "lie(sharp(d(u)), u) + lie(d(v), u*u) + lie(d(u**2), v)",
]


def _check(dec, text, seed=0):
    K = dec.K
    compiler = Compiler(Discrete(dec), {"u": primal(0), "v": primal(0)}, {}, {"u", "v"})
    compiler.static_env = env_of(K, {})
    rng = np.random.default_rng(seed)
    u = 0.5 + 0.3 * rng.random(K.num_simplices(0))
    v = 0.5 + 0.3 * rng.random(K.num_simplices(0))

    def env(u):
        return env_of(K, {"u": u, "v": v})
    tree = parse_expression(text, "test")
    F = compiler.compile(tree, "test")
    J = derivative(compiler, tree, "u", "test")(env(u))
    value = np.asarray(F(env(u)))
    assert sp.issparse(J) and J.shape == (value.size, u.size)
    w = rng.standard_normal(u.size)
    eps = 1e-6 * np.abs(u).max()
    numeric = (F(env(u + eps * w)) - F(env(u - eps * w))) / (2 * eps)
    assert np.abs(numeric).max() > 0
    assert np.abs(J @ w - numeric).max() <= 1e-6 * np.abs(numeric).max()


@pytest.mark.parametrize("text", EXPRESSIONS)
def test_each_rule_equals_central_differences_on_a_lattice(text):
    _check(dec_of("lattice"), text)


@pytest.mark.parametrize("text", [EXPRESSIONS[0], EXPRESSIONS[3], EXPRESSIONS[4], EXPRESSIONS[6]])
def test_each_rule_equals_central_differences_on_a_sphere(text):
    """Vectors in R³ on a closed curved surface."""
    _check(dec_of("sphere"), text, seed=1)


def test_the_rules_on_tetrahedra():
    """flux_field of a 2-form (a negatively oriented tetrahedron's sign included), ♯ and ∧ in 3-D."""
    _check(dec_of("tets"), "norm(flux_field(d(u) ^ d(v))) + norm(sharp(d(u**2)))**2", seed=3)


def test_the_intrinsic_sharp_rule_equals_central_differences():
    _check(dec_of("sphere", "intrinsic_delaunay"), "codifferential(average(norm(sharp(d(u)))**2) * d(u))", seed=2)
