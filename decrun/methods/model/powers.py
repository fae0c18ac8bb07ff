"""``a ** n`` for a fixed small integer ``n`` by repeated multiplication.

NumPy's float power calls the general ``pow`` for every exponent but a few (−1, 0, ½, 1, 2), so
``u**3`` costs several times a product per value. When the exponent of ``a ** b`` is fixed for
the run (:meth:`~decrun.methods.model.kind_inference.KindInference.is_static`: a number or a
constant) and its value is an integer with ``|n| ≤`` :data:`LARGEST`, an array base is raised by
products instead:

    a³ = (a·a)·a,   a⁴ = (a·a)·(a·a),   a⁵ = ((a·a)·(a·a))·a,   a⁻ⁿ = 1 / aⁿ

Each product is rounded once, so the value differs from ``pow``'s by a few units in the last
place (relative ≤ 4·2⁻⁵³ for 0 < n ≤ 5, one rounding more for 1/aⁿ); a zero base with a
negative exponent gives ±inf (the sign of ``a⁻ⁿ``'s limit, as ``np.power`` gives) and NaN and
±inf propagate as they do through ``np.power``. A number base (a Python or NumPy scalar), any
other exponent, and an exponent that changes during the run keep ``**``. The derivative rule
(:mod:`decrun.methods.model.jacobian`) is unchanged: only the evaluation of the value is.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

__all__ = ["LARGEST", "fixed_power", "integer_power"]

#: the largest |n| raised by products: a⁵ is three products, about a quarter of pow's time on
#: 12,000 values (the shallow-ice diffusivity's H^{n+2} with Glen's n = 3: conf/app/halfar.yaml)
LARGEST = 5


def integer_power(n: int) -> Callable[[np.ndarray], np.ndarray]:
    """``a ↦ aⁿ`` (elementwise, a float array of any shape) by products, for an integer
    ``0 < |n| ≤ LARGEST``; a new array, never ``a`` itself."""
    if not (0 < abs(n) <= LARGEST):
        raise ValueError(f"integer_power takes 0 < |n| <= {LARGEST}, got {n}")
    products: dict[int, Callable[[np.ndarray], np.ndarray]] = {
        1: np.positive, 2: lambda a: a * a, 3: lambda a: a * a * a, 4: lambda a: np.square(a * a),
        5: lambda a: np.square(a * a) * a}
    positive = products[abs(n)]
    if n > 0:
        return positive
    return lambda a: 1.0 / positive(a)


def _chosen(exponent) -> Callable[[object], object]:
    """The power by ``exponent``'s value: products for a small nonzero integer, else ``**``."""
    if np.ndim(exponent) == 0 and np.isfinite(exponent) and float(exponent).is_integer() \
            and 0 < abs(float(exponent)) <= LARGEST:
        products = integer_power(int(exponent))

        def power(base, exponent=exponent):
            if isinstance(base, np.ndarray) and base.dtype == np.float64:
                return products(base)
            return base ** exponent
        return power
    return lambda base: base ** exponent


def fixed_power(base: Callable[[dict], object], exponent: Callable[[dict], object]) -> Callable[[dict], object]:
    """The closure of ``base ** exponent`` for an exponent fixed for the run: its value is read
    at the first evaluation and the power chosen once (:func:`integer_power` for a small integer,
    ``**`` otherwise)."""
    chosen: list = []

    def power(env):
        if not chosen:
            chosen.append(_chosen(exponent(env)))
        return chosen[0](base(env))
    return power
