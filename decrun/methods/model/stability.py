"""Before a model runs: is its time step stable for every explicit term? (``app.stability_check``;
the diffusion-only limit is :func:`decrun.methods.model.integrators.explicit_stability_limit`.)

Two refusals, each one line naming the config key or term and an override that works (a third,
of indefinite stars, is :mod:`decrun.methods.model.indefinite_stars`):

- **Non-finite terms** (:func:`refuse_nonfinite_terms`): a term of dt(u) that is NaN or ±inf at
  the initial state (``u/x`` where x = 0) is refused naming the term, before any eigen-solve.
- **Explicit stability of every explicit term** (:func:`explicit_limit`). The Jacobian J of the
  explicitly integrated part of dt(y) = F(y) at the initial state — all of F for explicit
  Euler, RK4 and SSPRK3; the explicit terms for ``imex``, ``semi_implicit`` and ``ark_imex`` —
  is applied by finite differences (any term: advection through ``lie``/``interior``, a wave
  written as two first-order fields, a reaction), its eigenvalues of largest modulus found by
  ARPACK (small systems: all of them, densely). One step multiplies the mode of eigenvalue λ by
  R(dt λ), R the scheme's stability function; the exact flow multiplies it by e^{dt λ}. The
  step is refused when the growth the scheme adds over the run, max_λ (|R(dt λ)| /
  max(1, |e^{dt λ}|))^{steps}, exceeds :data:`SPURIOUS_GROWTH` — a physical growth (λ > 0) is
  never refused — naming ``app.dt`` and the largest step that passes (× 0.9, a whole number of
  steps to ``t_end``). An ARPACK failure falls back to a Gershgorin bound of the probed matrix;
  where neither is possible, the refusal names ``app.stability_check=false``.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
import scipy.sparse.linalg as spla

from decrun.methods.model.language import ModelError, to_text
from decrun.methods.model.tableaux import TABLEAUX, Tableau

__all__ = ["refuse_nonfinite_terms", "explicit_limit", "SPURIOUS_GROWTH", "stability_function", "suggested_dt", "fitted_dt"]

#: the largest growth over a run that a scheme may add to the exact flow's, on any mode
SPURIOUS_GROWTH = 10.0
#: up to this many unknowns the Jacobian is probed column by column and all its eigenvalues found
DENSE_MAX = 400
#: the explicitly integrated part of each integrator: "all" of F or only its explicit terms
EXPLICIT_PART = {"explicit_euler": "all", "rk4": "all", "ssprk3": "all", "imex": "rest", "ark_imex": "rest",
                 "semi_implicit": "lagged"}


def stability_function(scheme: str) -> Callable[[np.ndarray], np.ndarray] | None:
    """z ↦ R(z) of the explicit part of ``scheme`` (None: no explicit part to check):
    forward Euler for ``explicit_euler``, ``imex`` and ``semi_implicit``, the tableau's
    R(z) = 1 + z bᵀ(I − zA)⁻¹1 for RK4 and SSPRK3, the explicit tableau of ``ark_imex``."""
    if scheme not in EXPLICIT_PART:
        return None
    if scheme in ("explicit_euler", "imex", "semi_implicit"):
        return lambda z: 1.0 + np.asarray(z, dtype=np.complex128)
    tableau = TABLEAUX[scheme]
    if tableau.additive:
        assert tableau.explicit_A is not None and tableau.explicit_b is not None
        tableau = Tableau(f"{scheme} (explicit)", tableau.explicit_A, tableau.explicit_b, tableau.c, tableau.order)
    return tableau.stability_function


# ---------------------------------------------------------------------------------------- terms
def refuse_nonfinite_terms(model) -> None:
    """ModelError naming the first term of an evolution's right side that is not finite at the
    initial state (t = 0), with the count of its non-finite values."""
    compiler = model.compiler
    env = _environment(model, dict(model.initial_values))
    for equation in model.equations:
        if equation.kind != "evolution":
            continue
        for _sign, term in compiler.terms(equation.rhs):
            with np.errstate(all="ignore"):
                value = np.asarray(compiler.compile(term, equation.where)(env), dtype=np.float64)
            bad = int(np.sum(~np.isfinite(value)))
            if bad:
                rest = [to_text(other) for _s, other in compiler.terms(equation.rhs) if other is not term]
                without = f"dt({equation.target}) = {' + '.join(rest)}" if rest else ""
                leave = f" or leave it out ({without})" if without else ""
                raise ModelError(f"{equation.where}: the term {to_text(term)} of dt({equation.target}) is not finite at "
                                 f"t = 0 ({bad} of {value.size} values: a division by zero or an overflow); make it "
                                 f"finite at every simplex (e.g. a divisor that never vanishes){leave}")


def _environment(model, state: dict, t: float = 0.0) -> dict:
    with np.errstate(all="ignore"):
        return model.environment(state, t)


# ---------------------------------------------------------------------------------------- spectrum
def _rate(model, part: str) -> Callable[[dict], dict]:
    """state ↦ the explicitly integrated part of dt(u) for every evolved u (module docstring)."""
    if part == "all":
        return lambda state: model.derivative(_environment(model, state))
    if part == "rest":
        evolution = model.evolution
        return lambda state: {u: evolution.rest_value(u, _environment(model, state)) for u in evolution.names}
    from decrun.methods.model.integrators import SemiImplicit

    lagged = SemiImplicit(model, 1.0, None)

    def rest(state):
        env = _environment(model, state)
        out = {}
        for u in lagged.names:
            value = np.zeros(lagged.sizes[u])
            for sign, closure in lagged.rest[u]:
                value = value + sign * np.asarray(closure(env), dtype=np.float64)
            out[u] = value
        return out
    return rest


class _Jacobian:
    """J v ≈ (F(y + εv) − F(y))/ε over the stacked evolved fields at the initial state."""

    def __init__(self, model, part: str):
        self.names = list(model.evolved)
        self.sizes = [model.kinds[name].size(model.ops.K) for name in self.names]
        self.offsets = np.concatenate([[0], np.cumsum(self.sizes)]).astype(np.int64)
        self.rate = _rate(model, part)
        self.y = np.concatenate([np.asarray(model.initial_values[name], dtype=np.float64) for name in self.names])
        self.f0 = self._f(self.y)
        self.n = int(self.y.size)

    def _unstack(self, y: np.ndarray) -> dict:
        return {name: y[self.offsets[i]:self.offsets[i + 1]] for i, name in enumerate(self.names)}

    def _f(self, y: np.ndarray) -> np.ndarray:
        values = self.rate(self._unstack(y))
        return np.concatenate([np.broadcast_to(np.asarray(values[name], dtype=np.float64), (size,))
                               for name, size in zip(self.names, self.sizes, strict=True)])

    def matvec(self, v: np.ndarray) -> np.ndarray:
        v = np.real(np.asarray(v)).ravel()
        norm = float(np.linalg.norm(v))
        if norm == 0:
            return np.zeros(self.n)
        epsilon = 1e-7 * (1.0 + float(np.linalg.norm(self.y))) / norm
        with np.errstate(all="ignore"):
            return (self._f(self.y + epsilon * v) - self.f0) / epsilon

    def dense(self) -> np.ndarray:
        return np.column_stack([self.matvec(column) for column in np.eye(self.n)])


def spectrum_sample(jacobian: _Jacobian, count: int = 6) -> tuple[np.ndarray, str]:
    """(eigenvalues, how): all of J's (dense, n ≤ :data:`DENSE_MAX`), else the ``count`` of largest
    modulus by ARPACK; when ARPACK fails, the Gershgorin bound ρ ≤ max_i Σ_j |J_ij| of the probed
    matrix (n ≤ 20 DENSE_MAX), as the eigenvalue −ρ and ±iρ (the worst places of a diffusion and a
    wave of that size); empty when nothing worked."""
    n = jacobian.n
    if n <= DENSE_MAX:
        J = jacobian.dense()
        if not np.all(np.isfinite(J)):
            return np.zeros(0), "non-finite"
        return np.linalg.eigvals(J), "dense"
    operator = spla.LinearOperator((n, n), matvec=jacobian.matvec, dtype=np.float64)
    v0 = np.random.default_rng(0).standard_normal(n)
    try:
        values = spla.eigs(operator, k=min(count, n - 2), which="LM", v0=v0, tol=1e-3, ncv=min(n - 1, 24),
                           maxiter=50 * count, return_eigenvectors=False)
        if np.all(np.isfinite(values)):
            return np.asarray(values), "arpack"
    except spla.ArpackNoConvergence as error:
        values = np.asarray(error.eigenvalues)
        if values.size and np.all(np.isfinite(values)):
            return values, "arpack (partial)"
    except (spla.ArpackError, ValueError, np.linalg.LinAlgError):
        pass
    if n <= 20 * DENSE_MAX:
        J = jacobian.dense()
        if np.all(np.isfinite(J)):
            rho = float(np.max(np.abs(J).sum(axis=1)))
            return np.array([-rho, 1j * rho, -1j * rho]), "gershgorin"
    return np.zeros(0), "failed"


def _excess(R, z: np.ndarray) -> np.ndarray:
    """|R(z)| / max(1, |e^z|): what one step adds to the exact flow's growth, per mode."""
    with np.errstate(all="ignore"):
        exact = np.maximum(1.0, np.exp(np.minimum(np.real(z), 700.0)))
        return np.abs(R(z)) / exact


