"""The shallow-water test suite on the sphere (Williamson et al. 1992, J. Comput. Phys. 102;
Galewsky, Scott & Polvani 2004, Tellus 56A): initial states, the error norms (Williamson eq. 82–84)
and the invariants of the TRiSK discretization (:mod:`decrun.core.trisk`).

A :class:`Case` holds vectorized functions of points ``(n, 3)`` in metres on (or near: they are
projected radially) the sphere of radius ``a``: the depth h (m), the velocity (m s⁻¹, tangent
vectors in R³), the bottom topography b (m) and the Coriolis parameter f (s⁻¹). θ is the latitude,
λ the longitude, u the zonal and v the meridional velocity; a day is 86 400 s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.integrate import cumulative_simpson
from scipy.interpolate import CubicSpline

from decrun.core.forms import sample_vector_field
from decrun.core.trisk import TRiSK

__all__ = ["EARTH_RADIUS", "OMEGA", "GRAVITY", "DAY", "Case", "williamson_tc2", "williamson_tc5", "williamson_tc6",
           "galewsky", "longitude_latitude", "zonal_meridional", "circulation", "error_norms", "invariants",
           "RK_STABILITY_INTERVAL", "stable_time_step"]

EARTH_RADIUS = 6.37122e6  # a (m)
OMEGA = 7.292e-5  # Ω (s⁻¹)
GRAVITY = 9.80616  # g (m s⁻²)
DAY = 86400.0  # s

Field = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Case:
    """One test case: ``depth``, ``velocity``, ``topography``, ``coriolis`` as functions of points
    (n, 3) → (n,) or (n, 3); ``duration`` (s) its standard run length; ``exact`` true when the
    initial state is the exact solution at every time (TC2)."""

    name: str
    depth: Field
    velocity: Field
    topography: Field
    coriolis: Field
    duration: float
    exact: bool = False


def longitude_latitude(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(λ, θ) of points (n, 3), λ ∈ (−π, π] from atan2(y, x) and θ = asin(z/|x|) ∈ [−π/2, π/2]."""
    radius = np.linalg.norm(points, axis=1)
    return np.arctan2(points[:, 1], points[:, 0]), np.arcsin(np.clip(points[:, 2] / radius, -1.0, 1.0))


def zonal_meridional(points: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """(n, 3) the tangent vectors u e_λ + v e_θ, e_λ = (−sin λ, cos λ, 0) (east),
    e_θ = (−sin θ cos λ, −sin θ sin λ, cos θ) (north)."""
    lon, lat = longitude_latitude(points)
    east = np.column_stack([-np.sin(lon), np.cos(lon), np.zeros_like(lon)])
    north = np.column_stack([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)])
    return u[:, None] * east + v[:, None] * north


def _unit(points: np.ndarray) -> np.ndarray:
    return points / np.linalg.norm(points, axis=1, keepdims=True)


def _rotated_axis(alpha: float) -> np.ndarray:
    """The axis (−sin α, 0, cos α): the flow's rotation axis of TC2, tilted by α from the pole
    towards λ = π."""
    return np.array([-np.sin(alpha), 0.0, np.cos(alpha)])


def williamson_tc2(alpha: float = 0.0, a: float = EARTH_RADIUS, omega: float = OMEGA,
                   g: float = GRAVITY) -> Case:
    """Test case 2, steady zonal geostrophic flow about the axis n = (−sin α, 0, cos α):
    u = (u0/a) n × x (u0 = 2πa/12 days), g h = g h0 − (a Ω u0 + u0²/2) (n·x̂)², f = 2Ω n·x̂,
    g h0 = 2.94e4 m² s⁻², no topography; 5 days; the exact solution is the initial state."""
    u0 = 2.0 * np.pi * a / (12.0 * DAY)
    axis = _rotated_axis(alpha)
    gh0 = 2.94e4

    def depth(x):
        return (gh0 - (a * omega * u0 + 0.5 * u0 ** 2) * (_unit(x) @ axis) ** 2) / g

    return Case("williamson_tc2", depth, lambda x: (u0 / a) * np.cross(axis, a * _unit(x)),
                lambda x: np.zeros(x.shape[0]), lambda x: 2.0 * omega * (_unit(x) @ axis), 5.0 * DAY, exact=True)


