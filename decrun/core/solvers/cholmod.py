"""``solver=cholmod``: sparse Cholesky (SuiteSparse CHOLMOD), SPD only.

A = L Lᵀ once (fill-reducing ordering), two triangular solves per right-hand side. The matrix
must be symmetric (checked: CHOLMOD reads one triangle only) and positive definite (CHOLMOD
reports otherwise; the error names ``solver=direct``).

Two Python bindings of CHOLMOD, chosen by ``backend`` (``auto``: the first installed):

``sksparse``  scikit-sparse: CHOLMOD's *supernodal* factorization (dense BLAS-3 blocks), the
              faster one — about half the CPU of cholespy's on a 655k-vertex heat matrix
              (``benchmarks/bench_solvers.py``). It builds against the system's SuiteSparse
              (Debian 12: ``apt-get install libsuitesparse-dev``, then
              ``pip install "scikit-sparse<0.5"``), so it is not a dependency.
``cholespy``  the cholespy wheel (a dependency: installs everywhere). It compiles CHOLMOD with
              the *simplicial* factorization and nested-dissection ordering fixed, hence its
              larger cost on big matrices; the solves are as fast.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
import os
import sys
import warnings
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from decrun.core.choices import Choice
from decrun.core.solvers.base import Solver
from decrun.errors import ConfigError, SolverError

__all__ = ["CholmodSolver", "CholmodBackend", "asymmetry", "quiet_stdout", "installed_backends", "cholesky_factor",
           "cholesky_solve"]

SYMMETRY_TOL = 1e-12  # max |A − Aᵀ| relative to max |A| accepted as symmetric (round-off)


def asymmetry(A: sp.csr_matrix) -> float:
    """max |A − Aᵀ| / max |A| (0 for an exactly symmetric matrix). A canonical CSR matrix whose
    transpose has its pattern (the usual symmetric system) compares the two value arrays entry
    by entry — Aᵀ in CSR has sorted indices, so equal patterns pair the same (i, j) — without
    forming A − Aᵀ."""
    scale = float(np.abs(A.data).max()) if A.nnz else 0.0
    if not scale > 0:
        return 0.0
    if A.format == "csr" and A.has_canonical_format:
        transpose = A.T.tocsr()
        if np.array_equal(A.indptr, transpose.indptr) and np.array_equal(A.indices, transpose.indices):
            return float(np.abs(A.data - transpose.data).max()) / scale
    difference = A - A.T
    return float(np.abs(difference.data).max()) / scale if difference.nnz else 0.0


@contextlib.contextmanager
def quiet_stdout():
    """Silence file descriptor 1 (CHOLMOD prints its 'not positive definite' warning there)."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        with open(os.devnull, "w") as sink:
            os.dup2(sink.fileno(), 1)
            yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


class CholmodBackend(Choice):
    """The binding of CHOLMOD that factorizes (module docstring)."""

    auto = "auto"
    sksparse = "sksparse"
    cholespy = "cholespy"


#: the bindings in order of preference (the faster first)
PREFERENCE = (CholmodBackend.sksparse, CholmodBackend.cholespy)


@functools.lru_cache(maxsize=None)
def installed_backends() -> tuple[CholmodBackend, ...]:
    """The CHOLMOD bindings importable here, the faster first."""
    found = []
    for backend in PREFERENCE:
        try:
            importlib.import_module("sksparse.cholmod" if backend is CholmodBackend.sksparse else "cholespy")
        except ImportError:
            continue
        found.append(backend)
    return tuple(found)


def _backend(backend: CholmodBackend | str) -> CholmodBackend:
    """``backend`` resolved: ``auto`` → the fastest installed; a ConfigError naming the key and
    the override that works when the one asked for is not installed."""
    backend = CholmodBackend.of(backend, "solver.backend")
    installed = installed_backends()
    if backend is CholmodBackend.auto:
        if not installed:
            raise SolverError("solver=cholmod needs the package cholespy: install it with `pip install cholespy`, "
                              "or run with solver=direct")
        return installed[0]
    if backend not in installed:
        how = ("it builds against SuiteSparse: apt-get install libsuitesparse-dev && pip install 'scikit-sparse<0.5'"
               if backend is CholmodBackend.sksparse else "pip install cholespy")
        other = next((b for b in installed if b is not backend), None)
        fix = f"solver.backend={other}" if other else "solver=direct"
        raise ConfigError(f"solver.backend={backend}: {backend} is not installed ({how}); use {fix}")
    return backend