def _growth(R, eigenvalues: np.ndarray, dt: float, duration: float) -> float:
    """The largest spurious growth over ``duration`` at step ``dt``: max excess^(duration/dt)
    (inf beyond the floats)."""
    excess = float(np.max(_excess(R, dt * eigenvalues)))
    exponent = max(1.0, duration / dt) * math.log(excess) if excess > 0 else -math.inf
    return math.exp(exponent) if exponent < 700 else math.inf


def largest_stable_dt(R, eigenvalues: np.ndarray, dt: float, duration: float) -> float:
    """The largest step ≤ ``dt`` (to 1 %) whose spurious growth over ``duration`` is at most
    :data:`SPURIOUS_GROWTH` (bisection in log dt; 0 when none above dt·1e-12 is)."""
    low, high = dt * 1e-12, dt
    if _growth(R, eigenvalues, low, duration) > SPURIOUS_GROWTH:
        return 0.0
    while high / low > 1.01:
        middle = math.sqrt(low * high)
        if _growth(R, eigenvalues, middle, duration) <= SPURIOUS_GROWTH:
            low = middle
        else:
            high = middle
    return low


def fitted_dt(dt: float, t_end: float | None) -> str:
    """The ``app.dt`` to suggest at most ``dt`` (s): a whole number of steps of ``t_end``, or with
    no ``t_end`` ``dt`` to two digits (every refusal that names a working step uses it)."""
    if t_end is not None:
        return repr(t_end / math.ceil(t_end / dt))
    digits = float(f"{dt:.2g}")
    return f"{digits if digits <= dt else dt * 0.99:.2g}"


