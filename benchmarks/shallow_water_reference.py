"""The stored spectral references of Williamson's shallow-water test cases 5 and 6, read with numpy only.

``benchmarks/shallow_water_spectral.py`` (a pseudo-spectral vorticity–divergence solver on ducc0's
spherical-harmonic transforms) wrote them into ``benchmarks/data/`` with ``shallow_water_reference.json``
beside them: one entry per file with its sha256, the case, the day and the exact command that
regenerates it. This module needs neither ducc0 nor decrun:

- :func:`reference_depth` — the fluid depth h (m) of a stored reference at arbitrary points of the
  sphere of radius :data:`EARTH_RADIUS`, by spectral evaluation of the stored coefficients
  (orthonormal associated Legendre functions by their three-term recurrence, vectorized over the
  points and the orders m);
- :func:`williamson_norms` — the normalized l1, l2, l∞ errors of Williamson et al. (1992) eq. 82–84
  with area weights;
- the closed-form initial states of TC2, TC5 and TC6 (the solver starts from them; the tests check the
  evaluator's conventions against them).

Conventions (those of ducc0/healpy): colatitude ϑ from the north pole, longitude λ from the +x axis
eastward in [0, 2π) (λ = atan2(y, x)), latitude θ = π/2 − ϑ; orthonormal spherical harmonics with the
Condon–Shortley phase, ∫|Y_lm|² dΩ = 1; a real field is f = Σ_l a_l0 Y_l0 + 2 Re Σ_{m>0} a_lm Y_lm,
coefficients stored m-major (index m (2T + 1 − m) / 2 + l).

TC5's depth is returned as the stored free surface h + b (smooth) minus the exact cone b at the points,
so the cone's kinks do not ring through the evaluation (the solver's own depth coefficients carry the
truncated cone's Gibbs ripples; they are stored too, as ``h_lm``).
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = [
    "DATA_DIR", "MANIFEST", "EARTH_RADIUS", "OMEGA", "GRAVITY", "DAY", "Reference", "ReferenceFileError",
    "load_reference", "reference_name", "reference_depth", "sha256_of", "williamson_norms", "evaluate_real_field", "spherical_coordinates",
    "tc2_state", "tc5_state", "tc6_state", "tc5_mountain", "initial_state",
]

#: Williamson et al. (1992) constants: radius (m), rotation rate (1/s), gravity (m/s²), one day (s)
EARTH_RADIUS = 6.37122e6
OMEGA = 7.292e-5
GRAVITY = 9.80616
DAY = 86400.0

DATA_DIR = Path(__file__).resolve().parent / "data"
MANIFEST = DATA_DIR / "shallow_water_reference.json"


class ReferenceFileError(RuntimeError):
    """A stored reference is missing, or its bytes do not match the manifest's sha256."""


# ----------------------------------------------------------------------------------------------------
# closed-form states (latitude θ, longitude λ in radians; arrays of any matching shape)
# ----------------------------------------------------------------------------------------------------

def tc2_state(latitude: np.ndarray, longitude: np.ndarray, alpha: float = 0.0,
              u0: float = 2.0 * np.pi * EARTH_RADIUS / (12.0 * DAY), gh0: float = 2.94e4):
    """Williamson TC2 (steady zonal geostrophic flow, axis tilted by ``alpha``).

    Returns ``(u, v, h, f)``: eastward and northward velocity (m/s), depth (m) and the Coriolis
    parameter f = 2Ω (−cos λ cos θ sin α + sin θ cos α) (1/s) rotated with the flow, so that the
    state is an exact steady solution. gh = gh0 − (aΩu0 + u0²/2)(−cos λ cos θ sin α + sin θ cos α)².
    """
    z_rotated = -np.cos(longitude) * np.cos(latitude) * np.sin(alpha) + np.sin(latitude) * np.cos(alpha)
    u = u0 * (np.cos(latitude) * np.cos(alpha) + np.cos(longitude) * np.sin(latitude) * np.sin(alpha))
    v = -u0 * np.sin(longitude) * np.sin(alpha)
    h = (gh0 - (EARTH_RADIUS * OMEGA * u0 + 0.5 * u0 ** 2) * z_rotated ** 2) / GRAVITY
    return u, v, h, 2.0 * OMEGA * z_rotated


def tc5_mountain(latitude: np.ndarray, longitude: np.ndarray) -> np.ndarray:
    """TC5's cone b = b0 (1 − r/R) (m): b0 = 2000 m, R = π/9, centre λc = 3π/2, θc = π/6,
    r² = min(R², (λ − λc)² + (θ − θc)²) with λ in [0, 2π)."""
    radius, lon_c, lat_c = np.pi / 9.0, 1.5 * np.pi, np.pi / 6.0
    lam = np.mod(longitude, 2.0 * np.pi)
    r = np.sqrt(np.minimum(radius ** 2, (lam - lon_c) ** 2 + (latitude - lat_c) ** 2))
    return 2000.0 * (1.0 - r / radius)


