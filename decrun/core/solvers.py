"""Sparse linear solvers behind one interface: ``factorize(A)`` once, ``solve(b)`` many.

>>> solver = make_solver("direct")
>>> solver.factorize(A)        # A: (n, n) scipy.sparse
>>> x = solver.solve(b)        # b: (n,) or (n, m)

``factorize`` remembers a fingerprint of the matrix it prepared: calling it again with the
same matrix (same sparsity and values) is free, so an application may call it every time
step without paying for a new factorization.

======== ======================================== =====================================
name     method                                   options (``conf/solver/<name>.yaml``)
======== ======================================== =====================================
direct   scipy SuperLU, LU once                    ``permc_spec``
cg       conjugate gradients, Jacobi precond.      ``tol`` (relative residual), ``maxiter``,
                                                   ``preconditioner`` (jacobi | none)
amg      pyamg multigrid hierarchy (built once)    ``tol``, ``maxiter``, ``method``, ``accel``
         as preconditioner of a Krylov method
pardiso  MKL PARDISO via pypardiso, LU once        ``matrix_type``
======== ======================================== =====================================

``cg`` and ``amg`` (with ``accel: cg``) need a symmetric positive definite matrix; a solve
that does not reach ``tol`` raises :class:`SolverError`. ``amg`` and ``pardiso`` need the
optional packages pyamg / pypardiso (extras ``decrun[amg]``, ``decrun[pardiso]``); without
them :func:`make_solver` raises :class:`SolverError` before any work is done.
"""

from __future__ import annotations

import hashlib

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from decrun.errors import ConfigError, SolverError


def _fingerprint(A: sp.csr_matrix) -> str:
    h = hashlib.sha1()
    h.update(repr(A.shape).encode())
    for array in (A.indptr, A.indices, A.data):
        h.update(np.ascontiguousarray(array).tobytes())
    return h.hexdigest()


