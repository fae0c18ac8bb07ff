"""Every shipped model's numbers pinned to round-off (issue 47: the compiler rewrite must not
move them).

Each case is a shipped model (``conf/app/<model>.yaml``) on its default mesh, run a few steps
through the same composition as the ``decrun`` command, plus the heat model under every
integrator (on a diagonal and on Whitney's Galerkin ⋆). A run is reduced to a fingerprint —
per field its size, sum, Σ x², Σ |x| and Σ wᵢ xᵢ with fixed weights wᵢ = sin(0.7 i + 0.3), per
declared metric its value — and compared with ``model_pins.json``, written by the code of
``main`` before the rewrite (``python tests/methods/test_model_pins.py --write``). Round-off
here is 1e-9 relative to the field's size (Σ |x|): a reordered sum moves the last digits, a
changed scheme moves the third.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

from decrun.runner.job.config import compose_config
from decrun.runner.job.run import run_experiment

PINS = Path(__file__).with_name("model_pins.json")
#: relative tolerance of a pinned number (against the size of the field or the metric)
ROUND_OFF = 1e-9

#: name → overrides: every shipped model a few steps on its default mesh, and heat under each integrator
CASES: dict[str, list[str]] = {
    "heat": ["app=heat", "app.t_end=null", "app.steps=5"],
    "wave": ["app=wave", "app.t_end=null", "app.steps=5"],
    "poisson": ["app=poisson"],
    "heat_geodesics": ["app=heat_geodesics"],
    "darcy": ["app=darcy"],
    "brusselator": ["app=brusselator", "app.t_end=null", "app.steps=4"],
    "gray_scott": ["app=gray_scott", "app.steps=4"],
    "klausmeier": ["app=klausmeier", "app.steps=4"],
    "cahn_hilliard": ["app=cahn_hilliard", "app.steps=4"],
    "halfar": ["app=halfar", "app.t_end=null", "app.steps=4"],
    "mcf": ["app=mcf", "app.steps=3"],
}
for _integrator in ("explicit_euler", "rk4", "implicit_euler", "crank_nicolson", "imex", "semi_implicit", "bdf",
                    "radau", "rk45"):
    CASES[f"heat_{_integrator}"] = ["app=heat", "mesh.subdiv=2", f"app.integrator={_integrator}", "app.dt=0.002",
                                    "app.t_end=null", "app.steps=4"]
for _integrator in ("rk4", "implicit_euler", "crank_nicolson"):
    CASES[f"heat_whitney_{_integrator}"] = ["app=heat", "mesh.subdiv=2", "operator=whitney",
                                            f"app.integrator={_integrator}", "app.dt=0.002", "app.t_end=null",
                                            "app.steps=4"]
for _integrator in ("bdf", "radau", "rk45", "semi_implicit", "rk4"):  # nonlinear reactions: Jacobians, lagging
    CASES[f"gray_scott_{_integrator}"] = ["app=gray_scott", f"app.integrator={_integrator}", "app.steps=3"]


def fingerprint(overrides: list[str]) -> dict:
    """The numbers of one run: ``{"fields": {name: [size, Σx, Σx², Σ|x|, Σwx]}, "metrics": {…}}``."""
    result = run_experiment(compose_config([*overrides, "figures=false", "progress=false"])).result
    fields = {}
    for name, value in sorted(result.fields.items()):
        x = np.asarray(getattr(value, "values", value), dtype=np.float64).ravel()
        weights = np.sin(0.7 * np.arange(x.size) + 0.3)
        fields[name] = [float(x.size), float(x.sum()), float(x @ x), float(np.abs(x).sum()), float(weights @ x)]
    declared = compose_config(overrides).app.get("metrics") or {}
    metrics = {name: float(result.metrics[name]) for name in sorted(declared)}
    return {"fields": fields, "metrics": metrics}


def _close(got: float, want: float, scale: float) -> bool:
    if math.isnan(want):
        return math.isnan(got)
    return abs(got - want) <= ROUND_OFF * max(scale, abs(want), 1e-300)


def differences(got: dict, want: dict) -> list[str]:
    """What moved between two fingerprints (empty when they agree to round-off)."""
    out = []
    if sorted(got["fields"]) != sorted(want["fields"]):
        out.append(f"fields {sorted(got['fields'])} != {sorted(want['fields'])}")
    for name, pinned in want["fields"].items():
        now = got["fields"].get(name)
        if now is None:
            continue
        size, _, squares, absolute, _ = pinned
        scales = [0, absolute, squares, absolute, absolute]
        labels = ["size", "sum", "sum of squares", "sum of |x|", "weighted sum"]
        for label, a, b, scale in zip(labels, now, pinned, scales, strict=True):
            if not _close(a, b, scale):
                out.append(f"{name}: {label} {a!r} != {b!r}")
    for name, pinned in want["metrics"].items():
        now = got["metrics"].get(name)
        if now is None or not _close(now, pinned, abs(pinned)):
            out.append(f"metric {name}: {now!r} != {pinned!r}")
    return out


@pytest.mark.parametrize("case", sorted(CASES))
def test_shipped_model_numbers_unchanged(case):
    pinned = json.loads(PINS.read_text())
    assert case in pinned, f"{case} is not pinned; run python tests/methods/test_model_pins.py --write on main"
    problems = differences(fingerprint(CASES[case]), pinned[case])
    assert not problems, f"{case}: " + "; ".join(problems)


def test_a_changed_scheme_is_caught():
    """The comparison is not vacuous: the heat model with a 1 % larger diffusivity differs."""
    pinned = json.loads(PINS.read_text())["heat_rk4"]
    moved = fingerprint([*CASES["heat_rk4"], "app.constants.k=1.01"])
    assert differences(moved, pinned)


if __name__ == "__main__":  # python tests/methods/test_model_pins.py --write   (on main's code only)
    if "--write" in sys.argv:
        PINS.write_text(json.dumps({name: fingerprint(overrides) for name, overrides in sorted(CASES.items())},
                                   indent=1, sort_keys=True) + "\n")
