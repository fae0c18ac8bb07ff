"""The operators of the model language: degree rules, discrete definitions, evaluation.

:data:`OPERATORS` is the one table of the language: for each operator its argument count, its
typing rule (the degree and duality it takes and gives, checked when a model loads), its
discrete definition with the thesis' equation, how it is evaluated, and — for the linear
operators — its matrix as a :class:`Linear` ``⋆_j⁻¹ A``, from which implicit integrators and
solves assemble their systems. The language reference of docs/models.md is generated from this table
(:func:`reference_table`), so the two cannot disagree.

Operators act through :class:`Discrete`, which takes every matrix from
:class:`decrun.core.dec.DEC` (so ``operator=`` and ``boundary=`` apply unchanged) and keeps the
few the language adds (:mod:`decrun.methods.model.discrete`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional

import numpy as np
import scipy.sparse as sp

from decrun.errors import ConfigError
from decrun.methods.model import discrete, robin, sphere_functions, sphere_operators, vector_derivatives
from decrun.methods.model.kinds import NUMBER, VECTOR, Kind, dual, primal
from decrun.methods.model.wording import article

__all__ = ["Linear", "Discrete", "Operator", "OPERATORS", "ALIASES", "POINTWISE", "Mismatch", "reference_table",
           "register", "pointwise", "load_plugins", "ENTRY_POINT_GROUP", "PluginError"]


class Mismatch(Exception):
    """A typing rule's refusal: the message says what the operator takes and what it got."""


@dataclass
class Linear:
    """A linear operator on forms written ``⋆_inv⁻¹ A`` (``inv`` None: just ``A``), so that
    systems containing inverse stars — the Laplacian ⋆0⁻¹ S — are assembled in weak form
    (multiplied by ⋆_inv) and a non-diagonal (Galerkin) ⋆ is never inverted. ``A`` is a
    scipy sparse matrix (n_out, n_in)."""

    inv: Optional[int]
    A: sp.spmatrix

    def scaled(self, c: float) -> "Linear":
        return Linear(self.inv, (c * self.A).tocsr())


class Discrete:
    """The matrices and geometry every operator reads, from one :class:`DEC` (cached there)."""

    def __init__(self, dec):
        self.dec, self.K, self.n = dec, dec.K, dec.n
        calculus = getattr(dec.star_variant, "calculus", None)
        #: operator=intrinsic_delaunay: d0, ⋆1, ♯, ♭ of the intrinsic triangulation
        #: (:class:`decrun.core.intrinsic_calculus.IntrinsicCalculus`), where primal 1-forms and
        #: vectors then live; None for the variants on the mesh's own simplices
        self.intrinsic = calculus(dec) if calculus is not None else None

    def diagonal(self, k: int) -> np.ndarray | None:
        """(n_k,) diagonal of ⋆_k, or None (Galerkin ⋆)."""
        if self.intrinsic is not None and k == 1:
            return self.intrinsic.star1
        return self.dec.star_diagonal_or_none(k)

    def mean_edge_length(self) -> float:
        """The built-in ``h``: the mean edge length of the triangulation the operators live on
        (the intrinsic one under ``intrinsic``: the heat method's t = m h² is its spacing)."""
        if self.intrinsic is not None:
            return float(self.intrinsic.T.edge_lengths.mean())
        return float(self.K.mean_edge_length)

    def sharp(self, omega: np.ndarray) -> np.ndarray:
        """ω♯ per top simplex (of the intrinsic triangulation under ``intrinsic``)."""
        return discrete.sharp(self.K, omega) if self.intrinsic is None else self.intrinsic.sharp(omega)

    def flat(self, vectors: np.ndarray) -> np.ndarray:
        """X♭ on the edges (of the intrinsic triangulation under ``intrinsic``)."""
        return discrete.flat(self.K, vectors) if self.intrinsic is None else self.intrinsic.flat(vectors)

    def star_inverse_apply(self, k: int, x):
        """⋆_k⁻¹ x (a division for diagonal stars, a factorized solve otherwise)."""
        return self.dec.star_solve(k, x)

    def matrix(self, linear: Linear) -> Callable[[np.ndarray], np.ndarray]:
        """x ↦ ⋆_inv⁻¹ A x as one callable: the diagonal ⋆_inv⁻¹ folded into A once."""
        if linear.inv is None:
            A = linear.A.tocsr()
            return lambda x: A @ x
        diagonal = self.diagonal(linear.inv)
        if diagonal is not None:
            A = (sp.diags(1.0 / diagonal) @ linear.A).tocsr()
            return lambda x: A @ x
        A, k = linear.A.tocsr(), linear.inv
        return lambda x: self.dec.star_solve(k, A @ x)

    def compose(self, outer: Linear, inner: Linear) -> Linear | None:
        """``outer ∘ inner`` as one :class:`Linear`, or None when a non-diagonal ⋆⁻¹ would sit
        between them (no sparse matrix represents it)."""
        if inner.inv is None:
            return Linear(outer.inv, (outer.A @ inner.A).tocsr())
        diagonal = self.diagonal(inner.inv)
        if diagonal is None:
            return None
        return Linear(outer.inv, (outer.A @ sp.diags(1.0 / diagonal) @ inner.A).tocsr())

    def add(self, first: Linear, second: Linear) -> Linear | None:
        """``first + second`` with a common ⋆⁻¹ on the left (⋆⁻¹A + B = ⋆⁻¹(A + ⋆B))."""
        if first.inv == second.inv:
            return Linear(first.inv, (first.A + second.A).tocsr())
        if first.inv is None:
            first, second = second, first
        if second.inv is None:
            return Linear(first.inv, (first.A + self.dec.star(first.inv) @ second.A).tocsr())
        return None  # two different inverse stars on the left: not one weak form

    def identity(self, kind: Kind) -> Linear:
        return Linear(None, sp.identity(kind.size(self.K), format="csr"))


