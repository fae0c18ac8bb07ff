"""A compiled model as the ODE system integrators step: ``M y' = f(y, t)`` over one stacked
vector of its free unknowns (the interface of issue 47 between the compiled model and the
integrators, ``Problem``).

The evolved fields are stacked in the order of their equations; the Dirichlet values are
condensed out (the border values stay fixed, so their rows are dropped and their columns move
into f: integrators never see borders). From the model's lowering
(:class:`~decrun.methods.model.lowering.Evolution`: row u reads ``M_u u' = Σ_v A_uv v + M_u R_u``):

- ``mass``: M = diag(M_u) restricted to the free values (``None`` when it is the identity);
- ``stiff``: L = [A_uv] restricted to the free values — the part of f linear with constant
  coefficients;
- ``f(y, t)``: the whole weak right side ``L_full x + M R(x, t)`` at the free rows, x = y with
  the border values inserted;
- ``jacobian(y, t)``: the exact ∂f/∂y, L + M ∂R/∂y with ∂R/∂y from the derivative pass
  (:mod:`decrun.methods.model.jacobian`: the registry's derivative rules, sparse);
- ``nonstiff(y, t)``: g = f − L y.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from decrun.methods.model.jacobian import derivative_values
from decrun.methods.model.jacobian_assembly import PatternAssembly, as_matrix

__all__ = ["ModelProblem"]


class ModelProblem:
    """The ``Problem`` of a compiled model (module docstring); ``size`` free unknowns."""

    def __init__(self, model):
        self.model = model
        self.evolution = evolution = model.evolution
        names = evolution.names
        fixed_index, fixed_values = evolution.fixed()
        self.fixed_index, self.fixed_values = fixed_index, fixed_values
        self.total = evolution.total
        self.free = np.setdiff1d(np.arange(self.total), fixed_index)
        self.size = int(self.free.size)
        self._mass_full = sp.block_diag([evolution.mass[u] for u in names], format="csr")
        rows = [[evolution.blocks.get((u, v)) for v in names] for u in names]
        for i, u in enumerate(names):
            if rows[i][i] is None:
                rows[i][i] = sp.csr_matrix((evolution.sizes[u], evolution.sizes[u]))
        self._stiff_full = sp.bmat(rows, format="csr")
        #: (total, total) the stiff blocks over every evolved value, border rows and columns included
        self.stiff_full = self._stiff_full
        mass = self._mass_full[self.free][:, self.free].tocsr()
        identity = (mass - sp.identity(self.size)).count_nonzero() == 0
        self.mass = None if identity else mass
        self.stiff = self._stiff_full[self.free][:, self.free].tocsr()
        self._rest_jacobians: dict | None = None
        self._assembly: PatternAssembly | None = None
        self._assembly_made = False

    # ------------------------------------------------------------------ states
    def full(self, y: np.ndarray) -> np.ndarray:
        """(total,) every evolved value: ``y`` at the free places, the border values at theirs."""
        x = np.empty(self.total)
        x[self.free] = y
        x[self.fixed_index] = self.fixed_values
        return x

    def state(self, y: np.ndarray) -> dict[str, np.ndarray]:
        """``y`` as the model's state (field → values, border values included)."""
        return self.evolution.unstack(self.full(y))

    def free_values(self, state: dict) -> np.ndarray:
        """The stacked free values of a state (the inverse of :meth:`state`)."""
        return self.evolution.stack(state)[self.free]

    def _rest(self, env: dict) -> np.ndarray:
        return np.concatenate([np.broadcast_to(self.evolution.rest_value(u, env), (self.evolution.sizes[u],))
                               for u in self.evolution.names])

    # ------------------------------------------------------------------ the Problem interface
    def f(self, y: np.ndarray, t: float) -> np.ndarray:
        """(size,) the weak right side at the free rows: L_full x + M R(x, t)."""
        x = self.full(y)
        env = self.model.environment(self.evolution.unstack(x), t)
        return (self._stiff_full @ x + self._mass_full @ self._rest(env))[self.free]

    def nonstiff(self, y: np.ndarray, t: float) -> np.ndarray:
        """(size,) g = f − L y."""
        return self.f(y, t) - self.stiff @ y

    def check_jacobian(self) -> None:
        """Build the derivative closures of every explicit term now: a term without an exact
        Jacobian is refused here (one line naming its equation), before any step."""
        if self._rest_jacobians is not None:
            return
        model, evolution = self.model, self.evolution
        names = set(evolution.names)
        out: dict = {}
        for equation in model.equations:
            if equation.kind != "evolution":
                continue
            u = equation.target
            for sign, term in evolution.rest_trees[u]:
                for v in sorted(model.compiler.reads(term) & names):
                    closure, rows, cols = derivative_values(model.compiler, term, v, equation.where)
                    if closure is not None:
                        out.setdefault((u, v), []).append((sign, closure, rows, cols))
        self._rest_jacobians = out

    def _rest_values(self, x: np.ndarray, t: float) -> dict:
        """{(u, v): ∂R_u/∂v} at the stacked values ``x`` as the derivative pass gives them (an
        array: a diagonal, or a sparse matrix)."""
        self.check_jacobian()
        assert self._rest_jacobians is not None
        env = self.model.environment(self.evolution.unstack(x), t)
        out = {}
        for key, parts in self._rest_jacobians.items():
            total = None
            for sign, closure, rows, cols in parts:
                D = closure(env)
                D = sign * (np.asarray(D, dtype=np.float64) if not sp.issparse(D) else D)
                if total is None:
                    total = D
                elif sp.issparse(total) or sp.issparse(D):
                    total = as_matrix(total, rows, cols) + as_matrix(D, rows, cols)
                else:
                    total = total + D
            out[key] = total
        return out

    def _pattern(self) -> PatternAssembly | None:
        """The pattern assembly of J (:mod:`decrun.methods.model.jacobian_assembly`), made once;
        None when a row mass is not diagonal or a block couples fields of different sizes."""
        if not self._assembly_made:
            self._assembly_made = True
            evolution = self.evolution
            mass = self._mass_full
            diagonal = mass.diagonal()
            same = all(evolution.sizes[u] == evolution.sizes[v] for u, v in self._rest_jacobians or {})
            usable = same and (mass - sp.diags(diagonal)).count_nonzero() == 0
            self._assembly = (PatternAssembly(self.stiff, list(self._rest_jacobians or {}), evolution.slices, self.free,
                                              self.total, diagonal) if usable else None)
        return self._assembly

    def jacobian(self, y: np.ndarray, t: float) -> sp.csr_matrix:
        """(size, size) the exact ∂f/∂y: L + M ∂R/∂y (sparse): in a pattern made once when every
        ∂R_u/∂v is a diagonal (:class:`~decrun.methods.model.jacobian_assembly.PatternAssembly`)."""
        self.check_jacobian()
        if not self._rest_jacobians:
            return self.stiff
        values = self._rest_values(self.full(y), t)
        pattern = self._pattern() if not any(sp.issparse(D) for D in values.values()) else None
        if pattern is not None:
            return pattern.assemble(values)
        rest = self._assemble_rest(values)
        full = self._stiff_full + self._mass_full @ rest
        return full[self.free][:, self.free].tocsr()

    def rest_jacobian(self, x: np.ndarray, t: float) -> sp.csr_matrix | None:
        """(total, total) ∂R/∂x of the explicit terms over every evolved value (border values
        included), at the stacked values ``x``; None when no explicit term reads an evolved field."""
        self.check_jacobian()
        if not self._rest_jacobians:
            return None
        return self._assemble_rest(self._rest_values(x, t))

    def _assemble_rest(self, values: dict) -> sp.csr_matrix:
        evolution = self.evolution
        names = evolution.names
        rows: list[list] = [[None for _ in names] for _ in names]
        for (u, v), D in values.items():
            rows[names.index(u)][names.index(v)] = as_matrix(D, evolution.sizes[u], evolution.sizes[v])
        for i, u in enumerate(names):
            if all(block is None for block in rows[i]):
                rows[i][i] = sp.csr_matrix((evolution.sizes[u], evolution.sizes[u]))
        for j, v in enumerate(names):
            if all(rows[i][j] is None for i in range(len(names))):
                rows[j][j] = sp.csr_matrix((evolution.sizes[v], evolution.sizes[v]))
        return sp.bmat(rows, format="csr")