@dataclass
class CholmodSolver(Solver):
    """Cholesky factorization once in ``factorize``; each solve two triangular solves.

    backend : which binding of CHOLMOD factorizes (module docstring); ``auto`` the fastest installed
    """

    name = "cholmod"
    needs_spd = True
    backend: CholmodBackend = CholmodBackend.auto

    def __post_init__(self):
        super().__post_init__()
        self.backend = CholmodBackend.of(self.backend, "solver.backend")
        _backend(self.backend)  # a binding that is not installed: the hint now, before any mesh work

    def _prepare(self, A) -> None:
        self._factor = cholesky_factor(A, self.name, self.backend)

    def _solve_block(self, b: np.ndarray) -> np.ndarray:
        return cholesky_solve(self._factor, np.ascontiguousarray(b))


class _Supernodal:
    """A scikit-sparse factor with cholespy's ``solve(b, x)`` (x ← A⁻¹ b)."""

    def __init__(self, factor):
        self.factor = factor

    def solve(self, b: np.ndarray, x: np.ndarray) -> None:
        x[...] = self.factor(b)


def cholesky_factor(A: sp.csr_matrix, name: str, backend: CholmodBackend | str = CholmodBackend.auto,
                    skew: float | None = None):
    """The CHOLMOD factor of the symmetric positive definite CSR matrix ``A`` (an object with
    ``solve(b, x)``), by ``backend`` (``auto``: the fastest installed); SolverError (naming
    ``solver=direct``) when ``A`` is not symmetric or not positive definite. ``skew`` is
    :func:`asymmetry` of ``A`` when the caller has measured it already (None: measured here)."""
    backend = _backend(backend)
    skew = asymmetry(A) if skew is None else skew
    if skew > SYMMETRY_TOL:
        raise SolverError(f"{name} solver: the {A.shape} matrix is not symmetric (max |A − Aᵀ| = {skew:.2g} × max |A|); "
                          "Cholesky needs a symmetric positive definite matrix: use solver=direct")
    if backend is CholmodBackend.sksparse:
        from sksparse.cholmod import CholmodNotPositiveDefiniteError, cholesky

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error")  # CHOLMOD's warnings (e.g. not positive definite) are failures
                return _Supernodal(cholesky(sp.csc_matrix(A), mode="supernodal"))
        except (CholmodNotPositiveDefiniteError, Warning) as exc:
            raise SolverError(f"{name} solver: cannot factorize the {A.shape} matrix: {str(exc).splitlines()[0]} "
                              "(Cholesky needs a positive definite matrix: use solver=direct)") from None
    import cholespy

    A = sp.csr_matrix(A)
    A.sort_indices()
    try:
        with quiet_stdout():
            return cholespy.CholeskySolverD(A.shape[0], A.indptr.astype(np.int32), A.indices.astype(np.int32),
                                            np.ascontiguousarray(A.data), cholespy.MatrixType.CSR)
    except ValueError as exc:  # "Matrix is not positive definite!"
        raise SolverError(f"{name} solver: cannot factorize the {A.shape} matrix: {exc} "
                          "(Cholesky needs a positive definite matrix: use solver=direct)") from None


def cholesky_solve(factor, b: np.ndarray) -> np.ndarray:
    """x with A x = b for a ``factor`` of A (:func:`cholesky_factor`); b (n,) or (n, m) C-contiguous float64."""
    x = np.empty_like(b)
    factor.solve(b, x)
    if not np.all(np.isfinite(x)):
        raise SolverError("cholmod solver: the solution is not finite (matrix numerically singular?)")
    return x
