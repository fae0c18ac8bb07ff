"""Energy- and enstrophy-bounded swept vorticity, with an optional local clamp.

The swept circulation (swept.py) is consistent but, at ν = 0, not a contraction: its energy
rises almost every step (1.2e-4 per step at 5120 faces, dt = 0.02, +2 % in 4 s) and fine
channels diverge. Two parts, applied to the advected vorticity w* of step d:

(a) ``circulation="swept_clamped"`` only: a local maximum principle. Each interior cell's
    value is clamped to the range of the previous vorticity over the vertices of the
    triangles its backtracked corners lie in (the cell's footprint; the exact update averages
    ω over X(C)), and the removed mass goes back to the cells with room in proportion to their
    room (``conservative_clamp``), so Σ ⋆0 w is unchanged. Measured: it clips extrema (18 %
    less enstrophy than (b) alone after 4 s at 5120 faces), so the default uses it only where
    (b) cannot act (slip walls with inflow).
(b) ``circulation="swept_bounded"`` (default) and ``"swept_clamped"``, on flows without inflow
    (forces are added after it): the energy E(w) = ½ ψᵀ S ψ (ψ = the stream function of w,
    S = d0ᵀ ⋆1 d0) and, on closed surfaces and between slip walls, the enstrophy Z(w) = ½ Σ ⋆0 w²
    may not exceed those of the previous state. (No-slip border cells make vorticity, so
    enstrophy is no invariant there, and bounding it wrecked the cellular flow's steady state in
    the square: drift 298 /s instead of 1.8e-3 /s. With slip walls and inflow, where vorticity
    enters and leaves, ``swept_bounded`` uses the clamp (a) instead: it kept the inviscid
    12059-face channel bounded, which diverged with no-slip walls with or without it.) If w* raises the enstrophy, the result is the blend
    w_θ = (1 − θ) w* + θ w_s with w_s = (⋆0 + α S)⁻¹ ⋆0 w* (one implicit diffusion step with
    α = h̄², h̄ the mean edge length: it damps grid-scale modes by about half, a degree-l
    harmonic by 1 / (1 + l(l+1) h̄²)) and θ ∈ [0, 1] the smallest blend meeting the bound
    (Z(w_θ) is a quadratic in θ). If then the energy is too high, the energy fix
    w − β ψ̄ (ψ̄ = ψ minus its ⋆0-mean) with β the smallest root of E(w − β ψ̄) = E₀: along ψ̄ both
    quantities fall (⟨w, ψ̄⟩⋆0 = 2E > 0), and by Cauchy–Schwarz the enstrophy lost per energy lost
    is at most that of a uniform rescale — the change sits in the large scales, where the swept
    rule's energy gain is. A rescale s = min(√(Z₀ / Z), √(E₀ / E)) < 1 remains as the guard
    against round-off (``EnergyEnstrophyBound``).

Both conserve Σ ⋆0 w (1ᵀ(⋆0 + α S) = 1ᵀ⋆0, ψ̄ has zero mean, the guard's scale acts on a zero
mean on closed surfaces). On the exact steady states of tests/fluid_cases.py the bound never
acts: the default's drift is the swept rule's, O(h) (tests/methods/test_fluid.py). Nothing here loops over cells in Python.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

__all__ = ["footprint_range", "conservative_clamp", "EnergyEnstrophyBound"]

_EPS = np.finfo(np.float64).eps


def footprint_range(w: np.ndarray, top: np.ndarray, triangle: np.ndarray, corners: np.ndarray,
                    n_circumcenters: int) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi), each (n0,): the range of the vertex vorticity ``w`` (n0,) over the corners of the
    triangles ``triangle`` (m,) holding the backtracked circumcenters, gathered per cell over its
    ``corners`` (n0, k) (dual-point ids, padded; ids ≥ ``n_circumcenters`` are fixed border points
    and are skipped: cells with them are border cells, which the limiter leaves alone)."""
    values = w[top[triangle]]  # (m, 3)
    lo_point, hi_point = values.min(axis=1), values.max(axis=1)
    moving = corners < n_circumcenters
    ids = np.where(moving, corners, 0)
    lo = np.where(moving, lo_point[ids], np.inf).min(axis=1)
    hi = np.where(moving, hi_point[ids], -np.inf).max(axis=1)
    return lo, hi


def conservative_clamp(w: np.ndarray, lo: np.ndarray, hi: np.ndarray, star0: np.ndarray,
                       active: np.ndarray) -> np.ndarray:
    """(n0,) ``w`` clamped to [lo, hi] on the ``active`` (n0,) bool cells, with the removed mass
    Σ ⋆0 (w − clamped) redistributed over the active cells in proportion to their room
    ⋆0 (hi − w) (mass to add) or ⋆0 (w − lo) (mass to remove), so that Σ ⋆0 w is unchanged and
    no active cell leaves its range (when the total room is smaller than the mass, which a
    consistent w* does not produce, the rest stays on the cells: conservation wins)."""
    clamped = np.where(active, np.clip(w, lo, hi), w)
    excess = float(star0 @ (w - clamped))
    if excess == 0.0:
        return clamped
    room = np.where(active, (hi - clamped) if excess > 0 else (clamped - lo), 0.0)
    capacity = float(star0 @ room)
    if not capacity > 0:
        return w
    return clamped + np.sign(excess) * room * (min(abs(excess), capacity) / capacity) \
        + (excess - np.sign(excess) * min(abs(excess), capacity)) / star0.sum()


