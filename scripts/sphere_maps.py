"""Longitude–latitude maps of the shallow-water test cases' initial states (issue 49), drawn by
the runner's ``sphere_map`` / ``error_map`` figures from the formulas of Williamson et al. (1992)
and Galewsky et al. (2004) on an icosphere of radius a:

- TC2 at α = π/4: the depth h, whose extremes lie on the tilted axis (−sin α, 0, cos α);
- TC5: the free surface h + b over the mountain at (λ, θ) = (−90°, 30°);
- Galewsky: the jet's relative vorticity ζ = −(1/(a cos θ)) ∂(u cos θ)/∂θ, per triangle
  (at the circumcentres), contours every 2e-5 s⁻¹ from −1e-4 to 1e-4 over 0°–90°N.

    python scripts/sphere_maps.py [--out docs/gallery] [--subdiv 5]

writes ``sphere_tc5_surface.png`` and ``sphere_galewsky_vorticity.png`` (shown in docs/gallery.md)
and, with ``--all``, ``sphere_tc2_alpha45.png``. The formulas are those of ``../shared``'s
SHALLOW_WATER.md, written here again so the pictures do not depend on the model under construction.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

EARTH_RADIUS, OMEGA, GRAVITY, DAY = 6.37122e6, 7.292e-5, 9.80616, 86400.0


def longitude_latitude(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(λ, θ) in radians of points (n, 3)."""
    radius = np.linalg.norm(points, axis=1)
    return np.arctan2(points[:, 1], points[:, 0]), np.arcsin(np.clip(points[:, 2] / radius, -1.0, 1.0))


def tc2_depth(points: np.ndarray, alpha: float, a: float = EARTH_RADIUS) -> np.ndarray:
    """TC2: g h = g h0 − (a Ω u0 + u0²/2)(−cos λ cos θ sin α + sin θ cos α)², g h0 = 2.94e4."""
    lon, lat = longitude_latitude(points)
    u0 = 2.0 * np.pi * a / (12.0 * DAY)
    axial = -np.cos(lon) * np.cos(lat) * np.sin(alpha) + np.sin(lat) * np.cos(alpha)
    return (2.94e4 - (a * OMEGA * u0 + 0.5 * u0 ** 2) * axial ** 2) / GRAVITY


def tc5_mountain(points: np.ndarray) -> np.ndarray:
    """TC5: b = b0 (1 − r/R), b0 = 2000 m, R = π/9, r² = min(R², (λ − λc)² + (θ − θc)²),
    λc = −π/2, θc = π/6."""
    lon, lat = longitude_latitude(points)
    radius = np.pi / 9.0
    dlon = np.angle(np.exp(1j * (lon + 0.5 * np.pi)))
    return 2000.0 * (1.0 - np.sqrt(np.minimum(radius ** 2, dlon ** 2 + (lat - np.pi / 6.0) ** 2)) / radius)


def tc5_surface(points: np.ndarray, a: float = EARTH_RADIUS) -> np.ndarray:
    """TC5: h + b = h0 − (a Ω u0 + u0²/2) sin²θ / g, u0 = 20 m/s, h0 = 5960 m."""
    _, lat = longitude_latitude(points)
    return 5960.0 - (a * OMEGA * 20.0 + 200.0) * np.sin(lat) ** 2 / GRAVITY


def galewsky_vorticity(points: np.ndarray, a: float = EARTH_RADIUS) -> np.ndarray:
    """Galewsky's jet u(θ) = (u_max/e_n) exp(1/((θ − θ0)(θ − θ1))) on θ0 < θ < θ1 and its
    relative vorticity ζ = −(1/a)(u'(θ) − u tan θ), u' = −u (2θ − θ0 − θ1)/((θ − θ0)(θ − θ1))²."""
    _, lat = longitude_latitude(points)
    theta0 = np.pi / 7.0
    theta1 = 0.5 * np.pi - theta0
    inside = (lat > theta0) & (lat < theta1)
    product = np.where(inside, (lat - theta0) * (lat - theta1), -1.0)
    u = np.where(inside, 80.0 / np.exp(-4.0 / (theta1 - theta0) ** 2) * np.exp(1.0 / product), 0.0)
    du = -u * (2.0 * lat - theta0 - theta1) / product ** 2
    return -(du - u * np.tan(lat)) / a


def sphere(subdiv: int, radius: float = EARTH_RADIUS):
    """The complex of ``mesh=icosphere mesh.subdiv=<subdiv> mesh.radius=<radius>`` (no noise)."""
    from decrun.core.complex import SimplicialComplex
    from decrun.runner.mesh.sources.primitives import Icosphere

    mesh = Icosphere(subdiv=subdiv, radius=radius).load()
    return SimplicialComplex(mesh.vertices, mesh.simplices, orient="fix")


def circumcentres(K) -> np.ndarray:
    """(n2, 3) the triangles' circumcentres (where a dual 0-form's values sit)."""
    from decrun.core.dec import DEC

    return DEC(K).circumcenters(2)


def figures(K) -> dict:
    """file name → the matplotlib figure."""
    from decrun.runner.plots.sphere import sphere_map

    V = K.vertices
    return {
        "sphere_tc2_alpha45.png": sphere_map(K, tc2_depth(V, np.pi / 4), name="h", unit="m", time=0.0,
                                             title="TC2 depth h, α = π/4"),
        "sphere_tc5_surface.png": sphere_map(K, tc5_surface(V), name="h + b", unit="m", time=0.0,
                                             title="TC5 free surface h + b", interval=100.0,
                                             outline=tc5_mountain(V), outline_name="mountain b"),
        "sphere_galewsky_vorticity.png": sphere_map(K, galewsky_vorticity(circumcentres(K)), name="ζ", unit="s⁻¹",
                                                    time=0.0, title="Galewsky jet, relative vorticity",
                                                    value_range=(-1e-4, 1e-4), interval=2e-5, latitudes=(0, 90)),
    }


def main(argv: list[str] | None = None) -> int:
    from decrun.runner.plots.common import save_figure

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(Path(__file__).resolve().parents[1] / "docs" / "gallery"))
    parser.add_argument("--subdiv", type=int, default=5)
    parser.add_argument("--all", action="store_true", help="also the TC2 map (not shown in the docs)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name, fig in figures(sphere(args.subdiv)).items():
        if args.all or name != "sphere_tc2_alpha45.png":
            save_figure(fig, out / name, dpi=110)
            print(out / name)
    return 0


if __name__ == "__main__":
    sys.exit(main())
