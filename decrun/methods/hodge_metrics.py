"""The metrics of ``app=hodge`` (Theorem 5, §6.3.4–6.3.6): how orthogonal the parts of a
Hodge decomposition ω = dα + δβ + γ are, how much of ω each holds, and how harmonic γ is.
A ratio of round-off is absent, not a number."""

from __future__ import annotations

import numpy as np

__all__ = ["ROUNDOFF", "orthogonality_metrics", "harmonic_residuals"]

#: a part whose norm is ≤ ROUNDOFF × ‖ω‖ (energy share ≤ ROUNDOFF²) is zero to round-off
ROUNDOFF = 1e-8


def orthogonality_metrics(dec, omega: np.ndarray, parts: dict[str, np.ndarray], k: int = 1) -> dict:
    """Theorem 5 checks for k-forms. For each pair of parts |⟨a, b⟩_⋆k| / ‖ω‖²_⋆k, the energy
    fraction ‖part‖² / ‖ω‖² of each part and the relative reconstruction error."""
    total = dec.inner(k, omega, omega)
    out = {}
    names = list(parts)
    worst = 0.0
    for i, p in enumerate(names):
        for q in names[i + 1:]:
            value = abs(dec.inner(k, parts[p], parts[q])) / total if total > 0 else 0.0
            out[f"orthogonality_{p}_{q}"] = float(value)
            worst = max(worst, float(value))
    out["orthogonality_max"] = worst
    for p in names:
        out[f"energy_fraction_{p}"] = float(dec.inner(k, parts[p], parts[p]) / total) if total > 0 else 0.0
    rest = omega - sum(parts.values())
    out["reconstruction_error_relative"] = float(np.sqrt(abs(dec.inner(k, rest, rest)) / total)) if total > 0 else 0.0
    return out


def harmonic_residuals(dec, omega: np.ndarray, harmonic: np.ndarray, energy_metrics: dict, k: int = 1) -> dict:
    """``harmonic_curl_relative`` ‖dγ‖_⋆/‖dω‖_⋆ and ``harmonic_codifferential_relative``
    ‖δγ‖_⋆/‖δω‖_⋆ of the harmonic part γ (n_k,) of ω (n_k,): both ≈ 0 for a harmonic γ. Each
    is absent when it would be a ratio of round-off: γ is zero to round-off, or so is dω
    (δω) — d kills the exact part and δ the coexact part, so dω comes from the coexact and
    harmonic parts only, δω from the exact and harmonic ones (energy shares from
    ``energy_metrics``' ``energy_fraction_*``, ≤ ROUNDOFF² each)."""
    energy = {name: energy_metrics[f"energy_fraction_{name}"] for name in ("exact", "coexact", "harmonic")}

    def relative(op, j, sources):
        if energy["harmonic"] <= ROUNDOFF ** 2 or sum(energy[s] for s in sources) <= ROUNDOFF ** 2:
            return None
        ref = np.sqrt(abs(dec.inner(j, op @ omega, op @ omega)))
        return float(np.sqrt(abs(dec.inner(j, op @ harmonic, op @ harmonic))) / ref) if ref > 0 else None

    out = {}
    for name, value in (("harmonic_curl_relative", relative(dec.d(k), k + 1, ("coexact", "harmonic"))),
                        ("harmonic_codifferential_relative", relative(dec.codifferential(k), k - 1,
                                                                      ("exact", "harmonic")))):
        if value is not None:
            out[name] = value
    return out