@dataclass(frozen=True)
class Operator:
    """One operator of the language (see the module docstring)."""

    name: str
    arity: tuple[int, ...]
    takes: str  # the typing rule in words (docs/models.md)
    definition: str  # the discrete definition and the thesis' equation (docs/models.md)
    kind: Callable[[list[Kind], int], Kind]
    evaluate: Optional[Callable]  # (Discrete, kinds, *values) -> value; None: through its matrix (linear)
    linear: Optional[Callable] = None  # (Discrete, kind of the argument) -> Linear | None
    #: (Discrete, kinds, first argument's value) -> the sparse matrix of the operator in its second
    #: argument, for an operator linear in it once the first is fixed (lie of a static velocity)
    fixed_first: Optional[Callable] = None
    #: the derivative rule, for exact Jacobians: (Discrete, kinds, values, i) -> ∂(op)/∂(argument i)
    #: at the arguments' ``values``, either an array (a value-by-value factor: the diagonal matrix
    #: diag(f'(x))) or a sparse matrix; None: the operator has no derivative rule (a linear
    #: operator's derivative is its matrix, :attr:`linear`, and needs no rule)
    derivative: Optional[Callable] = None
    #: True for a value-by-value operator: each output value reads the inputs' values on the same
    #: simplex only (its Jacobian is diagonal; it may stand in initial and border values)
    pointwise: bool = False


def _one_form(args, n, name, allowed: Callable[[Kind], bool], takes: str) -> Kind:
    (kind,) = args
    if not (kind.is_form and allowed(kind)):
        raise Mismatch(f"{name} takes {takes}, got a {kind}")
    return kind


# ------------------------------------------------------------------ d
def _d_kind(args, n):
    kind = _one_form(args, n, "d", lambda k: k.degree < n, f"a form of degree < {n} (the mesh dimension)")
    return Kind("form", kind.degree + 1, kind.dual)


def _d_linear(ops: Discrete, kind: Kind) -> Linear:
    if ops.intrinsic is not None and not kind.dual and kind.degree == 0:
        return Linear(None, ops.intrinsic.d0)
    return Linear(None, ops.dec.d_dual(kind.degree) if kind.dual else ops.dec.d(kind.degree))


# ------------------------------------------------------------------ ⋆
def _star_kind(args, n):
    kind = _one_form(args, n, "star", lambda k: True, "a form")
    return Kind("form", n - kind.degree, not kind.dual)


def _star_linear(ops: Discrete, kind: Kind) -> Linear:
    n = ops.n
    if not kind.dual:  # primal k → dual n−k: ⋆_k
        return Linear(None, ops.dec.star(kind.degree))
    j = n - kind.degree  # dual k → primal n−k: (−1)^{k(n−k)} ⋆_{n−k}⁻¹, so that ⋆⋆ = (−1)^{k(n−k)}
    sign = (-1) ** (kind.degree * j)
    return Linear(j, sign * sp.identity(ops.K.num_simplices(j), format="csr"))


def _inv_star_kind(args, n):
    kind = _one_form(args, n, "inv_star", lambda k: k.dual, "a dual form (star(u) is the dual of a primal u)")
    return Kind("form", n - kind.degree, False)


def _inv_star_linear(ops: Discrete, kind: Kind) -> Linear:
    j = ops.n - kind.degree
    return Linear(j, sp.identity(ops.K.num_simplices(j), format="csr"))


# ------------------------------------------------------------------ δ, Δ
def _codifferential_kind(args, n):
    kind = _one_form(args, n, "codifferential", lambda k: not k.dual and k.degree >= 1,
                     "a primal k-form with k ≥ 1")
    return primal(kind.degree - 1)