class Solver:
    """Interface: ``factorize(A)`` stores what repeated solves with ``A`` need."""

    name = "base"

    def __init__(self):
        self._key: str | None = None
        self.shape: tuple[int, int] | None = None
        self.factorizations = 0  # how many times the matrix was actually prepared

    def factorize(self, A) -> "Solver":
        """Prepare repeated solves with the square sparse matrix ``A`` (n, n).

        A no-op when ``A`` equals (values and pattern) the matrix prepared last.
        """
        A = sp.csr_matrix(A, dtype=np.float64)
        if A.shape[0] != A.shape[1]:
            raise SolverError(f"{self.name} solver: matrix must be square, got {A.shape}")
        A.sum_duplicates()
        key = _fingerprint(A)
        if key == self._key:
            return self
        self._prepare(A)
        self._key, self.shape = key, A.shape
        self.factorizations += 1
        return self

    def solve(self, b: np.ndarray) -> np.ndarray:
        """Solve ``A x = b`` for ``b`` of shape (n,) or (n, m); returns x of b's shape."""
        if self._key is None:
            raise SolverError(f"{self.name} solver: solve() called before factorize()")
        b = np.asarray(b, dtype=np.float64)
        if b.shape[0] != self.shape[0]:
            raise SolverError(f"{self.name} solver: right-hand side has {b.shape[0]} rows, matrix {self.shape}")
        if b.ndim == 1:
            return self._solve_one(b)
        return np.column_stack([self._solve_one(b[:, j]) for j in range(b.shape[1])]).reshape(b.shape)

    def _prepare(self, A: sp.csr_matrix) -> None:
        raise NotImplementedError

    def _solve_one(self, b: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class DirectSolver(Solver):
    """scipy SuperLU: one LU factorization of ``A`` reused by every ``solve``."""

    name = "direct"

    def __init__(self, permc_spec: str = "COLAMD"):
        super().__init__()
        self.permc_spec = permc_spec
        self._lu = None

    def _prepare(self, A) -> None:
        try:
            self._lu = spla.splu(sp.csc_matrix(A), permc_spec=self.permc_spec)
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SolverError(f"direct solver: cannot factorize the {A.shape} matrix: {exc}") from exc

    def solve(self, b: np.ndarray) -> np.ndarray:
        if self._lu is None:
            raise SolverError("direct solver: solve() called before factorize()")
        b = np.asarray(b, dtype=np.float64)
        x = self._lu.solve(b)
        if not np.all(np.isfinite(x)):
            raise SolverError("direct solver: the solution is not finite (matrix numerically singular?)")
        return x


def _check_tol(name: str, tol: float, maxiter) -> None:
    if not tol > 0:
        raise ConfigError(f"solver.tol: must be > 0, got {tol}")
    if maxiter is not None and maxiter < 1:
        raise ConfigError(f"solver.maxiter: must be >= 1 or null, got {maxiter}")


class CGSolver(Solver):
    """Conjugate gradients with a Jacobi (diagonal) preconditioner, relative tolerance ``tol``.

    ``factorize`` stores ``A`` and the inverse diagonal; each solve iterates until
    ``||b - A x|| <= tol ||b||``.
    """

    name = "cg"

    def __init__(self, tol: float = 1e-10, maxiter: int | None = None, preconditioner: str = "jacobi"):
        super().__init__()
        _check_tol(self.name, tol, maxiter)
        if preconditioner not in ("jacobi", "none"):
            raise ConfigError(f"solver.preconditioner: choose jacobi or none, got {preconditioner!r}")
        self.tol, self.maxiter, self.preconditioner = tol, maxiter, preconditioner
        self.iterations: list[int] = []

    def _prepare(self, A) -> None:
        self._A = A
        self._M = None
        if self.preconditioner == "jacobi":
            diagonal = A.diagonal()
            if np.any(diagonal <= 0):
                i = int(np.flatnonzero(diagonal <= 0)[0])
                raise SolverError(f"cg solver: Jacobi needs a positive diagonal; A[{i},{i}] = {diagonal[i]:.3g}")
            inverse = 1.0 / diagonal
            self._M = spla.LinearOperator(A.shape, matvec=lambda x: inverse * x.ravel(), dtype=np.float64)

    def _solve_one(self, b):
        count = [0]
        x, info = spla.cg(self._A, b, rtol=self.tol, atol=0.0, maxiter=self.maxiter, M=self._M,
                          callback=lambda _: count.__setitem__(0, count[0] + 1))
        self.iterations.append(count[0])
        if info != 0 or not np.all(np.isfinite(x)):
            residual = np.linalg.norm(b - self._A @ x) / max(np.linalg.norm(b), np.finfo(float).tiny)
            raise SolverError(f"cg solver: no convergence to tol={self.tol:g} after {count[0]} iterations "
                              f"(relative residual {residual:.3g}; is the matrix SPD?)")
        return x


class AMGSolver(Solver):
    """pyamg algebraic multigrid: the hierarchy is built once in ``factorize``; each solve
    runs ``accel`` (cg by default) preconditioned by one V-cycle to relative tolerance ``tol``."""

    name = "amg"

    def __init__(self, tol: float = 1e-10, maxiter: int | None = None,
                 method: str = "smoothed_aggregation", accel: str = "cg"):
        super().__init__()
        try:
            import pyamg
        except ImportError:
            raise SolverError("solver=amg needs the optional package pyamg: pip install 'decrun[amg]'") from None
        _check_tol(self.name, tol, maxiter)
        builders = {"smoothed_aggregation": pyamg.smoothed_aggregation_solver, "ruge_stuben": pyamg.ruge_stuben_solver}
        if method not in builders:
            raise ConfigError(f"solver.method: choose one of {sorted(builders)}, got {method!r}")
        if accel not in ("cg", "gmres", "bicgstab", "none"):
            raise ConfigError(f"solver.accel: choose cg|gmres|bicgstab|none, got {accel!r}")
        self._build = builders[method]
        self.tol, self.maxiter, self.method, self.accel = tol, maxiter, method, accel

    def _prepare(self, A) -> None:
        self._A = A
        self._ml = self._build(A)

    def _solve_one(self, b):
        accel = None if self.accel == "none" else self.accel
        residuals: list[float] = []
        x = self._ml.solve(b, tol=self.tol, maxiter=self.maxiter or 500, accel=accel, residuals=residuals)
        norm_b = max(np.linalg.norm(b), np.finfo(float).tiny)
        residual = np.linalg.norm(b - self._A @ x) / norm_b
        if not np.all(np.isfinite(x)) or residual > 10 * self.tol:
            raise SolverError(f"amg solver: no convergence to tol={self.tol:g} after {len(residuals)} iterations "
                              f"(relative residual {residual:.3g})")
        return x


class PardisoSolver(Solver):
    """Intel MKL PARDISO (pypardiso): analysis + numerical factorization once, then
    forward/backward substitution per solve."""

    name = "pardiso"

    def __init__(self, matrix_type: int = 11):
        super().__init__()
        try:
            import pypardiso
        except ImportError:
            raise SolverError("solver=pardiso needs the optional package pypardiso: pip install 'decrun[pardiso]'") from None
        if matrix_type not in (11, 1):
            raise ConfigError(f"solver.matrix_type: only 11 (real nonsymmetric) and 1 (real structurally symmetric) "
                              f"are supported with full matrices, got {matrix_type}")
        self._pardiso = pypardiso.PyPardisoSolver(mtype=matrix_type)

    def _prepare(self, A) -> None:
        A = sp.csr_matrix(A)
        A.sort_indices()
        self._A = A
        try:
            self._pardiso.factorize(A)
        except Exception as exc:  # PyPardisoError
            raise SolverError(f"pardiso solver: cannot factorize the {A.shape} matrix: {exc}") from exc

    def solve(self, b):
        if self._key is None:
            raise SolverError("pardiso solver: solve() called before factorize()")
        b = np.asarray(b, dtype=np.float64)
        try:
            x = self._pardiso.solve(self._A, b)
        except Exception as exc:
            raise SolverError(f"pardiso solver: solve failed: {exc}") from exc
        return np.asarray(x).reshape(b.shape)


SOLVERS = {"direct": DirectSolver, "cg": CGSolver, "amg": AMGSolver, "pardiso": PardisoSolver}


def make_solver(name: str = "direct", **options) -> Solver:
    """Return a solver by name (``direct`` | ``cg`` | ``amg`` | ``pardiso``) with its options
    (the keys of ``conf/solver/<name>.yaml`` other than ``name``)."""
    try:
        cls = SOLVERS[name]
    except KeyError:
        raise ConfigError(f"solver.name: unknown solver {name!r}; choose one of {sorted(SOLVERS)}") from None
    try:
        return cls(**options)
    except TypeError as exc:
        raise ConfigError(f"solver={name}: bad options {sorted(options)}: {exc}") from None
