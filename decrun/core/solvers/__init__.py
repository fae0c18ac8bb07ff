"""Sparse linear solvers behind one interface: ``factorize(A)`` once, ``solve(b)`` many.

>>> solver = make_solver("auto")
>>> solver.factorize(A)        # A: (n, n) scipy.sparse
>>> x = solver.solve(b)        # b: (n,) or (n, m)

Every solver is a dataclass whose fields are its options (the keys of
``conf/solver/<name>.yaml``, declared once here); ``solver.fresh()`` is a new, unfactorized
solver with the same options — the runner's ``ctx.new_solver()``. ``factorize`` remembers a
fingerprint of the matrix it prepared: calling it again with the same matrix is free.

======== ======================================== =====================================
module   method                                   options
======== ======================================== =====================================
auto     the default: CHOLMOD Cholesky for SPD     ``permc_spec`` (of the LU)
         matrices, SuperLU LU for the rest
cholmod  CHOLMOD (cholespy wheel), L Lᵀ once       none
direct   scipy SuperLU, LU once                    ``permc_spec``
cg       conjugate gradients, Jacobi precond.      ``tol`` (relative residual), ``maxiter``,
                                                   ``preconditioner`` (jacobi | none)
amg      pyamg multigrid hierarchy (built once)    ``tol``, ``maxiter``, ``method``, ``accel``
         as preconditioner of a Krylov method
pardiso  MKL PARDISO via pypardiso, LU once        ``matrix_type``
======== ======================================== =====================================

``cholmod``, ``cg`` and ``amg`` need a symmetric positive definite matrix
(``Solver.needs_spd``); a solve that does not reach ``tol`` raises :class:`SolverError`. The shared kernels — a singular
PSD solve by shift-and-refine, and a solve with fixed values (condensation) — are in
:mod:`decrun.core.solvers.kernels`.
"""

from __future__ import annotations

from decrun.core.solvers.base import Solver
from decrun.core.solvers.kernels import SingularSolve, constant_kernel, solve_with_fixed

__all__ = ["Solver", "SingularSolve", "constant_kernel", "solve_with_fixed", "make_solver", "solver_factory"]


def make_solver(name: str = "auto", **options) -> Solver:
    """A solver by name (``auto`` | ``cholmod`` | ``direct`` | ``cg`` | ``amg`` | ``pardiso``, or a dotted class path)
    with its options; unknown options are a :class:`decrun.errors.ConfigError`."""
    from dataclasses import fields

    from decrun.core.plugins import resolve
    from decrun.errors import ConfigError

    cls = type(resolve(name, Solver, "decrun.core.solvers", "solver")) if options else None
    if cls is None:
        return resolve(name, Solver, "decrun.core.solvers", "solver")
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(options) - known)
    if unknown:
        raise ConfigError(f"solver={name}: unknown option(s) {unknown}; it has {sorted(known)}")
    return cls(**options)


def solver_factory(solver=None):
    """A callable returning a fresh, unfactorized solver for every linear system.

    ``solver`` may be None (``auto``), a name, a :class:`Solver` (its options are reused via
    ``solver.fresh()``, never a deep copy) or already a factory.
    """
    if solver is None or isinstance(solver, str):
        name = solver or "auto"
        return lambda: make_solver(name)
    if isinstance(solver, Solver):
        return solver.fresh
    if callable(solver):
        return solver
    raise TypeError(f"expected a solver name, a Solver or a factory, got {solver!r}")
