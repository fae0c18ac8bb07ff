"""Benchmark: steady-flow drift of the vorticity fluid vs mesh size, per scheme (issue 18).

One step at ν = 0, dt = 0.001 from an exact steady state (tests/fluid_cases.py): rigid
rotation and the degree-2 state w = 6xz on unit icospheres (320 … 20k faces, 82k with --full),
the cellular flow sin πx sin πy on regular and 0.15 h-jittered lattices of the unit square.
Drift = ‖w₁ − w₀‖_⋆0 / ‖w₀‖_⋆0 / dt (1/s); the order is log(drift ratio) / log(h ratio) between
successive rows (h ∝ faces^-1/2): positive = converging. Schemes (velocity, circulation):
thesis (wshd07, trapezoid), corrected (wshd07, corrected_trapezoid — decrun's former default),
wshd07_swept, default (least_squares, swept).

    OMP_NUM_THREADS=1 python benchmarks/bench_fluid_drift.py            # ~2 min
    OMP_NUM_THREADS=1 python benchmarks/bench_fluid_drift.py --full     # + 82k faces, 64-cell lattices
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from fluid_cases import CASES, SCHEMES, drift_per_s, steady_case  # noqa: E402

LEVELS = {"sphere": [2, 3, 4, 5], "lattice": [8, 16, 32]}
FULL = {"sphere": [6], "lattice": [64]}


def table(case: str, levels, schemes) -> list[str]:
    """Markdown rows: faces, then drift (order) per scheme."""
    rows, previous = [], None
    for level in levels:
        dec, w0, mask = steady_case(case, level)
        faces = dec.K.num_simplices(2)
        drift = {s: drift_per_s(dec, w0, mask, s) for s in schemes}
        cells = []
        for s in schemes:
            if previous is None:
                cells.append(f"{drift[s]:.3g}")
            else:
                order = np.log(previous[1][s] / drift[s]) / np.log(np.sqrt(faces / previous[0]))
                cells.append(f"{drift[s]:.3g} ({order:+.2f})")
        rows.append(f"| {case} | {faces} | " + " | ".join(cells) + " |")
        print(rows[-1], flush=True)
        previous = (faces, drift)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="add the 82k-face sphere and 64-cell lattices")
    parser.add_argument("--cases", nargs="*", default=list(CASES), choices=CASES)
    args = parser.parse_args()
    schemes = list(SCHEMES)
    print("| case | faces | " + " | ".join(f"{s} drift 1/s (order)" for s in schemes) + " |")
    print("|---|---|" + "---|" * len(schemes))
    for case in args.cases:
        kind = "sphere" if case in ("rigid_rotation", "degree_2") else "lattice"
        table(case, LEVELS[kind] + (FULL[kind] if args.full else []), schemes)


if __name__ == "__main__":
    main()
