"""Small integer exponents (|n| ≤ 5) by products (decrun.methods.model.powers): the value equals NumPy's
power to round-off — negative bases, zeros under negative exponents (±inf), NaN and ±inf — and
the evaluator takes that path for ``u**3`` and for an integer-valued constant exponent, while any
other exponent keeps NumPy's power."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.methods.model.compiler import Compiler
from decrun.methods.model.kinds import NUMBER, primal
from decrun.methods.model.language import parse_expression
from decrun.methods.model.operators import Discrete
from decrun.methods.model.powers import LARGEST, integer_power
from decrun.runner.job.plugins import option

EXPONENTS = [n for n in range(-LARGEST, LARGEST + 1) if n != 0]
ULP = np.finfo(np.float64).eps


def bases() -> np.ndarray:
    """Negative and positive values over many magnitudes, with the special values."""
    generator = np.random.default_rng(47)
    values = generator.standard_normal(4000) * 10.0 ** generator.uniform(-30, 30, 4000)
    return np.concatenate([values, [0.0, -0.0, 1.0, -1.0, np.inf, -np.inf, np.nan, 2.0, -3.0]])


@pytest.mark.parametrize("n", EXPONENTS)
def test_integer_power_is_numpys_power_to_round_off(n):
    a = bases()
    with np.errstate(all="ignore"):
        fast, reference = integer_power(n)(a), np.power(a, float(n))
    finite = np.isfinite(reference) & (np.abs(reference) > np.finfo(np.float64).tiny)  # no overflow, no subnormals
    np.testing.assert_allclose(fast[finite], reference[finite], rtol=5 * ULP, atol=0)
    np.testing.assert_array_equal(np.signbit(fast[finite]), np.signbit(reference[finite]))
    special = ~finite
    np.testing.assert_array_equal(fast[special], reference[special])  # inf, nan, 0, ±0 where numpy gives them


def test_negative_exponent_of_zero_is_inf_as_in_numpy():
    a = np.array([0.0, -0.0, 2.0, -2.0])
    with np.errstate(divide="ignore"):
        np.testing.assert_array_equal(integer_power(-2)(a), [np.inf, np.inf, 0.25, 0.25])
        np.testing.assert_array_equal(integer_power(-2)(a), np.power(a, -2.0))
        np.testing.assert_array_equal(integer_power(-3)(a), np.power(a, -3.0))  # −0 → −inf
        assert np.signbit(integer_power(-3)(a)[1])


def test_the_largest_products_are_the_fifth_powers():
    """LARGEST = 5 (H^(n+2) of the shallow-ice diffusivity, Glen's n = 3): ±5 by products, ±6 refused."""
    assert LARGEST == 5 and 5 in EXPONENTS and -5 in EXPONENTS
    a = np.array([2.0, -3.0, 0.5])
    np.testing.assert_array_equal(integer_power(5)(a), [32.0, -243.0, 0.03125])  # exact in binary
    np.testing.assert_array_equal(integer_power(-5)(a), [1 / 32, -1 / 243, 32.0])
    for n in (6, -6):
        with pytest.raises(ValueError, match="0 < \\|n\\| <= 5"):
            integer_power(n)


def test_integer_power_returns_a_new_array():
    a = np.array([1.5, -2.0])
    assert integer_power(1)(a) is not a
    np.testing.assert_array_equal(integer_power(1)(a), a)


@lru_cache(maxsize=None)
def square() -> DEC:
    mesh = option("mesh", "grid", nx=6, ny=6).load()
    return DEC(SimplicialComplex(mesh.vertices, mesh.simplices))


def evaluate(expression: str, u: np.ndarray, constants: dict[str, float] | None = None) -> np.ndarray:
    constants = constants or {}
    compiler = Compiler(Discrete(square()), {"u": primal(0), **{name: NUMBER for name in constants}}, varying={"u"})
    compiler.static_env = {"pi": np.pi, **constants}
    closure = compiler.compile(parse_expression(expression, "test"), "test")
    return closure({"u": u, "t": 0.0, **compiler.static_env})


@pytest.mark.parametrize("expression, constants, n", [("u**3", {}, 3), ("u**4", {}, 4), ("u**(-2)", {}, -2),
                                                      ("u**c", {"c": 3.0}, 3), ("u**(c + 1)", {"c": -4.0}, -3),
                                                      ("u**(n + 2)", {"n": 3.0}, 5), ("u**(-5)", {}, -5)])
def test_the_evaluator_raises_integer_exponents_by_products(expression, constants, n):
    u = bases()[:4000]
    with np.errstate(all="ignore"):
        value = evaluate(expression, u, constants)
        products = {2: u * u, 3: u * u * u, 4: (u * u) * (u * u),  # the documented products
                    5: ((u * u) * (u * u)) * u}[abs(n)]
        if n < 0:
            products = 1.0 / products
        reference = np.power(u, float(n))
    np.testing.assert_array_equal(value, products)  # the products, bit for bit
    assert np.any(value != reference)  # … which pow does not give everywhere (so the path is seen)
    finite = np.isfinite(reference) & (np.abs(reference) > np.finfo(np.float64).tiny)
    np.testing.assert_allclose(value[finite], reference[finite], rtol=5 * ULP, atol=0)


@pytest.mark.parametrize("expression, constants, exponent", [("u**2.5", {}, 2.5), ("u**c", {"c": 6.0}, 6.0),
                                                             ("u**c", {"c": 0.0}, 0.0), ("u**t", {}, 0.0)])
def test_other_exponents_keep_numpys_power(expression, constants, exponent):
    u = np.abs(bases()[:4000]) + 0.5
    with np.errstate(all="ignore"):
        np.testing.assert_array_equal(evaluate(expression, u, constants), u ** exponent)