def tc5_state(latitude: np.ndarray, longitude: np.ndarray):
    """Williamson TC5 initial state: ``(u, v, h, f, b)``; u = u0 cos θ with u0 = 20 m/s, free surface
    h + b = h0 − (aΩu0 + u0²/2) sin²θ / g with h0 = 5960 m, depth h = surface − b (m)."""
    u0, h0 = 20.0, 5960.0
    surface = h0 - (EARTH_RADIUS * OMEGA * u0 + 0.5 * u0 ** 2) * np.sin(latitude) ** 2 / GRAVITY
    b = tc5_mountain(latitude, longitude)
    u = u0 * np.cos(latitude) + 0.0 * longitude
    return u, np.zeros_like(u), surface - b, 2.0 * OMEGA * np.sin(latitude) + 0.0 * longitude, b


def tc6_state(latitude: np.ndarray, longitude: np.ndarray):
    """Williamson TC6 (Rossby–Haurwitz wave, R = 4, ω = K = 7.848e-6 1/s, h0 = 8000 m): ``(u, v, h, f)``."""
    omega_w = kappa = 7.848e-6
    wave, h0, a = 4, 8000.0, EARTH_RADIUS
    c, s = np.cos(latitude), np.sin(latitude)
    u = a * omega_w * c + a * kappa * c ** (wave - 1) * (wave * s ** 2 - c ** 2) * np.cos(wave * longitude)
    v = -a * kappa * wave * c ** (wave - 1) * s * np.sin(wave * longitude)
    big_a = (0.5 * omega_w * (2.0 * OMEGA + omega_w) * c ** 2 + 0.25 * kappa ** 2 * c ** (2 * wave)
             * ((wave + 1) * c ** 2 + (2 * wave ** 2 - wave - 2) - 2 * wave ** 2 / c ** 2))
    big_b = (2.0 * (OMEGA + omega_w) * kappa / ((wave + 1) * (wave + 2)) * c ** wave
             * ((wave ** 2 + 2 * wave + 2) - (wave + 1) ** 2 * c ** 2))
    big_c = 0.25 * kappa ** 2 * c ** (2 * wave) * ((wave + 1) * c ** 2 - (wave + 2))
    gh = (GRAVITY * h0 + a ** 2 * big_a + a ** 2 * big_b * np.cos(wave * longitude)
          + a ** 2 * big_c * np.cos(2 * wave * longitude))
    return u, v, gh / GRAVITY, 2.0 * OMEGA * s + 0.0 * longitude


def initial_state(case: str, latitude: np.ndarray, longitude: np.ndarray, alpha: float = 0.0):
    """``(u, v, h, f, b)`` of ``case`` in {tc2, tc5, tc6} at (latitude, longitude) (radians): m/s, m, 1/s, m."""
    if case == "tc2":
        u, v, h, f = tc2_state(latitude, longitude, alpha)
        return u, v, h, f, np.zeros_like(h)
    if case == "tc5":
        return tc5_state(latitude, longitude)
    if case == "tc6":
        u, v, h, f = tc6_state(latitude, longitude)
        return u, v, h, f, np.zeros_like(h)
    raise ValueError(f"case={case!r} is not one of tc2, tc5, tc6")


# ----------------------------------------------------------------------------------------------------
# spectral evaluation at arbitrary points
# ----------------------------------------------------------------------------------------------------

def spherical_coordinates(points: np.ndarray, radius: float = EARTH_RADIUS, rtol: float = 1e-6):
    """(latitude, longitude) in radians of ``points`` (n, 3) on the sphere of ``radius`` centred at the
    origin; longitude = atan2(y, x) in [0, 2π). A point off the sphere by more than ``rtol`` is refused."""
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must have shape (n, 3), got {points.shape}")
    norms = np.linalg.norm(points, axis=1)
    worst = float(np.max(np.abs(norms / radius - 1.0))) if len(points) else 0.0
    if worst > rtol:
        raise ValueError(f"points are not on the sphere of radius {radius} m centred at the origin "
                         f"(largest relative deviation {worst:.3g}): pass points scaled to that radius")
    latitude = np.arcsin(np.clip(points[:, 2] / norms, -1.0, 1.0))
    longitude = np.mod(np.arctan2(points[:, 1], points[:, 0]), 2.0 * np.pi)
    return latitude, longitude