def _codifferential_linear(ops: Discrete, kind: Kind) -> Linear | None:
    k, dec = kind.degree, ops.dec
    if ops.intrinsic is not None and k == 1:
        return Linear(0, ops.intrinsic.codifferential_weak())
    if dec.boundary.codifferential(dec, k) is not None:  # boundary=flux: the adapted matrix (§6.4.4)
        matrix = dec.codifferential(k)
        return Linear(None, matrix) if sp.issparse(matrix) else None
    return Linear(k - 1, (dec.d(k - 1).T @ dec.star(k)).tocsr())  # eq. 4.14: ⋆_{k−1}⁻¹ d_{k−1}ᵀ ⋆_k


def _laplacian_kind(name):
    def rule(args, n):
        return _one_form(args, n, name, lambda k: not k.dual, "a primal form")
    return rule


def _laplacian_linear(sign: float):
    def build(ops: Discrete, kind: Kind) -> Linear | None:
        k, dec = kind.degree, ops.dec
        if k == 0 or not all(dec.star_is_diagonal(j) for j in (k - 1, k) if 0 <= j <= ops.n):
            symmetric = dec.laplacian_symmetric(k)  # ⋆_k Δ_k (the variant's stiffness for k = 0)
            return Linear(k, sign * symmetric) if sp.issparse(symmetric) else None
        return Linear(None, (sign * dec.laplacian(k)).tocsr())  # diagonal stars: dδ + δd as DEC builds it
    return build


def _laplacian_evaluate(sign: float):
    def run(ops: Discrete, kinds, x):
        k = kinds[0].degree
        return sign * (ops.dec.laplacian(k) @ x)
    return run


# ------------------------------------------------------------------ ∧, ♯, ♭, averages, advection
def _wedge_kind(args, n):
    a, b = args
    if not (a.is_form and b.is_form) or a.dual or b.dual:
        raise Mismatch(f"wedge (^) takes two primal forms, got a {a} and a {b} (use * for products with numbers)")
    if a.degree + b.degree > n:
        raise Mismatch(f"wedge of a {a} and a {b} has degree {a.degree + b.degree} > {n} (the mesh dimension)")
    if a.degree and b.degree and not (a.degree == 1 and b.degree == 1):
        raise Mismatch(f"wedge is defined for 0∧k, k∧0 and 1∧1, not {a.degree}∧{b.degree}")
    return primal(a.degree + b.degree)


def _wedge_evaluate(ops: Discrete, kinds, a, b):
    ka, kb = kinds
    if ka.degree == 0:
        return discrete.wedge_0k(ops.K, a, b, kb.degree)
    if kb.degree == 0:
        return discrete.wedge_0k(ops.K, b, a, ka.degree)
    return discrete.wedge_11(ops.K, a, b)


def _sharp_kind(args, n):
    _one_form(args, n, "sharp", lambda k: not k.dual and k.degree == 1, "a primal 1-form")
    return VECTOR


def _flux_field_kind(args, n):
    _one_form(args, n, "flux_field", lambda k: not k.dual and k.degree == n - 1,
              f"a primal {n - 1}-form (a flux through the {n - 1}-simplices)")
    return VECTOR


def _flat_kind(args, n):
    (kind,) = args
    if kind != VECTOR:
        raise Mismatch(f"flat takes a vector field (e.g. sharp(d(u))), got a {kind}")
    if n != 2:
        raise Mismatch(f"flat is defined on triangle meshes here (dimension 2), not dimension {n}")
    return primal(1)


def _average_kind(args, n):
    _one_form(args, n, "average", lambda k: k.degree == 0,
              "a primal 0-form (values at vertices) or a dual 0-form (values per top simplex)")
    return primal(1)


def _average_linear(ops: "Discrete", kind: Kind) -> Linear:
    if kind.dual:  # one value per top simplex → the mean over the top simplices at each edge
        return Linear(None, discrete.cell_to_edge_matrix(ops.K))
    return Linear(None, discrete.average_matrix(ops.K, 1))


def _cell_average_kind(args, n):
    _one_form(args, n, "cell_average", lambda k: not k.dual and k.degree == 0, "a primal 0-form")
    return dual(0)


def _cell_average_linear(ops: "Discrete", kind: Kind) -> Linear:
    return Linear(None, discrete.average_matrix(ops.K, ops.n))


def _border_kind(args, n):
    _one_form(args, n, "border", lambda k: not k.dual and k.degree == 0, "a primal 0-form (values at vertices)")
    return primal(n - 1)