def _estimate(model, scheme: str, dt: float, steps: int):
    """(R, eigenvalues, how, part) of the explicitly integrated part at the initial state, or
    None when ``scheme`` has none, the model does not evolve or its rate is not finite."""
    R = stability_function(scheme)
    if R is None or model.is_static or steps == 0:
        return None
    part = EXPLICIT_PART[scheme]
    jacobian = _Jacobian(model, part)
    if jacobian.n == 0 or not np.all(np.isfinite(jacobian.f0)):
        return None  # refuse_nonfinite_terms names a non-finite term; nothing explicit to check
    eigenvalues, how = spectrum_sample(jacobian)
    return R, eigenvalues, how, part


def explicit_limit(model, scheme: str, dt: float, steps: int, t_end: float | None) -> float:
    """The largest stable step of the explicitly integrated part of ``scheme`` (module
    docstring; inf when ``scheme`` has none or the model has no evolution), or ModelError naming
    ``app.dt`` and a step that passes, or ``app.stability_check=false`` where no estimate could
    be made."""
    estimate = _estimate(model, scheme, dt, steps)
    if estimate is None:
        return float("inf")
    R, eigenvalues, how, part = estimate
    duration = dt * steps
    what = "dt(y)" if part == "all" else "the explicit terms of dt(y)"
    if eigenvalues.size == 0:
        bound = 0.1 * dt
        raise ModelError(f"app.stability_check: no estimate of the stability limit of integrator={scheme} for {what} "
                         f"could be made ({how}: the eigen-solve and its Gershgorin fallback); either check a "
                         f"smaller step yourself, e.g. `app.dt={fitted_dt(bound, t_end)}`, or skip the check with "
                         "`app.stability_check=false`")
    if _growth(R, eigenvalues, dt, duration) <= SPURIOUS_GROWTH:
        return largest_stable_dt(R, eigenvalues, 1e6 * dt, duration)
    limit = largest_stable_dt(R, eigenvalues, dt, duration)
    rho = float(np.max(np.abs(eigenvalues)))
    names = ", ".join(f"dt({name})" for name in model.evolved)
    raise ModelError(f"app.dt={dt:g} is unstable for integrator={scheme}: the explicit part ({names}; largest "
                     f"|λ| of its Jacobian at t = 0: {rho:.3g}, by {how}) would grow a mode by a factor "
                     f"{_growth(R, eigenvalues, dt, duration):.3g} over the run that the equations do not; use "
                     f"`app.dt={fitted_dt(0.9 * limit, t_end)}` (stable up to ≈ {limit:.3g}) or an implicit integrator")


def suggested_dt(model, scheme: str, dt: float, steps: int, t_end: float | None, known: float | None) -> float:
    """A step for a run that diverged at ``dt``: min(0.9 × the stability limit, dt/4) — the limit the
    smaller of ``known`` (the diffusion limit) and the explicit part's at the initial state — as a
    whole number of steps to ``t_end``. dt/4 where no limit applies (an implicit scheme whose
    bounds or growth failed: a quarter step keeps e.g. Allen–Cahn's explicit reaction monotone)."""
    limit = known if known is not None and np.isfinite(known) else float("inf")
    try:
        estimate = _estimate(model, scheme, dt, steps)
    except (ModelError, ValueError, FloatingPointError):
        estimate = None
    if estimate is not None and estimate[1].size:
        R, eigenvalues, _how, _part = estimate
        limit = min(limit, largest_stable_dt(R, eigenvalues, dt, dt * steps) or limit)
    step = min(0.9 * limit, dt / 4)
    return float(fitted_dt(step, t_end))
