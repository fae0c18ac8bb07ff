"""A real field on the sphere from its spherical-harmonic coefficients, at arbitrary points: how a model
compares with a stored spectral reference (``benchmarks/data/``, written by
``benchmarks/shallow_water_spectral.py``) through the initial value
``{spherical_harmonics: <file.npz>, coefficients: <array>}`` of a field (:mod:`decrun.methods.model.initial`).

Conventions (ducc0/healpy): orthonormal harmonics with the Condon–Shortley phase, ∫|Y_lm|² dΩ = 1, a real field
f = Σ_l a_l0 Y_l0 + 2 Re Σ_{m>0} a_lm Y_lm, coefficients m-major (index m (2T + 1 − m)/2 + l) at triangular
truncation T; latitude θ = arcsin(z/|x|), longitude λ = atan2(y, x).

A stored file is read only when its sha256 is the one its manifest (``shallow_water_reference.json`` beside it)
lists; otherwise the read is refused in one line naming the file and the command that regenerates it.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from decrun.errors import ConfigError

__all__ = ["evaluate_real_field", "load_coefficients", "MANIFEST_NAME"]

#: the manifest beside the stored files: {"files": {name: {"sha256", "command", ...}}}
MANIFEST_NAME = "shallow_water_reference.json"


def evaluate_real_field(alm: np.ndarray, lmax: int, points: np.ndarray, chunk: int = 512) -> np.ndarray:
    """(n,) f at ``points`` (n, 3) from the m-major coefficients ``alm`` ((T+1)(T+2)/2 complex) of truncation
    ``lmax``: the orthonormal associated Legendre functions by λ_lm = A_lm (sin θ λ_{l−1,m} − B_lm λ_{l−2,m}),
    A_lm = √((4l²−1)/(l²−m²)), B_lm = √(((l−1)²−m²)/(4(l−1)²−1)), from λ_mm = (−1)^m √((2m+1)/(4π)
    Π_{k≤m} (2k−1)/(2k)) cos^m θ (through logarithms), vectorized over the orders m and the points."""
    alm = np.asarray(alm, dtype=complex)
    if alm.shape != ((lmax + 1) * (lmax + 2) // 2,):
        raise ValueError(f"alm has shape {alm.shape}, expected ({(lmax + 1) * (lmax + 2) // 2},) for T{lmax}")
    points = np.asarray(points, dtype=np.float64)
    norm = np.linalg.norm(points, axis=1)
    latitude = np.arcsin(np.clip(points[:, 2] / norm, -1.0, 1.0))
    longitude = np.arctan2(points[:, 1], points[:, 0])
    orders = np.arange(lmax + 1)
    start = orders * (2 * lmax + 1 - orders) // 2 + orders  # index of (l = m, m)
    ell, m_all = np.arange(lmax + 1.0)[:, None], np.arange(lmax + 1.0)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        a_factor = np.sqrt((4.0 * ell ** 2 - 1.0) / (ell ** 2 - m_all ** 2))
        b_factor = np.sqrt(((ell - 1.0) ** 2 - m_all ** 2) / (4.0 * (ell - 1.0) ** 2 - 1.0))
    log_mm = 0.5 * (np.log((2 * orders + 1) / (4.0 * np.pi))
                    + np.concatenate([[0.0], np.cumsum(np.log((2 * orders[1:] - 1) / (2.0 * orders[1:])))]))
    sign_mm = np.where(orders % 2 == 0, 1.0, -1.0)
    weight = np.where(orders == 0, 1.0, 2.0)[:, None]
    values = np.empty(latitude.size)
    for first in range(0, latitude.size, chunk):
        lat, lon = latitude[first:first + chunk], longitude[first:first + chunk]
        x = np.sin(lat)[None, :]
        log_cos = np.log(np.maximum(np.cos(lat), 1e-300))[None, :]
        p_now = sign_mm[:, None] * np.exp(log_mm[:, None] + orders[:, None] * log_cos)
        p_minus = np.zeros_like(p_now)
        real = alm[start].real[:, None] * p_now  # Σ_l a_lm λ_lm per order m
        imag = alm[start].imag[:, None] * p_now
        for offset in range(1, lmax + 1):  # degree l = m + offset for the orders m ≤ T − offset
            size = lmax + 1 - offset
            m = orders[:size]
            p_next = a_factor[m + offset, m][:, None] * (x * p_now[:size] - b_factor[m + offset, m][:, None]
                                                         * p_minus[:size])
            coefficient = alm[start[:size] + offset]
            real[:size] += coefficient.real[:, None] * p_next
            imag[:size] += coefficient.imag[:, None] * p_next
            p_minus, p_now = p_now[:size], p_next
        angle = orders[:, None] * lon[None, :]
        values[first:first + chunk] = np.sum(weight * (real * np.cos(angle) - imag * np.sin(angle)), axis=0)
    return values


def load_coefficients(path: str, name: str, where: str) -> tuple[np.ndarray, int]:
    """(the complex coefficients ``name`` of the stored ``.npz`` at ``path``, their truncation T), after
    checking the file's sha256 against the manifest beside it. A relative ``path`` is taken from the working
    directory, else from the repository root (``benchmarks/data/…`` from a checkout). Every failure is one line
    naming ``where``."""
    file = Path(path)
    if not file.is_file() and not file.is_absolute():  # a path of the repository (benchmarks/data/…) from elsewhere
        file = Path(__file__).resolve().parents[2] / path
    if not file.is_file():
        raise ConfigError(f"{where}: {path}: no such file, neither from the working directory nor the repository "
                          f"root ({Path(__file__).resolve().parents[2]}); give its absolute path")
    manifest = file.parent / MANIFEST_NAME
    entry = json.loads(manifest.read_text()).get("files", {}).get(file.name) if manifest.is_file() else None
    if entry is None:
        raise ConfigError(f"{where}: {path} is not listed in {manifest}; store it with "
                          "benchmarks/shallow_water_spectral.py --manifest")
    digest = hashlib.sha256(file.read_bytes()).hexdigest()
    if digest != entry["sha256"]:
        raise ConfigError(f"{where}: {path} has sha256 {digest[:12]}…, the manifest lists {entry['sha256'][:12]}…; "
                          f"regenerate it: {entry.get('command', '(no command in the manifest)')}")
    with np.load(file) as data:
        if name not in data.files:
            raise ConfigError(f"{where}: {path} has no array {name!r}; choose one of {sorted(data.files)}")
        return np.asarray(data[name], dtype=complex), int(data["lmax"])