def _border_linear(ops: "Discrete", kind: Kind) -> Linear:
    """``border(q) = ⋆_{n−1}⁻¹ B q``: (B q)_σ = o_σ · (mean of q over the vertices of σ) on each
    border (n−1)-simplex σ, 0 inside; o_σ = ±1 is σ's orientation against the outward one (its
    incidence with its one top simplex, ``d_{n−1}ᵀ 1``: on an interior simplex the two top
    simplices' incidences cancel). So ⟨border(q), v⟩ = vᵀ B q = Σ_σ o_σ q̄_σ v_σ ≈ ∫_∂Ω q tr v
    for every (n−1)-form v — for a Whitney (n−1)-form the trace on σ is v_σ/|σ| times σ's volume
    form, so ∫_σ q tr v = q̄_σ v_σ up to O(h²) — the boundary term of integrating by parts,
    ⟨p, d v⟩ = ⟨δ p, v⟩ + ∫_∂Ω q tr v: where a natural border value q enters a weak form."""
    n = ops.n
    outward = ops.dec.d(n - 1).T @ np.ones(ops.K.num_simplices(n))
    B = sp.diags(outward) @ discrete.average_matrix(ops.K, n - 1)
    return Linear(n - 1, B.tocsr())


def _velocity(kind: Kind) -> bool:
    """A velocity: a vector field, or a primal 1-form (a flux/circulation field, its ♯ taken)."""
    return kind == VECTOR or (kind.is_form and not kind.dual and kind.degree == 1)


def _as_vectors(ops: "Discrete", kind: Kind, value):
    return value if kind == VECTOR else discrete.sharp(ops.K, value)


def _interior_kind(args, n):
    field, form = args
    if not _velocity(field) or not (form.is_form and not form.dual and form.degree == 1):
        raise Mismatch(f"interior takes a vector field (or a 1-form, its ♯) and a primal 1-form, got a {field} and a "
                       f"{form}")
    return dual(0)


def _lie_kind(args, n):
    field, form = args
    if not _velocity(field) or not (form.is_form and not form.dual and form.degree in (0, 1)):
        raise Mismatch(f"lie takes a vector field (or a 1-form, its ♯) and a primal 0- or 1-form, got a {field} and a "
                       f"{form}")
    if form.degree == 1 and n != 2:
        raise Mismatch("lie of a 1-form is defined on triangle meshes here (dimension 2)")
    return form


def _lie_fixed_first(ops: "Discrete", kinds, field):
    """The matrix of u ↦ L_X u for a fixed X (0-forms; Cartan's formula on 1-forms)."""
    if kinds[1].degree != 0:
        return vector_derivatives.lie_1_matrix(ops.K, _as_vectors(ops, kinds[0], field))
    return discrete.lie_0_matrix(ops.K, _as_vectors(ops, kinds[0], field))


def _lie_evaluate(ops: "Discrete", kinds, field, form):
    vectors = _as_vectors(ops, kinds[0], field)
    if kinds[1].degree == 0:
        return discrete.lie_0(ops.K, vectors, form)
    return discrete.lie_1(ops.K, vectors, form)


# ------------------------------------------------------------------ measures
def _norm_kind(args, n):
    (kind,) = args
    if kind == VECTOR:
        return dual(0)
    if kind.is_form:
        return NUMBER
    raise Mismatch(f"norm takes a vector field (its length per top simplex) or a form (‖u‖), got a {kind}")


def weights(ops: Discrete, kind: Kind):
    """The ⋆ inner product's weight of a form: ``("star", k)`` for primal k-forms,
    ``("inverse", k)`` for dual forms on k-simplices, ``("volume",)`` for vectors."""
    if kind == VECTOR:
        return ("volume",)
    j = kind.simplex_dimension(ops.n)
    return ("inverse", j) if kind.dual else ("star", j)


def inner_product(ops: Discrete, kind: Kind, a, b) -> float:
    """⟨a, b⟩ (eq. 4.15): aᵀ ⋆_k b for primal k-forms, aᵀ ⋆_j⁻¹ b for dual forms on
    j-simplices (⟨⋆⁻¹a, ⋆⁻¹b⟩), Σ |σ| a_σ·b_σ for vectors."""
    weight = weights(ops, kind)
    if weight[0] == "volume":
        return float(np.einsum("f,fd,fd->", ops.K.top_volumes, a, b))
    if weight[0] == "star":
        return float(ops.dec.inner(weight[1], a, b))
    return float(a @ ops.dec.star_solve(weight[1], b))


def _norm_evaluate(ops: Discrete, kinds, x):
    """‖x‖ = √⟨x, x⟩; nan (never 0, never a clamp) where ⟨x, x⟩ < 0 — an indefinite ⋆ (negative
    circumcentric entries on obtuse triangles), reported by name at the end of the run
    (:func:`decrun.methods.model.finite.negative_norms`)."""
    if kinds[0] == VECTOR:
        return np.sqrt(np.einsum("fd,fd->f", x, x))
    square = inner_product(ops, kinds[0], x, x)
    return float(np.sqrt(square)) if square >= 0 else float("nan")


def _normalize_kind(args, n):
    (kind,) = args
    if kind != VECTOR:
        raise Mismatch(f"normalize takes a vector field (e.g. sharp(d(u))), got a {kind}")
    return VECTOR


