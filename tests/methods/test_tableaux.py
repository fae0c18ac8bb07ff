"""The Runge–Kutta tableaux (decrun/methods/model/tableaux.py) satisfy their order conditions, read
off the data: bᵀΦ(τ) = 1/γ(τ) for every rooted tree τ up to the method's order, and not for all
trees one order higher (the order is exact); for the IMEX pairs the same over trees whose nodes are
coloured explicit/implicit (the coupling conditions). Gauss and Radau IIA meet the collocation
simplifying conditions B(p), C(q), D(r); Radau IIA is L-stable (R(z) → 0 as z → −∞), Gauss–Legendre
is symplectic (b_i a_ij + b_j a_ji − b_i b_j = 0) with |R(iy)| = 1."""

from __future__ import annotations

from functools import lru_cache
from itertools import combinations_with_replacement

import numpy as np
import pytest

from decrun.methods.model.tableaux import (
    ARK_IMEX,
    ARS232,
    GAUSS_LEGENDRE,
    IMPLICIT_MIDPOINT,
    RADAU_IIA,
    TABLEAUX,
    Tableau,
)

SINGLE = [tableau for tableau in TABLEAUX.values() if not tableau.additive]
PAIRS = [tableau for tableau in TABLEAUX.values() if tableau.additive]


@lru_cache(maxsize=None)
def trees(order: int, colours: tuple[str, ...] = ("",)) -> tuple:
    """Every rooted tree with ``order`` nodes, each node coloured from ``colours``: (colour, children)
    with the children a sorted tuple of trees (so each tree is listed once)."""
    if order == 1:
        return tuple((colour, ()) for colour in colours)
    found = set()
    for colour in colours:
        for sizes in _partitions(order - 1):
            for children in _forests(sizes, colours):
                found.add((colour, children))
    return tuple(sorted(found))


def _partitions(total: int, largest: int | None = None):
    """The partitions of ``total`` into non-increasing parts."""
    largest = total if largest is None else largest
    if total == 0:
        yield ()
        return
    for part in range(min(total, largest), 0, -1):
        for rest in _partitions(total - part, part):
            yield (part, *rest)


def _forests(sizes: tuple[int, ...], colours: tuple[str, ...]):
    """Sorted tuples of trees with the given sizes."""
    groups = [(size, sizes.count(size)) for size in sorted(set(sizes))]
    forests = [()]
    for size, count in groups:
        forests = [forest + combo for forest in forests
                   for combo in combinations_with_replacement(trees(size, colours), count)]
    return {tuple(sorted(forest)) for forest in forests}


def size(tree) -> int:
    return 1 + sum(size(child) for child in tree[1])


def density(tree) -> int:
    """γ(τ) = |τ| Π γ(children)."""
    return size(tree) * int(np.prod([density(child) for child in tree[1]]))


def weights(tree, matrices: dict) -> np.ndarray:
    """Φ(τ) (s,): the product over the children of A^{child's colour} Φ(child) (ones for a leaf)."""
    out = np.ones(next(iter(matrices.values())).shape[0])
    for child in tree[1]:
        out = out * (matrices[child[0]] @ weights(child, matrices))
    return out


def defects(order: int, matrices: dict, b: dict) -> np.ndarray:
    """|b^{root colour}ᵀ Φ(τ) − 1/γ(τ)| over the trees of exactly ``order`` nodes."""
    return np.array([abs(b[tree[0]] @ weights(tree, matrices) - 1.0 / density(tree))
                     for tree in trees(order, tuple(matrices))])


def test_the_trees_are_counted_right():
    """1, 1, 2, 4, 9, 20 rooted trees of order 1..6; 2, 4, 14 two-coloured trees of order 1..3
    (order 3: 2³ colourings of the chain, 2 × 3 of the cherry)."""
    assert [len(trees(order)) for order in range(1, 7)] == [1, 1, 2, 4, 9, 20]
    assert [len(trees(order, ("E", "I"))) for order in range(1, 4)] == [2, 4, 14]


@pytest.mark.parametrize("tableau", SINGLE, ids=lambda tableau: tableau.name)
def test_a_tableau_has_exactly_its_order(tableau: Tableau):
    for order in range(1, tableau.order + 1):
        assert np.all(defects(order, {"": tableau.A}, {"": tableau.b}) < 1e-14), (tableau.name, order)
    assert np.max(defects(tableau.order + 1, {"": tableau.A}, {"": tableau.b})) > 1e-3


@pytest.mark.parametrize("tableau", PAIRS, ids=lambda tableau: tableau.name)
def test_an_imex_pair_has_its_order_with_the_coupling_conditions(tableau: Tableau):
    """Trees coloured E (explicit) / I (implicit): b^{root} Π A^{child} … = 1/γ."""
    matrices, b = {"E": tableau.explicit_A, "I": tableau.A}, {"E": tableau.explicit_b, "I": tableau.b}
    np.testing.assert_allclose(tableau.explicit_A.sum(axis=1), tableau.c, atol=1e-12)
    assert np.all(np.triu(tableau.explicit_A) == 0) and tableau.diagonally_implicit
    for order in range(1, tableau.order + 1):
        assert np.all(defects(order, matrices, b) < 1e-11), (tableau.name, order)  # 13-digit rationals
    assert np.max(defects(tableau.order + 1, matrices, b)) > 1e-3
    if tableau.b_hat is not None:  # the embedded method: b̂ for both parts
        embedded = {"E": tableau.b_hat, "I": tableau.b_hat}
        for order in range(1, tableau.embedded_order + 1):
            assert np.all(defects(order, matrices, embedded) < 1e-11)
        assert np.max(defects(tableau.embedded_order + 1, matrices, embedded)) > 1e-4


