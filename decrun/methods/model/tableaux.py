"""Runge–Kutta methods as data: Butcher tableaux, and additive (IMEX) pairs of them.

A method with s stages advances M y' = f(y, t) by one step dt through stage derivatives K_i::

    M K_i = f(Y_i, t + c_i dt),   Y_i = y + dt Σ_j a_ij K_j,   y⁺ = y + dt Σ_i b_i K_i

with A (s, s), b (s,), c = A·1 (s,). It is explicit when A is strictly lower triangular. An
additive pair (Kennedy & Carpenter 2003) splits f = L y + g: A, b act on the stiff linear part L
(diagonally implicit) and ``explicit_A``, ``explicit_b`` on g (strictly lower triangular), with
the same c. ``b_hat`` are embedded weights of a lower order (an error estimate), where the method
has them.

======================  =======  ======  ==========================================================
name                    stages   order   property
======================  =======  ======  ==========================================================
``explicit_euler``      1        1       —
``ssprk3``              3        3       strong-stability preserving (Shu & Osher 1988), CFL 1
``rk4``                 4        4       the classical method
``implicit_euler``      1        1       L-stable
``implicit_midpoint``   1        2       Gauss 1-stage: symplectic, A-stable
``crank_nicolson``      2        2       trapezoidal rule (Lobatto IIIA), A-stable
``gauss_legendre``      2        4       Gauss collocation: symplectic, A-stable, B(4) C(2) D(2)
``radau_iia``           3        5       Radau IIA collocation: L-stable, stiffly accurate, B(5) C(3)
``ars232``              3        2       IMEX ARS(2,3,2) (Ascher, Ruuth & Spiteri 1997), L-stable
``ark_imex``            4        3       IMEX ARK3(2)4L[2]SA (Kennedy & Carpenter 2003), L-stable,
                                         stiffly accurate, embedded order 2
======================  =======  ======  ==========================================================
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

import numpy as np

__all__ = ["Tableau", "TABLEAUX", "EXPLICIT_EULER", "SSPRK3", "RK4", "IMPLICIT_EULER", "IMPLICIT_MIDPOINT",
           "CRANK_NICOLSON", "GAUSS_LEGENDRE", "RADAU_IIA", "ARS232", "ARK_IMEX"]


def _matrix(rows) -> np.ndarray:
    array = np.array([[float(value) for value in row] for row in rows], dtype=np.float64)
    array.setflags(write=False)
    return array


def _vector(values) -> np.ndarray:
    return _matrix([values])[0]


@dataclass(frozen=True, eq=False)
class Tableau:
    """A Runge–Kutta method: ``A`` (s, s), ``b`` (s,), ``c`` (s,), its ``order``; optionally the
    embedded weights ``b_hat`` (s,) of order ``embedded_order``, and for an additive IMEX pair the
    explicit part's ``explicit_A`` (s, s) and ``explicit_b`` (s,) (then A, b are the implicit part)."""

    name: str
    A: np.ndarray
    b: np.ndarray
    c: np.ndarray
    order: int
    b_hat: np.ndarray | None = None
    embedded_order: int | None = None
    explicit_A: np.ndarray | None = None
    explicit_b: np.ndarray | None = None

    def __post_init__(self):
        s = len(self.b)
        shapes = [self.A.shape == (s, s), self.c.shape == (s,)]
        shapes += [self.b_hat is None or self.b_hat.shape == (s,)]
        shapes += [self.explicit_A is None or (self.explicit_A.shape == (s, s) and self.explicit_b is not None
                                               and self.explicit_b.shape == (s,))]
        if not all(shapes):
            raise ValueError(f"tableau {self.name}: A must be (s, s), b, c, b_hat and explicit_b (s,) for s = {s}")
        if not np.allclose(self.A.sum(axis=1), self.c, rtol=0, atol=1e-14):
            raise ValueError(f"tableau {self.name}: c must be the row sums of A")

    @property
    def stages(self) -> int:
        """s, the number of stages."""
        return len(self.b)

    @property
    def additive(self) -> bool:
        """An IMEX pair: A, b implicit on the stiff linear part, explicit_A, explicit_b on the rest."""
        return self.explicit_A is not None

    @property
    def explicit(self) -> bool:
        """A strictly lower triangular (and not an additive pair): every stage from the earlier ones."""
        return not self.additive and not np.any(np.triu(self.A))

    @property
    def diagonally_implicit(self) -> bool:
        """A lower triangular: one stage at a time (a DIRK, or the implicit part of an IMEX pair)."""
        return not np.any(np.triu(self.A, 1))

    def stability_function(self, z: complex | np.ndarray) -> np.ndarray:
        """R(z) = 1 + z bᵀ (I − z A)⁻¹ 1: one step of y' = λy is y⁺ = R(λ dt) y (z (m,) or scalar)."""
        z = np.atleast_1d(np.asarray(z, dtype=np.complex128))
        s = self.stages
        systems = np.eye(s)[None, :, :] - z[:, None, None] * self.A[None, :, :]
        stages = np.linalg.solve(systems, np.ones((len(z), s, 1)))[:, :, 0]
        return 1.0 + z * (stages @ self.b)


SQRT3, SQRT6 = np.sqrt(3.0), np.sqrt(6.0)