def _integral_kind(args, n):
    (kind,) = args
    if kind.is_form and (kind.degree == 0 or kind.degree == n):
        return NUMBER
    raise Mismatch(f"integral takes a 0-form or {article(n)} {n}-form (primal or dual), got a {kind}")


def integral(ops: Discrete, kind: Kind, x) -> float:
    """∫ u: Σ ⋆0 u for a primal 0-form, Σ u for a primal n-form (oriented) or a dual n-form
    (values on dual cells), Σ |σ| u for a dual 0-form (values per top simplex)."""
    if not kind.dual and kind.degree == 0:
        return float(np.sum(ops.dec.star(0) @ x))
    if kind.dual and kind.degree == 0:
        return float(ops.K.top_volumes @ x)
    return float(np.sum(x))


def _inner_kind(args, n):
    a, b = args
    if a != b or a == NUMBER:
        raise Mismatch(f"inner takes two forms of the same kind (or two vector fields), got a {a} and a {b}")
    return NUMBER


def _reduction_or_pointwise(name):
    def rule(args, n):
        if len(args) == 1:
            if args[0] == VECTOR:
                raise Mismatch(f"{name} takes a form or numbers, got a {args[0]}")
            return NUMBER
        return _pointwise_kind(name, args)
    return rule


def _reduction_or_pointwise_evaluate(function, reduce):
    def run(ops, kinds, *values):
        if len(values) == 1:
            value = values[0]
            return float(reduce(value)) if np.ndim(value) else float(value)
        return function(*values)
    return run


def _larger_derivative(larger: bool):
    """The derivative rule of two-argument max (``larger``) or min: 1 towards the argument that
    is taken at each value, 0 towards the other (ties go to the first); the one-argument
    reduction (a number) has no rule."""
    def rule(ops, kinds, values, i):
        if len(values) != 2:
            return None
        a, b = (np.asarray(value, dtype=np.float64) for value in values)
        first = (a >= b) if larger else (a <= b)
        taken = first if i == 0 else ~first
        return np.broadcast_to(taken.astype(np.float64), np.broadcast(a, b).shape).copy()
    return rule


def _pointwise_kind(name, args):
    kinds = [kind for kind in args if kind != NUMBER]
    if any(kind == VECTOR for kind in kinds):
        raise Mismatch(f"{name} acts on numbers and forms value by value, not on a vector field")
    if len(set(kinds)) > 1:
        raise Mismatch(f"{name} takes forms of one kind, got a {kinds[0]} and a {kinds[1]}")
    return kinds[0] if kinds else NUMBER


def _vertex_kind(args, n):
    if args[0] != NUMBER:
        raise Mismatch(f"vertex takes a vertex index (a number), got a {args[0]}")
    return primal(0)


def _vertex_evaluate(ops: Discrete, kinds, index):
    n0 = ops.K.num_simplices(0)
    if not (float(index).is_integer() and 0 <= index < n0):
        raise ValueError(f"vertex({index:g}): the mesh has vertices 0..{n0 - 1}; give one of them")
    out = np.zeros(n0)
    out[int(index)] = 1.0
    return out


def _unary(function):
    return lambda ops, kinds, x: function(x)


#: value-by-value functions of one argument (numbers and forms)
POINTWISE = {"exp": np.exp, "log": np.log, "sin": np.sin, "cos": np.cos, "tan": np.tan, "tanh": np.tanh,
             "sinh": np.sinh, "cosh": np.cosh, "arcsin": np.arcsin, "arccos": np.arccos, "arctan": np.arctan,
             "sqrt": np.sqrt, "abs": np.abs, "sign": np.sign}

#: f' of each of :data:`POINTWISE` (abs' = sign, sign' = 0 away from 0)
POINTWISE_DERIVATIVES: dict[str, Callable] = {
    "exp": np.exp, "log": lambda x: 1.0 / x, "sin": np.cos, "cos": lambda x: -np.sin(x),
    "tan": lambda x: 1.0 / np.cos(x) ** 2, "tanh": lambda x: 1.0 - np.tanh(x) ** 2, "sinh": np.cosh,
    "cosh": np.sinh, "arcsin": lambda x: 1.0 / np.sqrt(1.0 - x ** 2), "arccos": lambda x: -1.0 / np.sqrt(1.0 - x ** 2),
    "arctan": lambda x: 1.0 / (1.0 + x ** 2), "sqrt": lambda x: 0.5 / np.sqrt(x), "abs": np.sign,
    "sign": np.zeros_like}


def _pointwise_rule(name):
    return lambda args, n: _pointwise_kind(name, args)


OPERATORS: dict[str, Operator] = {}
#: the operators decrun itself defines (a plugin may not replace one)
BUILT_IN: set[str] = set()


def _register(operator: Operator) -> None:
    OPERATORS[operator.name] = operator
    BUILT_IN.add(operator.name)