def _smallest_blend(f0: float, slope: float, curvature: float, bound: float) -> float:
    """Smallest θ ∈ [0, 1] with f0 + slope θ + curvature θ² ≤ bound (f convex in θ), or 1.0
    (the caller checks the end point)."""
    if f0 <= bound:
        return 0.0
    a, b, c = curvature, slope, f0 - bound
    if a <= 0:
        return min(1.0, -c / b) if b < 0 else 1.0
    disc = b * b - 4 * a * c
    if disc < 0:
        return 1.0
    root = (-b - np.sqrt(disc)) / (2 * a)
    return float(min(1.0, max(root, 0.0)))


class EnergyEnstrophyBound:
    """Part (b): w* → a vorticity whose energy (and enstrophy) do not exceed those of the
    previous state (module docstring).

    Parameters
    ----------
    star0 : (n0,) dual areas ⋆0
    stiffness : (n0, n0) S = d0ᵀ ⋆1 d0 (PSD)
    recover : callable w (n0,) → ψ (n0,), the fluid's linear stream-function solve (step g)
    new_solver : callable () → solver with factorize(A), solve(b); the smoothing matrix
        ⋆0 + α S is factorized once here
    alpha : α (mesh units²), the smoothing's diffusion length²
    enstrophy : bound the enstrophy too (closed surfaces); False: the energy only (domains with
        walls, whose no-slip border cells make vorticity)
    """

    def __init__(self, star0: np.ndarray, stiffness: sp.spmatrix, recover, new_solver, alpha: float,
                 enstrophy: bool = True):
        self.star0, self.stiffness, self.recover, self.alpha = star0, stiffness, recover, float(alpha)
        self.bounds_enstrophy = bool(enstrophy)
        self._smooth = new_solver()
        self._smooth.factorize((sp.diags(star0) + self.alpha * stiffness).tocsr())

    def enstrophy(self, w: np.ndarray) -> float:
        """½ Σ ⋆0 w² (mesh units² / s²)."""
        return float(0.5 * self.star0 @ (w * w))

    def energy(self, psi: np.ndarray) -> float:
        """½ ψᵀ S ψ (mesh units⁴ / s²)."""
        return float(0.5 * psi @ (self.stiffness @ psi))

    def apply(self, w_old: np.ndarray, psi_old: np.ndarray, w: np.ndarray):
        """(w_new, ψ_new, action) for the advected vorticity ``w`` (n0,), the previous state
        ``w_old``, ``psi_old`` (n0,): the bounded vorticity, its stream function, and the branches
        that ran as bit flags: 0 none (``w`` is within both bounds and returned as is),
        1 blend towards the smoothed field (enstrophy), 2 energy fix along ψ̄, 4 final rescale."""
        z0, e0 = self.enstrophy(w_old) if self.bounds_enstrophy else np.inf, self.energy(psi_old)
        z_target, e_target = z0 * (1 - 8 * _EPS), e0 * (1 - 8 * _EPS)  # leave room for round-off
        psi = self.recover(w)
        action = 0
        if self.enstrophy(w) > z0:
            ws = self._smooth.solve(self.star0 * w)
            ws -= (self.star0 @ (ws - w)) / self.star0.sum()  # Σ ⋆0 ws = Σ ⋆0 w to the last bit
            dw = ws - w
            theta = _smallest_blend(self.enstrophy(w), float(self.star0 @ (w * dw)), self.enstrophy(dw), z_target)
            w, psi, action = w + theta * dw, psi + theta * (self.recover(ws) - psi), 1
        if self.energy(psi) > e0:
            bar = psi - (self.star0 @ psi) / self.star0.sum()  # ψ̄: zero mean, so Σ ⋆0 w is kept
            phi = self.recover(bar)  # the stream function of ψ̄ viewed as a vorticity
            S = self.stiffness
            beta = _smallest_blend(self.energy(psi), -float(psi @ (S @ phi)), self.energy(phi), e_target)
            # for β ≤ 2⟨w, ψ̄⟩⋆0 / ⟨ψ̄, ψ̄⟩⋆0 (= 4E / ‖ψ̄‖², > 0) the enstrophy does not rise either
            w, psi, action = w - beta * bar, psi - beta * phi, action | 2
        z, e = self.enstrophy(w), self.energy(psi)
        if z > z0 or e > e0:
            scale = min(np.sqrt(z0 / z) if z > z0 else 1.0, np.sqrt(e0 / e) if e > e0 else 1.0) * (1 - 4 * _EPS)
            w, psi, action = scale * w, scale * psi, action | 4
        return w, psi, action
