"""The lowering of a model's evolution equations, computed once per compiled model.

Every evolution ``dt(u) = F_u`` is split (:meth:`decrun.methods.model.compiler.Compiler.split`)
into blocks linear in the evolved fields with constant coefficients, ``⋆_k⁻¹ A_uv``, and the
rest R_u; row u multiplied by its mass ``M_u = ⋆_k`` reads ``M_u u' = Σ_v A_uv v + M_u R_u``.
:attr:`decrun.methods.model.system.CompiledModel.evolution` holds the one :class:`Evolution` of a
model: every integrator, the stability check and the Jacobians read it — none rebuilds it — and
this module imports no integrator (the integrators depend on the compiled model, not the reverse).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.language import ModelError

__all__ = ["Evolution"]


class Evolution:
    """The evolution equations of a :class:`~decrun.methods.model.system.CompiledModel` split
    for the implicit schemes: ``blocks[(u, v)]`` weak matrices A_uv, ``mass[u]`` the row's M_u
    (sparse), ``rest[u]``: [(sign, closure)] of the explicit terms and ``rest_trees[u]``."""

    def __init__(self, model):
        self.model = model
        compiler, ops = model.compiler, model.ops
        self.names = list(model.evolved)
        self.sizes = {name: model.kinds[name].size(ops.K) for name in self.names}
        offsets = np.cumsum([0] + [self.sizes[name] for name in self.names])
        self.slices = {name: slice(offsets[i], offsets[i + 1]) for i, name in enumerate(self.names)}
        self.total = int(offsets[-1])
        self.blocks, self.mass, self.rest, self.rest_trees = {}, {}, {}, {}
        unknowns = set(self.names)
        for equation in model.equations:
            if equation.kind != "evolution":
                continue
            u = equation.target
            blocks, rest = compiler.split(equation.rhs, unknowns)
            invs = {block.inv for block in blocks.values()} - {None}
            if len(invs) > 1:
                raise ModelError(f"{equation.where}: the linear terms of dt({u}) mix inverse stars {sorted(invs)}; "
                                 "write them over one ⋆ or use an explicit integrator")
            size = self.sizes[u]
            if invs:
                k = invs.pop()
                M = ops.dec.star(k).tocsr()
                for v, block in list(blocks.items()):
                    blocks[v] = block.A.tocsr() if block.inv is not None else (M @ block.A).tocsr()
            else:
                M = sp.identity(size, format="csr")
                blocks = {v: block.A.tocsr() for v, block in blocks.items()}
            self.mass[u] = M
            for v, A in blocks.items():
                self.blocks[(u, v)] = A
            self.rest_trees[u] = rest
            self.rest[u] = [(sign, compiler.compile(term, equation.where)) for sign, term in rest]
        self._mass_diagonal = {}
        for u, M in self.mass.items():
            M = sp.csr_matrix(M)
            M.sort_indices()
            n = M.shape[0]
            if M.nnz == n and np.array_equal(M.indptr, np.arange(n + 1)) and np.array_equal(M.indices, np.arange(n)):
                self._mass_diagonal[u] = M.data.copy()

    def apply_mass(self, u: str, value: np.ndarray) -> np.ndarray:
        """M_u value — a product with the diagonal when M_u is diagonal (⋆0, the circumcentric ⋆k)."""
        diagonal = self._mass_diagonal.get(u)
        if diagonal is not None:
            return diagonal * value
        return self.mass[u] @ value

    def reads_evolved(self, u: str) -> list:
        """The explicit terms of dt(u) that read an evolved field (not allowed in implicit schemes)."""
        compiler = self.model.compiler
        return [term for sign, term in self.rest_trees[u] if compiler.depends_on(term, set(self.names))]

    def rest_value(self, u: str, env: dict | None) -> np.ndarray:
        """R_u at ``env``: the sum of the explicit terms of dt(u) (zeros when there are none;
        ``env`` is None only where a model has no explicit term to read it)."""
        value = None
        for sign, closure in self.rest[u]:
            term = closure(env) if sign == 1 else sign * closure(env)
            value = term if value is None else value + term
        if value is None or np.ndim(value) == 0:  # no term, or only numbers
            return np.full(self.sizes[u], 0.0 if value is None else float(value))
        return value

    def matrix(self, alpha: float) -> sp.csr_matrix:
        """M − α A over all evolved fields (the block system)."""
        rows = []
        for u in self.names:
            row = []
            for v in self.names:
                block = self.blocks.get((u, v))
                part = None if block is None else -alpha * block
                if u == v:
                    part = self.mass[u] if part is None else self.mass[u] + part
                row.append(part)
            rows.append(row)
        return sp.bmat(rows, format="csr") if len(self.names) > 1 else sp.csr_matrix(rows[0][0])

    def apply_blocks(self, state: dict) -> dict:
        """Σ_v A_uv v for every row u."""
        out = {u: np.zeros(self.sizes[u]) for u in self.names}
        for (u, v), A in self.blocks.items():
            out[u] = out[u] + A @ state[v]
        return out

    def stack(self, values: dict) -> np.ndarray:
        return np.concatenate([np.asarray(values[name], dtype=np.float64) for name in self.names])

    def unstack(self, vector: np.ndarray) -> dict:
        return {name: vector[self.slices[name]] for name in self.names}

    def fixed(self) -> tuple[np.ndarray, np.ndarray]:
        """Indices in the stacked vector of the fixed values, and those values."""
        indices, values = [], []
        for name in self.names:
            if name in self.model.fixed:
                border, value = self.model.fixed[name]
                indices.append(border + self.slices[name].start)
                values.append(value)
        if not indices:
            return np.zeros(0, dtype=np.int64), np.zeros(0)
        return np.concatenate(indices), np.concatenate(values)