def pointwise(name: str, function: Callable, derivative: Callable, definition: str) -> Operator:
    """A value-by-value operator of one argument (a number or a form → the same): ``function``
    and its ``derivative`` are numpy functions of an array (``np.tanh`` and ``lambda x: 1 -
    np.tanh(x)**2``); ``definition`` is its line in the docs' operator table. What a plugin
    registers for a new elementwise function (docs/extending.md)."""
    return Operator(name, (1,), "number or form → the same", definition, _pointwise_rule(name),
                    _unary(function), derivative=lambda ops, kinds, values, i: derivative(values[0]), pointwise=True)


_register(Operator("d", (1,), "primal k → primal k+1; dual k → dual k+1 (k < n)",
                   "d_k = δ_{k+1}ᵀ (§4.5.1); on dual forms d^dual_{n−k} = (−1)^k δ_k (eq. 4.13)",
                   _d_kind, lambda ops, kinds, x: _d_linear(ops, kinds[0]).A @ x, _d_linear))
_register(Operator("star", (1,), "primal k → dual n−k; dual k → primal n−k",
                   "⋆_k = |⋆σ|/|σ| of the configured `operator=` (§4.5.4; Whitney's Galerkin ⋆ too); on dual "
                   "forms (−1)^{k(n−k)} ⋆_{n−k}⁻¹, so ⋆⋆ = (−1)^{k(n−k)}",
                   _star_kind, None, _star_linear))
_register(Operator("inv_star", (1,), "dual k → primal n−k",
                   "⋆_{n−k}⁻¹ (a factorized solve for a Galerkin ⋆, never an inverse matrix)",
                   _inv_star_kind, None, _inv_star_linear))
_register(Operator("codifferential", (1,), "primal k → primal k−1 (k ≥ 1)",
                   "δ_k = ⋆_{k−1}⁻¹ d_{k−1}ᵀ ⋆_k (eq. 4.14); boundary=flux replaces δ_1 (§6.4.4)",
                   _codifferential_kind, lambda ops, kinds, x: ops.matrix(_codifferential_linear(ops, kinds[0]))(x)
                   if ops.intrinsic is not None else ops.dec.codifferential(kinds[0].degree) @ x,
                   _codifferential_linear))
_register(Operator("laplacian", (1,), "primal k → primal k",
                   "Laplace–Beltrami sign: −(dδ + δd); on 0-forms −⋆0⁻¹ d0ᵀ ⋆1 d0 (the variant's stiffness), "
                   "negative semi-definite (§4.5.7, §1.3)",
                   _laplacian_kind("laplacian"), _laplacian_evaluate(-1.0), _laplacian_linear(-1.0)))
_register(Operator("laplace_de_rham", (1,), "primal k → primal k",
                   "dδ + δd, positive semi-definite, as the thesis writes Δ (§4.5.7)",
                   _laplacian_kind("laplace_de_rham"), _laplacian_evaluate(1.0), _laplacian_linear(1.0)))
_register(Operator("wedge", (2,), "primal j, primal k → primal j+k (0∧k, k∧0, 1∧1); also `a ^ b`",
                   "(f∧ω)(σ) = f̄_σ ω(σ); (α∧β)(σ) = 1/6 Σ_τ sign(τ) α(τ0τ1) β(τ1τ2) (§3.1.3; Hirani's "
                   "primal-primal wedge with barycentric weights)",
                   _wedge_kind, _wedge_evaluate, derivative=vector_derivatives.wedge_derivative))
_register(Operator("sharp", (1,), "primal 1-form → vector",
                   "Whitney interpolation at each top simplex's barycentre (eq. 6.7); sharp(d(u)) is the "
                   "gradient of the piecewise-linear u",
                   _sharp_kind, lambda ops, kinds, x: ops.sharp(x), derivative=vector_derivatives.sharp_derivative))
_register(Operator("flux_field", (1,), "primal (n−1)-form → vector",
                   "the Whitney (n−1)-form's vector field at each top simplex's barycentre, Σ_i o_i u_i (x − p_i) "
                   "/ (n |σ|) (lowest-order Raviart–Thomas; o_i u_i the flux out through the face opposite p_i): "
                   "the velocity whose fluxes are u, exact for constant fields",
                   _flux_field_kind, lambda ops, kinds, x: discrete.flux_field(ops.K, x),
                   derivative=vector_derivatives.flux_field_derivative))
_register(Operator("flat", (1,), "vector → primal 1-form (triangles)",
                   "ω_e = Σ_{f∋e} (|⋆e∩f|/|⋆e|) X_f·e (Hirani's primal-primal ♭), so −δ X♭ is the cotan "
                   "divergence",
                   _flat_kind, lambda ops, kinds, x: ops.flat(x), derivative=vector_derivatives.flat_derivative))