def williamson_tc5(a: float = EARTH_RADIUS, omega: float = OMEGA, g: float = GRAVITY) -> Case:
    """Test case 5, zonal flow over an isolated mountain: u = u0 cos θ (u0 = 20 m/s), free surface
    h + b = h0 − (a Ω u0 + u0²/2) sin²θ / g (h0 = 5960 m), mountain b = b0 (1 − r/R), b0 = 2000 m,
    R = π/9, r² = min(R², (λ − λc)² + (θ − θc)²), λc = −π/2 (= 3π/2), θc = π/6; 15 days."""
    u0, h0, b0, R = 20.0, 5960.0, 2000.0, np.pi / 9.0

    def topography(x):
        lon, lat = longitude_latitude(x)
        dlon = np.angle(np.exp(1j * (lon + 0.5 * np.pi)))  # λ − λc wrapped to (−π, π]
        r = np.sqrt(np.minimum(R ** 2, dlon ** 2 + (lat - np.pi / 6.0) ** 2))
        return b0 * (1.0 - r / R)

    def depth(x):
        z = _unit(x)[:, 2]
        return h0 - (a * omega * u0 + 0.5 * u0 ** 2) * z ** 2 / g - topography(x)

    axis = _rotated_axis(0.0)
    return Case("williamson_tc5", depth, lambda x: (u0 / a) * np.cross(axis, a * _unit(x)), topography,
                lambda x: 2.0 * omega * _unit(x)[:, 2], 15.0 * DAY)


def williamson_tc6(a: float = EARTH_RADIUS, omega: float = OMEGA, g: float = GRAVITY) -> Case:
    """Test case 6, the Rossby–Haurwitz wave of wavenumber R = 4 (ω = K = 7.848e-6 s⁻¹, h0 = 8000 m;
    the formulas of SHALLOW_WATER.md, cos⁻²θ multiplied out so the poles are regular); 14 days."""
    w = k = 7.848e-6
    R, h0 = 4, 8000.0

    def velocity(x):
        lon, lat = longitude_latitude(x)
        c, s = np.cos(lat), np.sin(lat)
        u = a * w * c + a * k * c ** (R - 1) * (R * s ** 2 - c ** 2) * np.cos(R * lon)
        v = -a * k * R * c ** (R - 1) * s * np.sin(R * lon)
        return zonal_meridional(x, u, v)

    def depth(x):
        lon, lat = longitude_latitude(x)
        c2 = np.cos(lat) ** 2
        A = (0.5 * w * (2.0 * omega + w) * c2
             + 0.25 * k ** 2 * (c2 ** R * ((R + 1) * c2 + (2 * R ** 2 - R - 2)) - 2 * R ** 2 * c2 ** (R - 1)))
        B = 2.0 * (omega + w) * k / ((R + 1) * (R + 2)) * c2 ** (R / 2) * ((R ** 2 + 2 * R + 2) - (R + 1) ** 2 * c2)
        C = 0.25 * k ** 2 * c2 ** R * ((R + 1) * c2 - (R + 2))
        return h0 + a ** 2 * (A + B * np.cos(R * lon) + C * np.cos(2 * R * lon)) / g

    return Case("williamson_tc6", depth, velocity, lambda x: np.zeros(x.shape[0]),
                lambda x: 2.0 * omega * _unit(x)[:, 2], 14.0 * DAY)


def galewsky(perturbed: bool = True, a: float = EARTH_RADIUS, omega: float = OMEGA, g: float = GRAVITY,
             samples: int = 20001) -> Case:
    """Galewsky et al. (2004): the jet u(θ) = (u_max/e_n) exp(1/((θ − θ0)(θ − θ1))) on θ0 < θ < θ1
    (u_max = 80 m/s, θ0 = π/7, θ1 = π/2 − θ0, e_n = exp(−4/(θ1 − θ0)²)), balanced by
    g h(θ) = g h0 − ∫_{−π/2}^{θ} a u (f + u tan θ'/a) dθ' (composite Simpson on ``samples`` latitudes,
    interpolated by a cubic spline), h0 such that the sphere's mean depth is 10 000 m; with
    ``perturbed`` the bump ĥ cos θ exp(−(λ/α)²) exp(−((θ2 − θ)/β)²) (ĥ = 120 m, θ2 = π/4, α = 1/3,
    β = 1/15) is added. 6 days."""
    u_max, theta0 = 80.0, np.pi / 7.0
    theta1 = 0.5 * np.pi - theta0
    e_n = np.exp(-4.0 / (theta1 - theta0) ** 2)

    def jet(lat):
        inside = (lat > theta0) & (lat < theta1)
        safe = np.where(inside, (lat - theta0) * (lat - theta1), -1.0)
        return np.where(inside, u_max / e_n * np.exp(1.0 / safe), 0.0)

    lat = np.linspace(-0.5 * np.pi, 0.5 * np.pi, samples)
    u = jet(lat)
    integrand = a * u * (2.0 * omega * np.sin(lat) + u * np.tan(np.clip(lat, -1.5, 1.5)) / a)  # u = 0 near the poles
    drop = cumulative_simpson(integrand, x=lat, initial=0.0) / g  # h0 − h(θ)
    mean_drop = 0.5 * np.trapezoid(drop * np.cos(lat), lat)  # the sphere's mean of h0 − h
    spline = CubicSpline(lat, drop)
    h0 = 10000.0 + mean_drop

    def depth(x):
        lon, la = longitude_latitude(x)
        h = h0 - spline(la)
        if perturbed:
            h = h + 120.0 * np.cos(la) * np.exp(-(lon / (1.0 / 3.0)) ** 2) * np.exp(-((np.pi / 4 - la) / (1.0 / 15.0)) ** 2)
        return h

    def velocity(x):
        _, la = longitude_latitude(x)
        return zonal_meridional(x, jet(la), np.zeros(x.shape[0]))

    return Case("galewsky" if perturbed else "galewsky_unperturbed", depth, velocity,
                lambda x: np.zeros(x.shape[0]), lambda x: 2.0 * omega * _unit(x)[:, 2], 6.0 * DAY)