EXPLICIT_EULER = Tableau("explicit_euler", _matrix([[0]]), _vector([1]), _vector([0]), order=1)
SSPRK3 = Tableau("ssprk3", _matrix([[0, 0, 0], [1, 0, 0], [0.25, 0.25, 0]]), _vector([1 / 6, 1 / 6, 2 / 3]),
                 _vector([0, 1, 0.5]), order=3)
RK4 = Tableau("rk4", _matrix([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1, 0]]),
              _vector([1 / 6, 1 / 3, 1 / 3, 1 / 6]), _vector([0, 0.5, 0.5, 1]), order=4)
IMPLICIT_EULER = Tableau("implicit_euler", _matrix([[1]]), _vector([1]), _vector([1]), order=1)
IMPLICIT_MIDPOINT = Tableau("implicit_midpoint", _matrix([[0.5]]), _vector([1]), _vector([0.5]), order=2)
CRANK_NICOLSON = Tableau("crank_nicolson", _matrix([[0, 0], [0.5, 0.5]]), _vector([0.5, 0.5]), _vector([0, 1]),
                         order=2)
#: Gauss–Legendre collocation at the roots of P₂(2c − 1): c = ½ ∓ √3/6
GAUSS_LEGENDRE = Tableau(
    "gauss_legendre",
    _matrix([[0.25, 0.25 - SQRT3 / 6], [0.25 + SQRT3 / 6, 0.25]]),
    _vector([0.5, 0.5]),
    _vector([0.5 - SQRT3 / 6, 0.5 + SQRT3 / 6]),
    order=4)
#: Radau IIA collocation at the right Radau points c = (4 ∓ √6)/10, 1 (the zeros of P₃(2c − 1) − P₂(2c − 1))
RADAU_IIA = Tableau(
    "radau_iia",
    _matrix([[(88 - 7 * SQRT6) / 360, (296 - 169 * SQRT6) / 1800, (-2 + 3 * SQRT6) / 225],
             [(296 + 169 * SQRT6) / 1800, (88 + 7 * SQRT6) / 360, (-2 - 3 * SQRT6) / 225],
             [(16 - SQRT6) / 36, (16 + SQRT6) / 36, 1 / 9]]),
    _vector([(16 - SQRT6) / 36, (16 + SQRT6) / 36, 1 / 9]),
    _vector([(4 - SQRT6) / 10, (4 + SQRT6) / 10, 1]),
    order=5)

#: ARS(2,3,2): γ = 1 − 1/√2, δ = 1 − 1/(2γ)
_GAMMA = 1 - 1 / np.sqrt(2.0)
_DELTA = 1 - 1 / (2 * _GAMMA)
ARS232 = Tableau(
    "ars232",
    _matrix([[0, 0, 0], [0, _GAMMA, 0], [0, 1 - _GAMMA, _GAMMA]]),
    _vector([0, 1 - _GAMMA, _GAMMA]),
    _vector([0, _GAMMA, 1]),
    order=2,
    explicit_A=_matrix([[0, 0, 0], [_GAMMA, 0, 0], [_DELTA, 1 - _DELTA, 0]]),
    explicit_b=_vector([_DELTA, 1 - _DELTA, 0]))


def _ark324() -> Tableau:
    """ARK3(2)4L[2]SA of Kennedy & Carpenter (2003, Appl. Numer. Math. 44), with its published rationals
    (the explicit and implicit parts share b and c; b_hat is the embedded order-2 method)."""
    F = Fraction
    gamma = F(1767732205903, 4055673282236)
    b: list[Fraction | int] = [F(1471266399579, 7840856788654), F(-4482444167858, 7529755066697),
                               F(11266239266428, 11593286722821), gamma]
    implicit: list[list[Fraction | int]] = [[0, 0, 0, 0],
                                            [gamma, gamma, 0, 0],
                                            [F(2746238789719, 10658868560708), F(-640167445237, 6845629431997),
                                             gamma, 0],
                                            b]
    explicit = [[0, 0, 0, 0],
                [2 * gamma, 0, 0, 0],
                [F(5535828885825, 10492691773637), F(788022342437, 10882634858940), 0, 0],
                [F(6485989280629, 16251701735622), F(-4246266847089, 9704473918619),
                 F(10755448449292, 10357097424841), 0]]
    b_hat = [F(2756255671327, 12835298489170), F(-10771552573575, 22201958757719), F(9247589265047, 10645013368117),
             F(2193209047091, 5459859503100)]
    c = [sum((F(value) for value in row), F(0)) for row in implicit]
    return Tableau("ark_imex", _matrix(implicit), _vector(b), _vector(c), order=3, b_hat=_vector(b_hat),
                   embedded_order=2, explicit_A=_matrix(explicit), explicit_b=_vector(b))


ARK_IMEX = _ark324()

#: every tableau by name
TABLEAUX: dict[str, Tableau] = {tableau.name: tableau for tableau in (
    EXPLICIT_EULER, SSPRK3, RK4, IMPLICIT_EULER, IMPLICIT_MIDPOINT, CRANK_NICOLSON, GAUSS_LEGENDRE, RADAU_IIA, ARS232,
    ARK_IMEX)}