_register(Operator("average", (1,), "primal 0-form → primal 1-form; dual 0-form → primal 1-form",
                   "(u_a + u_b)/2 on each edge ab (a coefficient per edge); of a dual 0-form g (one value per "
                   "top simplex): Σ_{σ∋e} g_σ / #{σ∋e}, the mean over the top simplices at the edge",
                   _average_kind, lambda ops, kinds, x: _average_linear(ops, kinds[0]).A @ x, _average_linear))
_register(Operator("cell_average", (1,), "primal 0-form → dual 0-form",
                   "ū_σ = Σ_{v∈σ} u_v / (n+1), the mean over the vertices of each top simplex (its value at the "
                   "barycentre)",
                   _cell_average_kind, lambda ops, kinds, x: _cell_average_linear(ops, kinds[0]).A @ x,
                   _cell_average_linear))
_register(Operator("border", (1,), "primal 0-form → primal (n−1)-form",
                   "⋆_{n−1}⁻¹ B q, (B q)_σ = o_σ q̄_σ on each border (n−1)-simplex σ (q̄_σ: the mean over its "
                   "vertices; o_σ = ±1: its orientation against the outward one), 0 inside: ⟨border(q), v⟩ ≈ "
                   "∫_∂Ω q tr v, the boundary term of integrating by parts — where natural border values enter a "
                   "weak form (Darcy's pressure)",
                   _border_kind, None, _border_linear))
_register(Operator("interior", (2,), "vector (or 1-form), primal 1-form → dual 0-form",
                   "i_X ω = X · ω♯ in each top simplex (a 1-form velocity is taken through ♯)",
                   _interior_kind, lambda ops, kinds, X, w: discrete.interior_1(ops.K, _as_vectors(ops, kinds[0], X), w),
                   derivative=vector_derivatives.interior_derivative))
_register(Operator("lie", (2,), "vector (or 1-form), primal 0- or 1-form → the same form",
                   "L_X u = X·∇u per top simplex, volume-averaged to the vertices (centred advection); on 1-forms "
                   "Cartan's L_X ω = i_X dω + d i_X ω",
                   _lie_kind, _lie_evaluate, fixed_first=_lie_fixed_first, derivative=vector_derivatives.lie_derivative))
_register(Operator("norm", (1,), "vector → dual 0-form; form → number",
                   "|X| per top simplex; ‖u‖ = √⟨u, u⟩ for a form", _norm_kind, _norm_evaluate,
                   derivative=vector_derivatives.norm_derivative))
_register(Operator("normalize", (1,), "vector → vector",
                   "X/|X| per top simplex, and 0 where X = 0 (where the direction is undefined: the heat method's "
                   "X = −∇u/|∇u| where ∇u = 0, as Crane et al. define it)", _normalize_kind,
                   lambda ops, kinds, x: discrete.normalize(x), derivative=vector_derivatives.normalize_derivative))
_register(Operator("integral", (1,), "0-form or n-form (primal or dual) → number",
                   "Σ ⋆0 u for a primal 0-form (the configured ⋆0); Σ u for an n-form", _integral_kind,
                   lambda ops, kinds, x: integral(ops, kinds[0], x)))
_register(Operator("inner", (2,), "two forms of one kind (or two vectors) → number",
                   "⟨a, b⟩ = aᵀ ⋆_k b (eq. 4.15); dual forms aᵀ ⋆⁻¹ b", _inner_kind,
                   lambda ops, kinds, a, b: inner_product(ops, kinds[0], a, b)))
_register(Operator("max", (1, 2), "form → number (largest value); two forms/numbers → value by value",
                   "max over the values, or the larger of two values at each simplex",
                   _reduction_or_pointwise("max"), _reduction_or_pointwise_evaluate(np.maximum, np.max),
                   derivative=_larger_derivative(larger=True), pointwise=True))
_register(Operator("min", (1, 2), "form → number (smallest value); two forms/numbers → value by value",
                   "min over the values, or the smaller of two values at each simplex",
                   _reduction_or_pointwise("min"), _reduction_or_pointwise_evaluate(np.minimum, np.min),
                   derivative=_larger_derivative(larger=False), pointwise=True))
_register(Operator("mean", (1,), "form → number", "the arithmetic mean of the values (unweighted)",
                   _reduction_or_pointwise("mean"), _reduction_or_pointwise_evaluate(None, np.mean)))
_register(Operator("vertex", (1,), "number i → primal 0-form",
                   "the indicator of vertex i (1 there, 0 elsewhere): a point source", _vertex_kind,
                   _vertex_evaluate))
def _explicit_kind(args, n):
    return args[0]


