"""Steps per second of the YAML shallow-water model (conf/app/shallow_water.yaml through
``+experiment=williamson_tc5``) and of its hand-written twin (benchmarks/shallow_water_numpy.py's
``ShallowWater``) in the SAME run, on the same mesh and state: interleaved blocks of steps, so both see
the same machine load; the ratio model/twin is the claim (issue 49's goal: ≥ 0.8).

    PYTHONPATH=. python benchmarks/bench_shallow_water.py --subdiv 6 --steps 40 --blocks 5

Prints one JSON line: steps/s of each (the median over the blocks), the ratio, the largest difference of
the two states after the run (they step the same scheme: round-off), the 1-minute load average.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from shallow_water_numpy import ShallowWater  # noqa: E402


def compiled_tc5(subdiv: int):
    """(compiled model, its RK4 stepper, dt) of ``decrun +experiment=williamson_tc5 mesh.subdiv=<subdiv>``."""
    from decrun.core.solvers import solver_factory
    from decrun.methods.model.integrators import make_integrator
    from decrun.methods.model.stepper import ModelStepper
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import prepare

    dt = {4: 1800.0, 5: 900.0, 6: 450.0, 7: 225.0}[subdiv]
    run = prepare(compose_config(["+experiment=williamson_tc5", f"mesh.subdiv={subdiv}", f"app.dt={dt}",
                                  "figures=false", "progress=false"]))
    app = run.experiment.app
    model = app.compiled(run.dec, solver_factory("auto"))
    stepper = ModelStepper(model, make_integrator(model, "rk4", dt, solver_factory("auto")), dt)
    return model, stepper, dt, app.constants["g"]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--subdiv", type=int, default=5)
    parser.add_argument("--steps", type=int, default=40, help="steps per block")
    parser.add_argument("--blocks", type=int, default=5)
    args = parser.parse_args()
    from decrun.core.trisk import TRiSK

    model, stepper, dt, g = compiled_tc5(args.subdiv)
    hand = ShallowWater(TRiSK(model.ops.dec), model.initial_values["b"], model.initial_values["f"], g=g)
    h, U = stepper.state["depth"].copy(), stepper.state["u"].copy()
    hand.step(h, U, dt, "rk4")  # warm both (the twin's matrices, the model's caches)
    yaml_rates, hand_rates, n = [], [], 0
    for _ in range(args.blocks):
        tick = time.perf_counter()
        for _ in range(args.steps):
            n += 1
            assert not stepper.step(n)
        yaml_rates.append(args.steps / (time.perf_counter() - tick))
        tick = time.perf_counter()
        for _ in range(args.steps):
            h, U = hand.step(h, U, dt, "rk4")
        hand_rates.append(args.steps / (time.perf_counter() - tick))
    yaml_rate, hand_rate = float(np.median(yaml_rates)), float(np.median(hand_rates))
    difference = max(float(np.abs(stepper.state["depth"] - h).max() / np.abs(h).max()),
                     float(np.abs(stepper.state["u"] - U).max() / np.abs(U).max()))
    print(json.dumps({"subdiv": args.subdiv, "cells": int(h.size), "dt": dt, "steps": n,
                      "yaml_steps_per_second": yaml_rate, "twin_steps_per_second": hand_rate,
                      "ratio": yaml_rate / hand_rate, "yaml_blocks": yaml_rates, "twin_blocks": hand_rates,
                      "max_relative_difference": difference, "load_average_1min": os.getloadavg()[0]}))


if __name__ == "__main__":
    main()
