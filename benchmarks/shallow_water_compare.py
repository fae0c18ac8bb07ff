"""Williamson's normalized l1, l2, l∞ differences of the depth h between two outputs of
``shallow_water_spectral.py`` (the self-convergence of the spectral reference: T85 vs T170 vs T213, or two
time steps at one truncation), on the finer output's Gauss grid with its Gauss weights as the areas.

    python benchmarks/shallow_water_compare.py benchmarks/data/sw_tc5_T170_day15.npz /tmp/tc5_T85_day15.npz

The coarser coefficients are zero-padded to the finer truncation and synthesized there (ducc0); TC5's depth
is the free surface minus the exact cone, as in ``shallow_water_reference.Reference.depth``.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from shallow_water_reference import tc5_mountain, williamson_norms  # noqa: E402
from shallow_water_spectral import SpectralGrid  # noqa: E402


def padded(alm: np.ndarray, lmax: int, target: int) -> np.ndarray:
    """m-major coefficients of truncation ``lmax`` as those of ``target`` ≥ lmax (zeros above lmax)."""
    out = np.zeros((target + 1) * (target + 2) // 2, dtype=complex)
    for m in range(lmax + 1):
        source = m * (2 * lmax + 1 - m) // 2
        destination = m * (2 * target + 1 - m) // 2
        out[destination + m: destination + lmax + 1] = alm[source + m: source + lmax + 1]
    return out


def depth_on(grid: SpectralGrid, data) -> np.ndarray:
    """The stored output's depth (m) on ``grid``."""
    meta = json.loads(str(data["meta"]))
    lmax = int(data["lmax"])
    if meta["case"] == "tc5":
        latitude, longitude = grid.latitude + 0.0 * grid.longitude, grid.longitude + 0.0 * grid.latitude
        return grid.synthesis(padded(data["surface_lm"], lmax, grid.lmax)) - tc5_mountain(latitude, longitude)
    return grid.synthesis(padded(data["h_lm"], lmax, grid.lmax))


def compare(first: Path, second: Path) -> dict[str, float]:
    """Norms of (coarser − finer) / finer on the finer output's grid."""
    files = sorted((np.load(first), np.load(second)), key=lambda d: int(d["lmax"]))
    coarse, fine = files
    fine_meta = json.loads(str(fine["meta"]))
    grid = SpectralGrid(int(fine["lmax"]), fine_meta["nlat"], fine_meta["nlon"])
    area = grid.weights[:, None] + 0.0 * grid.longitude
    return williamson_norms(depth_on(grid, coarse), depth_on(grid, fine), area)


if __name__ == "__main__":
    print(json.dumps(compare(Path(sys.argv[1]), Path(sys.argv[2]))))