_register(Operator("explicit", (1,), "anything → the same",
                   "the argument's value at the start of the step: a term under explicit(·) is never put into an "
                   "implicit integrator's matrix (imex splittings: s*laplacian(c) - D*laplacian(explicit(s*c)) "
                   "stabilizes; convex splitting); the identity for every other use",
                   _explicit_kind, lambda ops, kinds, x: x,
                   derivative=lambda ops, kinds, values, i: np.ones_like(np.asarray(values[0], dtype=np.float64)),
                   pointwise=True))

for _name, _function in POINTWISE.items():
    _register(pointwise(_name, _function, POINTWISE_DERIVATIVES[_name], f"{_name} of each value"))

# rotating shallow water (TRiSK): mass_flux, kinetic_energy, vorticity, kite_average, coriolis; Robin borders: border_mass
for _operator in sphere_operators.built_in_operators() + sphere_functions.built_in_operators() + \
        robin.built_in_operators():
    _register(_operator)

#: other spellings of the operators
ALIASES = {"codiff": "codifferential", "delta": "codifferential", "hodge": "star", "star_inv": "inv_star",
           "laplace": "laplacian", "avg": "average", "interior_product": "interior"}


#: the entry-point group through which an installed package adds operators (docs/extending.md)
ENTRY_POINT_GROUP = "decrun.operators"
#: names an operator may not take: the language's own words and built-in values
_NOT_OPERATOR_NAMES = {"dt", "solve", "x", "y", "z", "t", "h", "area", "pi", "random"}
_plugins_loaded: list[str] = []


class PluginError(ConfigError):
    """An operator plugin that cannot be loaded or registered: one line naming its entry point."""


def register(operator: Operator, source: str = "decrun") -> None:
    """Add ``operator`` to :data:`OPERATORS` (the one table every pass reads: typing,
    evaluation, linear blocks, derivatives, the docs' table). ``source`` names where it comes
    from in a refusal. A plugin may not replace a built-in operator, an alias or a reserved name."""
    name = operator.name
    if not isinstance(name, str) or not name.isidentifier() or name.startswith("_"):
        raise PluginError(f"{source}: an operator's name is a letter followed by letters, digits or '_', got {name!r}")
    if name in BUILT_IN or name in ALIASES or name in _NOT_OPERATOR_NAMES:
        raise PluginError(f"{source}: the operator name {name!r} is decrun's own (a built-in operator or name); "
                          f"rename the plugin's operator, e.g. {name}_2")
    if not operator.arity or not all(isinstance(count, int) and count >= 1 for count in operator.arity):
        raise PluginError(f"{source}: operator {name!r} needs arity, a tuple of argument counts ≥ 1, got "
                          f"{operator.arity!r}")
    if operator.evaluate is None and operator.linear is None:
        raise PluginError(f"{source}: operator {name!r} has neither evaluate nor linear; give it one of them")
    OPERATORS[name] = operator


def load_plugins() -> list[str]:
    """Register the operators of every installed package's entry points in the group
    :data:`ENTRY_POINT_GROUP` (found with :func:`importlib.metadata.entry_points`), once per
    process; each entry point names an :class:`Operator`, a list of them, or a function
    returning either. Returns the names registered from plugins. A plugin that fails to load
    is a one-line :class:`PluginError` naming its entry point and package."""
    if _plugins_loaded:
        return list(_plugins_loaded[1:])
    from importlib.metadata import entry_points

    names = []
    for entry in entry_points(group=ENTRY_POINT_GROUP):
        package = getattr(entry.dist, "name", None) or "its package"
        source = f"operator plugin {entry.name} = {entry.value} (entry point group {ENTRY_POINT_GROUP}, {package})"
        try:
            loaded = entry.load()
            operators = loaded() if callable(loaded) and not isinstance(loaded, Operator) else loaded
        except Exception as error:  # noqa: BLE001 - any failure of a user's package: one line naming it
            first = (str(error).splitlines() or [""])[0]
            raise PluginError(f"{source}: cannot be loaded ({type(error).__name__}: {first}); fix or uninstall "
                              f"{package}") from None
        for operator in [operators] if isinstance(operators, Operator) else list(operators):
            if not isinstance(operator, Operator):
                raise PluginError(f"{source}: gives a {type(operator).__name__}, not a "
                                  "decrun.methods.model.operators.Operator")
            register(operator, source)
            names.append(operator.name)
    _plugins_loaded[:] = ["loaded", *names]
    return names


def reference_table() -> str:
    """The language reference as a markdown table (operator, degree rule, discrete definition),
    generated from :data:`OPERATORS` (decrun's own operators; a plugin's are in its docs)."""
    def cell(text: str) -> str:  # a | inside a cell (|⋆σ|/|σ|) would end the column
        return text.replace("|", "\\|")

    rows = ["| operator | takes → gives | discrete definition |", "|---|---|---|"]
    for operator in OPERATORS.values():
        if operator.name not in BUILT_IN:
            continue
        rows.append(f"| `{operator.name}` | {cell(operator.takes)} | {cell(operator.definition)} |")
    return "\n".join(rows)
