"""The derivative rules that close the gaps of the derivative pass (issue 47, item 2): lie of a
1-form (in the form and in the velocity, a vector field or a 1-form) and ♭ under
``operator=intrinsic_delaunay`` (methods/model/vector_derivatives.py) — each exact Jacobian
against central differences of the evaluator itself on a random state, to 1e-6 relative, on a
planar lattice, a closed sphere (3-D vectors) and, for the operators that apply there,
tetrahedra; and the matrix of ω ↦ L_X ω for a fixed X equals the evaluation."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from test_model_operators import dec_of, env_of

from decrun.methods.model import discrete
from decrun.methods.model.compiler import Compiler
from decrun.methods.model.jacobian import derivative, pattern
from decrun.methods.model.kinds import primal
from decrun.methods.model.language import ModelError, parse_expression
from decrun.methods.model.operators import Discrete
from decrun.methods.model.vector_derivatives import lie_1_matrix

#: w a primal 1-form unknown, u a primal 0-form unknown, v a fixed 0-form
ONE_FORM_EXPRESSIONS = [
    "lie(w, w)",  # a 1-form advected by its own velocity (its ♯)
    "lie(sharp(w), w) + lie(sharp(d(v)), w)",  # a vector velocity that reads w, and a fixed one
    "lie(d(v), w*w) - lie(w, d(v))",  # through a product in the form; in the velocity only
    "codifferential(lie(flat(normalize(sharp(w))), w))",  # through ♭, normalize, then δ
    "lie(sharp(d(x*y + z)), w) - lie(d(x), w*w)",  # a static velocity: the matrix of ω ↦ L_X ω, made once
]


def _compiler(dec, kinds):
    compiler = Compiler(Discrete(dec), kinds, {}, set(kinds))
    compiler.static_env = env_of(dec.K, {})
    return compiler


def _check(dec, text, unknown, seed=0):
    """∂text/∂unknown against (F(y + εw) − F(y − εw)) / 2ε; ``unknown`` is w (a 1-form) or u (a
    0-form); the other fields fixed at random values."""
    K = dec.K
    kinds = {"w": primal(1), "u": primal(0), "v": primal(0)}
    compiler = _compiler(dec, kinds)
    rng = np.random.default_rng(seed)
    values = {name: 0.5 + 0.3 * rng.random(kind.size(K)) for name, kind in kinds.items()}
    values["w"] = rng.standard_normal(K.num_simplices(1))

    def env(y):
        return env_of(K, {**values, unknown: y})
    tree = parse_expression(text, "test")
    F = compiler.compile(tree, "test")
    y = values[unknown]
    J = derivative(compiler, tree, unknown, "test")(env(y))
    value = np.asarray(F(env(y)))
    assert sp.issparse(J) and J.shape == (value.size, y.size)
    direction = rng.standard_normal(y.size)
    eps = 1e-6 * np.abs(y).max()
    numeric = (F(env(y + eps * direction)) - F(env(y - eps * direction))) / (2 * eps)
    assert np.abs(numeric).max() > 0
    assert np.abs(J @ direction - numeric).max() <= 1e-6 * np.abs(numeric).max()
    structure = pattern(compiler, tree, unknown, "test")  # the sparsity bdf/radau take holds J's
    assert abs(J).multiply(structure).sum() == pytest.approx(abs(J).sum(), rel=1e-12)


@pytest.mark.parametrize("text", ONE_FORM_EXPRESSIONS)
def test_lie_of_a_1_form_equals_central_differences_on_a_lattice(text):
    _check(dec_of("lattice"), text, "w")


@pytest.mark.parametrize("text", ONE_FORM_EXPRESSIONS)
def test_lie_of_a_1_form_equals_central_differences_on_a_sphere(text):
    """Vectors in R³ on a closed curved surface: the normal N × X part of Cartan's formula."""
    _check(dec_of("sphere"), text, "w", seed=1)


@pytest.mark.parametrize("text", ["lie(d(u), d(u**2))", "codifferential(lie(sharp(d(u)), average(u)*d(v)))"])
def test_lie_of_a_1_form_in_a_0_form_unknown(text):
    """The 1-form d(u) as velocity and as advected form, ∂/∂u through d: both arguments' rules."""
    _check(dec_of("lattice"), text, "u", seed=2)
    _check(dec_of("sphere"), text, "u", seed=3)


def test_lie_on_tetrahedra():
    """On tetrahedra lie takes 0-forms only (its typing rule); its rules in both arguments there."""
    _check(dec_of("tets"), "lie(sharp(d(u)), u*u) + lie(d(v), u)", "u", seed=4)


def test_the_matrix_of_lie_of_a_1_form_is_the_evaluation():
    """ω ↦ L_X ω for a fixed X: the matrix (what implicit steppers take for lie(X, w) with a fixed
    X) applied to ω equals :func:`discrete.lie_1` to round-off, and L_X d f = d L_X f (d commutes
    with the Lie derivative, exactly as lie_1 is built)."""
    for name in ("lattice", "sphere"):
        K = dec_of(name).K
        rng = np.random.default_rng(5)
        X = rng.standard_normal((K.num_simplices(2), K.embedding_dim))
        omega = rng.standard_normal(K.num_simplices(1))
        expected = discrete.lie_1(K, X, omega)
        assert np.abs(lie_1_matrix(K, X) @ omega - expected).max() <= 1e-12 * np.abs(expected).max()
        f = rng.standard_normal(K.num_simplices(0))
        d0 = K.incidence(1)
        assert np.abs(lie_1_matrix(K, X) @ (d0 @ f) - d0 @ discrete.lie_0(K, X, f)).max() <= 1e-11 * np.abs(f).max()


def test_the_intrinsic_flat_rule_equals_central_differences():
    """♭ of the intrinsic triangulation (``operator=intrinsic_delaunay``) is linear: its matrix."""
    dec = dec_of("sphere", "intrinsic_delaunay")
    _check(dec, "codifferential(flat(sharp(d(u**2))))", "u", seed=6)
    _check(dec, "codifferential(flat(normalize(sharp(d(u))))) * u", "u", seed=7)


def test_a_number_computed_from_the_unknown_stays_refused_in_one_line():
    """inner/integral/mean/norm of a form couple every value (a dense Jacobian row): refused."""
    compiler = _compiler(dec_of("lattice"), {"w": primal(1), "u": primal(0), "v": primal(0)})
    for text in ("w * norm(w)", "lie(w, w) * mean(w)"):
        with pytest.raises(ModelError, match="couples all its values") as caught:
            derivative(compiler, parse_expression(text, "app.equations[0]"), "w", "app.equations[0]")
        assert "\n" not in str(caught.value)