def circulation(trisk: TRiSK, velocity: Field, radius: float, order: int = 4) -> np.ndarray:
    """(n1,) the primal 1-form U_e = ∫_e u·dl of a velocity field along the (chord) edges, with u
    evaluated at the radial projection of each Gauss–Legendre point onto the sphere of ``radius``."""
    return sample_vector_field(trisk.K, lambda x: velocity(radius * _unit(x)), order=order)


def error_norms(depth: np.ndarray, reference: np.ndarray, areas: np.ndarray) -> dict[str, float]:
    """Williamson et al. (1992) eq. 82–84 with I the area-weighted sum over the cells:
    l1 = I|h − hT| / I|hT|, l2 = √(I(h − hT)²) / √(I hT²), l∞ = max|h − hT| / max|hT|."""
    error = depth - reference
    return {"l1": float(areas @ np.abs(error) / (areas @ np.abs(reference))),
            "l2": float(np.sqrt(areas @ error ** 2 / (areas @ reference ** 2))),
            "linf": float(np.abs(error).max() / np.abs(reference).max())}


def invariants(trisk: TRiSK, depth: np.ndarray, circ: np.ndarray, topography: np.ndarray, coriolis: np.ndarray,
               g: float = GRAVITY) -> dict[str, float]:
    """The discrete invariants: mass Σ A_i h_i (m³), total energy Σ A_i (h_i K_i + g h_i (h_i/2 + b_i))
    (m⁵ s⁻², per unit density) and potential enstrophy Σ_v A_v h_v q_v²/2 (m s⁻²)."""
    areas = trisk.cell_areas
    kinetic = trisk.kinetic_energy(circ)
    depth_v = trisk.cell_to_triangle() @ depth
    pv = (trisk.vorticity(circ) + coriolis) / depth_v
    return {"mass": float(areas @ depth),
            "energy": float(areas @ (depth * kinetic + g * depth * (0.5 * depth + topography))),
            "potential_enstrophy": float(trisk.triangle_areas @ (0.5 * depth_v * pv ** 2))}


#: the half-length of the imaginary-axis interval inside each explicit Runge–Kutta method's
#: stability region: |λ dt| ≤ this for purely oscillatory modes (classical RK4: 2√2; SSPRK3: √3)
RK_STABILITY_INTERVAL = {"rk4": 2.0 * np.sqrt(2.0), "ssprk3": np.sqrt(3.0)}


def stable_time_step(trisk: TRiSK, depth_max: float, speed_max: float, method: str = "rk4",
                     g: float = GRAVITY) -> float:
    """The largest dt (s) the gravity waves and the advection allow:
    dt = β / ((√(g h_max) + |u|_max) √λ_max), β the method's imaginary stability interval
    (:data:`RK_STABILITY_INTERVAL`) and λ_max ≤ :meth:`TRiSK.laplacian_bound` (Gershgorin), so that
    2/√λ_max plays the role of the grid spacing: dt = β Δx / (2 (c + |u|))."""
    if method not in RK_STABILITY_INTERVAL:
        raise ValueError(f"method must be one of {sorted(RK_STABILITY_INTERVAL)}, not {method!r}")
    return float(RK_STABILITY_INTERVAL[method] / ((np.sqrt(g * depth_max) + speed_max) * np.sqrt(trisk.laplacian_bound())))
