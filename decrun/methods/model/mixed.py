"""The Galerkin (Whitney) Laplacian of k-forms, k ≥ 1, in implicit integrators: its mixed form.

Under a non-diagonal ⋆ (``operator=whitney``) the weak Laplacian of a primal k-form v,

    ⋆_k Δ v = B ⋆_{k−1}⁻¹ Bᵀ v + C v,   B = ⋆_k d_{k−1},   C = d_kᵀ ⋆_{k+1} d_k,

is dense (⋆_{k−1}⁻¹ is the inverse of a mass matrix), so the lowering keeps ``laplacian(v)`` as
an explicit term and implicit steppers refused it. Written with the codifferential as an
unknown of its own, p = δv = ⋆_{k−1}⁻¹ Bᵀ v (Arnold–Falk–Winther's mixed form), every matrix is
sparse: an evolution ``dt(u) = … + c·laplacian(v)`` (c a constant; ``laplacian`` = −Δ,
``laplace_de_rham`` = +Δ) reads

    ⋆_k u' = … − c (B p + C v)
         0 = Bᵀ v − ⋆_{k−1} p

— M y' = L y + g(y, t) over y = (the free values of the evolved fields, p), with M = diag(the
rows' masses, 0) and L sparse and constant. For the linear constraint, an implicit Runge–Kutta
method with an invertible A (Gauss, Radau IIA), implicit Euler and Crank–Nicolson (whose
constraint row 0 = ½(g⁺ + gⁿ) keeps g = 0 from consistent data) give the evolved values of the
dense ODE ⋆_k u' = −c ⋆_k Δ u exactly: p is δu at every stage. :class:`MixedProblem` is that
``Problem``; :func:`implicit_problem` hands it to the integrators that take M (implicit Euler,
Crank–Nicolson, the implicit tableaux), and the plain
:class:`~decrun.methods.model.problem.ModelProblem` otherwise (explicit steppers and ark_imex
then evaluate the Laplacian explicitly, with factorized solves, as before). M is singular here:
a stepper that solves with M alone cannot take it (one line, :func:`refuse_adaptive` for
SciPy's BDF/Radau, which take no mass matrix).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.jacobian import derivative
from decrun.methods.model.kinds import NUMBER
from decrun.methods.model.language import Binary, Call, ModelError, Name, Negate, Node, Number, to_text
from decrun.methods.model.operators import ALIASES, OPERATORS
from decrun.methods.model.problem import ModelProblem

__all__ = ["GalerkinLaplacian", "galerkin_laplacians", "MixedProblem", "implicit_problem", "refuse_adaptive"]

#: the Laplacians and their sign against Δ = dδ + δd
_SIGNS = {"laplacian": -1.0, "laplace_de_rham": 1.0}


@dataclass(frozen=True)
class GalerkinLaplacian:
    """One explicit term ``sign · coefficient · laplacian(field)`` of ``dt(row)`` (index ``index``
    in the lowering's ``rest_trees[row]``) whose weak matrix is dense; ``scale`` = sign ·
    coefficient · (−1 for ``laplacian``, +1 for ``laplace_de_rham``): the term is
    scale · Δ field."""

    row: str
    index: int
    field: str
    degree: int
    scale: float
    term: Node


def _match(model, term: Node) -> tuple[float, Node | None, str] | None:
    """(the operator's sign, the coefficient's tree or None, the field) of a term
    ``[c *] laplacian(v)`` / ``laplacian(v) [* c]`` / ``-laplacian(v)``, else None."""
    compiler = model.compiler
    if isinstance(term, Negate):
        inner = _match(model, term.operand)
        return None if inner is None else (-inner[0], inner[1], inner[2])
    if isinstance(term, Binary) and term.op in "*/":
        for call, other in ((term.right, term.left), (term.left, term.right)) if term.op == "*" else \
                ((term.left, term.right),):
            inner = _match(model, call)
            if inner is not None and inner[1] is None and compiler.is_static(other) \
                    and compiler.kind(other, "") == NUMBER:
                return inner[0], other if term.op == "*" else Binary("/", Number(1.0), other), inner[2]
        return None
    if isinstance(term, Call) and ALIASES.get(term.function, term.function) in _SIGNS and len(term.args) == 1:
        (argument,) = term.args
        if isinstance(argument, Name) and argument.name in model.evolved:
            return _SIGNS[ALIASES.get(term.function, term.function)], None, argument.name
    return None


def galerkin_laplacians(model) -> list[GalerkinLaplacian]:
    """The explicit terms of the model's evolutions that are a constant times the Laplacian of an
    evolved primal k-form (k ≥ 1) whose weak matrix the lowering could not make sparse (a
    non-diagonal ⋆_{k−1}); empty for every other model."""
    ops, compiler, evolution = model.ops, model.compiler, model.evolution
    if ops.intrinsic is not None:
        return []
    found = []
    for row in evolution.names:
        for index, (sign, term) in enumerate(evolution.rest_trees[row]):
            matched = _match(model, term)
            if matched is None:
                continue
            operator_sign, coefficient, field = matched
            kind = model.kinds[field]
            lowering = OPERATORS["laplacian" if operator_sign < 0 else "laplace_de_rham"].linear
            if kind.dual or kind.degree < 1 or lowering is None or lowering(ops, kind) is not None \
                    or ops.dec.star_is_diagonal(kind.degree - 1) or model.kinds[row] != kind:
                continue
            value = 1.0
            if coefficient is not None:
                value = float(compiler.compile(coefficient, "")(compiler.static_env))
            found.append(GalerkinLaplacian(row, index, field, kind.degree, sign * value * operator_sign, term))
    return found


class MixedProblem:
    """The ``Problem`` M y' = f(y, t) of a model with :func:`galerkin_laplacians`, over
    y = (the free values of the evolved fields, p = δv for each such field v) (module docstring)."""

    def __init__(self, model, laplacians: list[GalerkinLaplacian]):
        self.model, self.laplacians = model, laplacians
        self.base = base = ModelProblem(model)
        evolution, dec = model.evolution, model.ops.dec
        names = evolution.names
        for item in laplacians:
            if item.field in model.fixed:
                raise ModelError(f"{model.spec.key}.fields.{item.field}.dirichlet: the Galerkin Laplacian "
                                 f"{to_text(item.term)} takes natural border values in implicit integrators; drop "
                                 f"the Dirichlet values or use an explicit integrator (`{model.spec.key}.integrator=rk4`)")
        self.fields = sorted({item.field for item in laplacians}, key=names.index)
        degree = {item.field: item.degree for item in laplacians}
        self.codifferential_sizes = {v: dec.K.num_simplices(degree[v] - 1) for v in self.fields}
        offsets = np.cumsum([evolution.total] + [self.codifferential_sizes[v] for v in self.fields])
        self.p_slices = {v: slice(offsets[i], offsets[i + 1]) for i, v in enumerate(self.fields)}
        augmented = int(offsets[-1])
        self.lower_masses = {v: dec.star(degree[v] - 1).tocsr() for v in self.fields}
        self.couplings = {v: (dec.star(degree[v]) @ dec.d(degree[v] - 1)).tocsr() for v in self.fields}  # B
        # the weak rows: a row with an identity mass (strong) is multiplied by ⋆_k
        rows_with = {item.row for item in laplacians}
        scaled = {u: u in rows_with and (evolution.mass[u] - sp.identity(evolution.sizes[u])).count_nonzero() == 0
                  for u in names}
        #: each row's mass: the lowering's, or ⋆_k for a strong row (identity mass) that a Laplacian joins
        self.row_mass = row_mass = {u: dec.star(model.kinds[u].degree).tocsr() if scaled[u] else evolution.mass[u]
                                    for u in names}
        # L in blocks: the fields' rows and columns, then one pair per p
        order = names + [("p", v) for v in self.fields]
        sizes = [evolution.sizes[u] for u in names] + [self.codifferential_sizes[v] for v in self.fields]
        blocks: dict = {}

        def add(row, col, matrix):
            key = (order.index(row), order.index(col))
            blocks[key] = matrix if key not in blocks else blocks[key] + matrix
        for (u, v), A in evolution.blocks.items():
            add(u, v, row_mass[u] @ A if scaled[u] else A)
        for item in laplacians:
            k = item.degree
            if k < model.ops.n:
                add(item.row, item.field, item.scale * (dec.d(k).T @ dec.star(k + 1) @ dec.d(k)))
            add(item.row, ("p", item.field), item.scale * self.couplings[item.field])
        for v in self.fields:
            add(("p", v), v, self.couplings[v].T)
            add(("p", v), ("p", v), -self.lower_masses[v])
        self.stiff_full = _assemble(blocks, sizes)
        self.free = np.concatenate([base.free, np.arange(evolution.total, augmented)])
        self.size = int(self.free.size)
        mass_full = sp.block_diag([row_mass[u] for u in names] + [sp.csr_matrix((augmented - evolution.total,) * 2)],
                                  format="csr")
        self.mass_full = mass_full
        self.mass = mass_full[self.free][:, self.free].tocsr()
        self.stiff = self.stiff_full[self.free][:, self.free].tocsr()
        mixed = {(item.row, item.index) for item in laplacians}
        self.rest = {u: [(sign, closure) for i, (sign, closure) in enumerate(evolution.rest[u]) if (u, i) not in mixed]
                     for u in names}
        self.rest_trees = {u: [(sign, tree) for i, (sign, tree) in enumerate(evolution.rest_trees[u])
                               if (u, i) not in mixed] for u in names}
        self._jacobians: dict | None = None

    # ------------------------------------------------------------------ states
    def full(self, y: np.ndarray) -> np.ndarray:
        """(total + Σ n_{k−1},) the evolved values with the border values inserted, then p."""
        n = self.base.size
        return np.concatenate([self.base.full(y[:n]), y[n:]])

    def state(self, y: np.ndarray) -> dict[str, np.ndarray]:
        """The model's state of ``y`` (field → values; p is not a field)."""
        return self.base.state(y[:self.base.size])

    def free_values(self, state: dict) -> np.ndarray:
        """y of a state: its free values, and p = ⋆_{k−1}⁻¹ Bᵀ v (consistent data)."""
        parts = [self.base.free_values(state)]
        for v in self.fields:  # ⋆_{k−1}⁻¹: DEC's factorized solve, made once
            k = self.model.kinds[v].degree
            parts.append(np.asarray(self.model.ops.dec.star_solve(k - 1, self.couplings[v].T @ state[v]),
                                    dtype=np.float64))
        return np.concatenate(parts)

    # ------------------------------------------------------------------ the Problem interface
    def _rest(self, env: dict) -> np.ndarray:
        evolution = self.model.evolution
        parts = []
        for u in evolution.names:
            value = 0.0
            for sign, closure in self.rest[u]:
                value = value + sign * closure(env)
            parts.append(self.row_mass[u] @ np.broadcast_to(np.asarray(value, dtype=np.float64), (evolution.sizes[u],)))
        return np.concatenate(parts + [np.zeros(self.stiff_full.shape[0] - evolution.total)])

    def f(self, y: np.ndarray, t: float) -> np.ndarray:
        """(size,) L_full X + [M R_other; 0] at the free rows."""
        X = self.full(y)
        env = self.model.environment(self.model.evolution.unstack(X[:self.model.evolution.total]), t)
        return (self.stiff_full @ X + self._rest(env))[self.free]

    def nonstiff(self, y: np.ndarray, t: float) -> np.ndarray:
        """(size,) g = f − L y."""
        return self.f(y, t) - self.stiff @ y

    def check_jacobian(self) -> None:
        """The derivative closures of the other explicit terms (refused now, one line, if one has none)."""
        if self._jacobians is not None:
            return
        model = self.model
        names = set(model.evolution.names)
        where = {e.target: e.where for e in model.equations if e.kind == "evolution"}
        out: dict = {}
        for u, terms in self.rest_trees.items():
            for sign, term in terms:
                for v in sorted(model.compiler.reads(term) & names):
                    out.setdefault((u, v), []).append((sign, derivative(model.compiler, term, v, where[u])))
        self._jacobians = out

    def jacobian(self, y: np.ndarray, t: float) -> sp.csr_matrix:
        """(size, size) the exact ∂f/∂y: L + M ∂R_other/∂y."""
        self.check_jacobian()
        assert self._jacobians is not None
        if not self._jacobians:
            return self.stiff
        evolution = self.model.evolution
        X = self.full(y)
        env = self.model.environment(evolution.unstack(X[:evolution.total]), t)
        names = evolution.names
        sizes = [evolution.sizes[u] for u in names] + [self.codifferential_sizes[v] for v in self.fields]
        blocks = {(names.index(u), names.index(v)): self.row_mass[u] @ sum(sign * closure(env) for sign, closure in parts)
                  for (u, v), parts in self._jacobians.items()}
        full = self.stiff_full + _assemble(blocks, sizes)
        return full[self.free][:, self.free].tocsr()


def _assemble(blocks: dict, sizes: list[int]) -> sp.csr_matrix:
    """One sparse matrix from ``blocks`` {(i, j): matrix} over blocks of ``sizes`` (zero elsewhere)."""
    count = len(sizes)
    grid = [[blocks.get((i, j)) for j in range(count)] for i in range(count)]
    for i in range(count):
        if grid[i][i] is None:  # bmat needs every row and column's size
            grid[i][i] = sp.csr_matrix((sizes[i], sizes[i]))
    return sp.bmat(grid, format="csr")


def implicit_problem(model):
    """The ``Problem`` an integrator that takes M (implicit Euler, Crank–Nicolson, the implicit
    tableaux) steps: :class:`MixedProblem` when the model has :func:`galerkin_laplacians`, else
    the model's own :attr:`~decrun.methods.model.system.CompiledModel.problem`."""
    laplacians = galerkin_laplacians(model)
    return MixedProblem(model, laplacians) if laplacians else model.problem


def refuse_adaptive(model, scheme: str) -> None:
    """SciPy's BDF and Radau take no mass matrix: a model with :func:`galerkin_laplacians` is
    refused in one line naming the term and the integrators that run it."""
    laplacians = galerkin_laplacians(model)
    if laplacians:
        item = laplacians[0]
        where = next(e.where for e in model.equations if e.kind == "evolution" and e.target == item.row)
        raise ModelError(f"{where}: {to_text(item.term)}: integrator={scheme} (SciPy's solve_ivp) takes no mass matrix "
                         f"and the Galerkin ⋆ of operator=whitney needs one (M y' = L y); use "
                         f"`{model.spec.key}.integrator=radau_iia` (order 5, L-stable) or "
                         f"`{model.spec.key}.integrator=crank_nicolson`")