def _legendre_factors(lmax: int):
    """Recurrence factors of the orthonormal Legendre functions λ_lm (indexed [l, m]):
    λ_lm = A_lm (x λ_{l−1,m} − B_lm λ_{l−2,m}), A_lm = √((4l²−1)/(l²−m²)), B_lm = √(((l−1)²−m²)/(4(l−1)²−1))."""
    ell = np.arange(lmax + 1, dtype=float)[:, None]
    m = np.arange(lmax + 1, dtype=float)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        a_factor = np.sqrt((4.0 * ell ** 2 - 1.0) / (ell ** 2 - m ** 2))
        b_factor = np.sqrt(((ell - 1.0) ** 2 - m ** 2) / (4.0 * (ell - 1.0) ** 2 - 1.0))
    return a_factor, b_factor


def evaluate_real_field(alm: np.ndarray, lmax: int, latitude: np.ndarray, longitude: np.ndarray,
                        chunk: int = 512) -> np.ndarray:
    """f(θ, λ) = Σ_l a_l0 Y_l0 + 2 Re Σ_{m>0} a_lm Y_lm at n points from the m-major coefficients ``alm``
    ((T+1)(T+2)/2 complex, ducc0/healpy order and normalization). Vectorized over the orders m and the
    points (in chunks of ``chunk``): the recurrence λ_lm = A_lm (cos ϑ λ_{l−1,m} − B_lm λ_{l−2,m}) runs once
    per degree offset l − m (T + 1 steps), in place on three rotating buffers."""
    alm = np.asarray(alm, dtype=complex)
    if alm.shape != ((lmax + 1) * (lmax + 2) // 2,):
        raise ValueError(f"alm has shape {alm.shape}, expected ({(lmax + 1) * (lmax + 2) // 2},) for T{lmax}")
    latitude, longitude = np.asarray(latitude, dtype=float), np.asarray(longitude, dtype=float)
    orders = np.arange(lmax + 1)
    start = orders * (2 * lmax + 1 - orders) // 2 + orders   # index of (l = m, m)
    a_factor, b_factor = _legendre_factors(lmax)
    # λ_mm = (−1)^m √((2m+1)/(4π) Π_{k≤m} (2k−1)/(2k)) sin^m ϑ, through logarithms (sin^m ϑ alone underflows)
    log_mm = 0.5 * (np.log((2 * orders + 1) / (4.0 * np.pi))
                    + np.concatenate([[0.0], np.cumsum(np.log((2 * orders[1:] - 1) / (2.0 * orders[1:])))]))
    sign_mm = np.where(orders % 2 == 0, 1.0, -1.0)
    weight = np.where(orders == 0, 1.0, 2.0)[:, None]
    # per offset: the orders m = 0 … T − offset, their A, B and coefficients (real, imaginary) as columns
    steps = []
    for offset in range(1, lmax + 1):
        m = orders[: lmax + 1 - offset]
        coefficient = alm[start[: m.size] + offset]
        steps.append((m.size, a_factor[m + offset, m][:, None], b_factor[m + offset, m][:, None],
                       coefficient.real.copy()[:, None], coefficient.imag.copy()[:, None]))
    values = np.empty(latitude.size)
    for first in range(0, latitude.size, chunk):
        lat, lon = latitude[first:first + chunk], longitude[first:first + chunk]
        x = np.sin(lat)[None, :]                            # cos ϑ
        log_sin = np.log(np.maximum(np.cos(lat), 1e-300))[None, :]
        p_now = sign_mm[:, None] * np.exp(log_mm[:, None] + orders[:, None] * log_sin)
        p_minus, p_next, product = (np.zeros_like(p_now) for _ in range(3))
        real = alm[start].real[:, None] * p_now            # Σ_l a_lm λ_lm per m: real and imaginary parts
        imag = alm[start].imag[:, None] * p_now
        for size, a_col, b_col, c_real, c_imag in steps:
            now, minus, nxt, work = p_now[:size], p_minus[:size], p_next[:size], product[:size]
            np.multiply(x, now, out=nxt)
            np.multiply(b_col, minus, out=work)
            np.subtract(nxt, work, out=nxt)
            np.multiply(a_col, nxt, out=nxt)
            np.multiply(c_real, nxt, out=work)
            np.add(real[:size], work, out=real[:size])
            np.multiply(c_imag, nxt, out=work)
            np.add(imag[:size], work, out=imag[:size])
            p_minus, p_now, p_next = p_now, p_next, p_minus
        angle = orders[:, None] * lon[None, :]
        values[first:first + chunk] = np.sum(weight * (real * np.cos(angle) - imag * np.sin(angle)), axis=0)
    return values


# ----------------------------------------------------------------------------------------------------
# the stored references
# ----------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Reference:
    """One stored solver output: spectral coefficients at truncation ``lmax`` (m-major, complex128) of the
    depth h, the free surface h + b, relative vorticity ζ and divergence δ; the depth on the solver's Gauss
    grid (``grid_latitude`` × ``grid_longitude``, m) and the Gauss weights; its manifest entry."""

    name: str
    case: str
    day: float
    lmax: int
    h_lm: np.ndarray
    surface_lm: np.ndarray
    vorticity_lm: np.ndarray
    divergence_lm: np.ndarray
    h_grid: np.ndarray
    grid_latitude: np.ndarray
    grid_longitude: np.ndarray
    gauss_weights: np.ndarray
    entry: dict

    def depth(self, latitude: np.ndarray, longitude: np.ndarray) -> np.ndarray:
        """h (m) at (latitude, longitude): the stored surface minus the exact cone for TC5, else h_lm."""
        if self.case == "tc5":
            return (evaluate_real_field(self.surface_lm, self.lmax, latitude, longitude)
                    - tc5_mountain(latitude, longitude))
        return evaluate_real_field(self.h_lm, self.lmax, latitude, longitude)


def _manifest(data_dir: Path = DATA_DIR) -> dict:
    manifest = Path(data_dir) / MANIFEST.name
    if not manifest.is_file():
        raise ReferenceFileError(f"{manifest} is missing: regenerate the references with "
                                 "benchmarks/shallow_water_spectral.py (commands in benchmarks/data/README.md)")
    return json.loads(manifest.read_text())


def sha256_of(path: Path) -> str:
    """Hex sha256 of the file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def load_reference(name: str, data_dir: Path = DATA_DIR) -> Reference:
    """Load the manifest's file ``name`` (in ``data_dir``, by default benchmarks/data/) after checking its
    sha256 against the manifest there; a missing file or a mismatch is one :class:`ReferenceFileError`
    naming the file and the command that regenerates it."""
    entries = _manifest(data_dir)["files"]
    if name not in entries:
        raise ReferenceFileError(f"{name} is not in {MANIFEST.name}; stored: {', '.join(sorted(entries))}")
    entry = entries[name]
    path = Path(data_dir) / name
    if not path.is_file():
        raise ReferenceFileError(f"{path} is missing: regenerate it with `{entry['command']}`")
    digest = sha256_of(path)
    if digest != entry["sha256"]:
        raise ReferenceFileError(f"{path} has sha256 {digest}, the manifest says {entry['sha256']}: "
                                 f"regenerate it with `{entry['command']}`")
    with np.load(path) as data:
        return Reference(name=name, case=entry["case"], day=float(entry["day"]), lmax=int(data["lmax"]),
                         h_lm=data["h_lm"], surface_lm=data["surface_lm"], vorticity_lm=data["vorticity_lm"],
                         divergence_lm=data["divergence_lm"], h_grid=data["h_grid"],
                         grid_latitude=data["grid_latitude"], grid_longitude=data["grid_longitude"],
                         gauss_weights=data["gauss_weights"], entry=entry)


def reference_name(case: str, day: float, alpha: float = 0.0, data_dir: Path = DATA_DIR) -> str:
    """The manifest's file for (case, day, alpha); when several are stored, the finest truncation, then
    the RK4 run (its time error is far below the leapfrog's)."""
    entries = _manifest(data_dir)["files"]
    matches = [(e["lmax"], e["scheme"] == "rk4", name) for name, e in entries.items()
               if e["case"] == case and np.isclose(e["day"], day) and np.isclose(e.get("alpha", 0.0), alpha)]
    if not matches:
        stored = ", ".join(f"{e['case']} day {e['day']:g}" for e in entries.values())
        raise ReferenceFileError(f"no stored reference for case={case!r} day={day:g}; stored: {stored}")
    return max(matches)[2]


def reference_depth(case: str, day: float, points: np.ndarray) -> np.ndarray:
    """The reference fluid depth h (m), shape (n,), of ``case`` ('tc5' or 'tc6') at ``day`` at ``points``
    (n, 3) on the sphere of radius :data:`EARTH_RADIUS` centred at the origin (longitude = atan2(y, x))."""
    latitude, longitude = spherical_coordinates(points)
    return load_reference(reference_name(case, day)).depth(latitude, longitude)


def williamson_norms(h: np.ndarray, h_true: np.ndarray, area: np.ndarray) -> dict[str, float]:
    """Williamson et al. (1992) eq. 82–84 with I[·] = Σ area·(·):
    l1 = I[|h − hT|] / I[|hT|], l2 = √I[(h − hT)²] / √I[hT²], l∞ = max|h − hT| / max|hT|."""
    h, h_true, area = (np.asarray(x, dtype=float) for x in (h, h_true, area))
    error = h - h_true
    return {"l1": float(np.sum(area * np.abs(error)) / np.sum(area * np.abs(h_true))),
            "l2": float(np.sqrt(np.sum(area * error ** 2) / np.sum(area * h_true ** 2))),
            "linf": float(np.max(np.abs(error)) / np.max(np.abs(h_true)))}