def simplifying(tableau: Tableau, condition: str, k: int) -> float:
    """The defect of B(k), C(k) or D(k) at its k-th power (the conditions hold up to k when the defects
    at 1..k vanish)."""
    A, b, c = tableau.A, tableau.b, tableau.c
    if condition == "B":
        return abs(b @ c ** (k - 1) - 1 / k)
    if condition == "C":
        return np.max(abs(A @ c ** (k - 1) - c ** k / k))
    return np.max(abs((b * c ** (k - 1)) @ A - b * (1 - c ** k) / k))


@pytest.mark.parametrize("tableau, B, C, D", [(GAUSS_LEGENDRE, 4, 2, 2), (RADAU_IIA, 5, 3, 2)],
                         ids=["gauss_legendre", "radau_iia"])
def test_collocation_methods_meet_their_simplifying_conditions(tableau, B, C, D):
    """Gauss: B(2s), C(s), D(s); Radau IIA: B(2s − 1), C(s), D(s − 1) — each exactly."""
    for condition, highest in (("B", B), ("C", C), ("D", D)):
        assert all(simplifying(tableau, condition, k) < 1e-14 for k in range(1, highest + 1)), condition
        assert simplifying(tableau, condition, highest + 1) > 1e-3, condition


def test_radau_iia_and_the_implicit_parts_of_the_imex_pairs_are_l_stable():
    """A-stable (|R| ≤ 1 on the imaginary axis and the left half-plane) and R(z) → 0 as z → −∞."""
    y = np.linspace(-200, 200, 4001)
    rng = np.random.default_rng(0)
    left = -rng.exponential(10, 2000) + 1j * rng.normal(0, 30, 2000)
    for tableau in (RADAU_IIA, ARK_IMEX, ARS232):
        assert np.max(abs(tableau.stability_function(1j * y))) <= 1 + 1e-12, tableau.name
        assert np.max(abs(tableau.stability_function(left))) <= 1 + 1e-12, tableau.name
        far = abs(tableau.stability_function(np.array([-1e4, -1e6, -1e8])))
        assert np.all(far < 10 / np.array([1e4, 1e6, 1e8])), (tableau.name, far)
    # stiffly accurate: bᵀ is the last row of A, so R(∞) = 1 − bᵀA⁻¹1 = 0 exactly
    assert abs(1 - RADAU_IIA.b @ np.linalg.solve(RADAU_IIA.A, np.ones(3))) < 1e-14
    # R approximates e^z to order 5: R(z) − e^z = O(z⁶)
    z = np.array([0.1, 0.05])
    error = abs(RADAU_IIA.stability_function(z) - np.exp(z))
    assert 50 < error[0] / error[1] < 80  # 2⁶ = 64


def symplecticity(tableau: Tableau) -> np.ndarray:
    """m_ij = b_i a_ij + b_j a_ji − b_i b_j (zero for a symplectic method)."""
    B = tableau.b[:, None] * tableau.A
    return B + B.T - np.outer(tableau.b, tableau.b)


def test_gauss_legendre_is_symplectic_and_radau_is_not():
    assert np.max(abs(symplecticity(GAUSS_LEGENDRE))) < 1e-15
    assert np.max(abs(symplecticity(IMPLICIT_MIDPOINT))) == 0
    assert np.max(abs(symplecticity(RADAU_IIA))) > 1e-3
    # |R(iy)| = 1: no damping of oscillations; R(−∞) = 1 (A-stable, not L-stable)
    y = np.linspace(-100, 100, 1001)
    np.testing.assert_allclose(abs(GAUSS_LEGENDRE.stability_function(1j * y)), 1.0, rtol=1e-12)
    assert abs(GAUSS_LEGENDRE.stability_function(-1e8)[0] - 1) < 1e-6


def test_the_families_are_read_off_the_data():
    assert [name for name, tableau in TABLEAUX.items() if tableau.explicit] == ["explicit_euler", "ssprk3", "rk4"]
    assert [name for name, tableau in TABLEAUX.items() if tableau.additive] == ["ars232", "ark_imex"]
    assert not GAUSS_LEGENDRE.diagonally_implicit and not RADAU_IIA.diagonally_implicit
    assert ARK_IMEX.stages == 4 and RADAU_IIA.stages == 3 and GAUSS_LEGENDRE.stages == 2
    assert not GAUSS_LEGENDRE.A.flags.writeable  # data, not state


def test_a_malformed_tableau_is_refused():
    A, b, c = np.eye(2), np.ones(2) / 2, np.ones(2)
    with pytest.raises(ValueError, match="tableau bad: A must be"):
        Tableau("bad", A, np.ones(3), c, order=1)
    with pytest.raises(ValueError, match="tableau bad: c must be the row sums of A"):
        Tableau("bad", A, b, np.zeros(2), order=1)
