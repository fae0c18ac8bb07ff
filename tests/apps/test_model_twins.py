"""Every shipped time-dependent model against its step written by hand in numpy/scipy
(benchmarks/model_twins.py, the twins bench_models.py times the models against): after 100
steps on a small mesh the two states agree to round-off, with both sparse factorizations."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

from model_twins import MODELS, model_and_twin  # noqa: E402

#: small meshes: the models' own defaults, the sphere at subdiv 2 (162 vertices), and Klausmeier's
#: 16 × 16 grid at its bands' spacing h = 1 (its default h = 1/15 makes ν ∂x a 300/unit advection
#: whose round-off, not the scheme, sets the last digits)
SMALL = {"heat": ["mesh.subdiv=2"], "wave": ["mesh.subdiv=2"], "mcf": ["mesh.subdiv=2"],
         "klausmeier": ["mesh.width=15", "mesh.height=15", "app.dt=0.05"]}


@pytest.mark.parametrize("library", ["direct", "auto"])
@pytest.mark.parametrize("name", sorted(MODELS))
def test_the_hand_written_twin_equals_the_model_to_round_off(name, library):
    """100 steps of the model and of its twin from the same state: max |model − hand| ≤ 1e-12 of
    max |hand| in every field, and the fields moved (the comparison is not of two still states)."""
    model_step, stepper, hand_step, hand = model_and_twin(name, SMALL.get(name, []), library)
    initial = {u: value.copy() for u, value in hand.items()}
    for _ in range(100):
        model_step()
        hand_step()
    moved = 0.0
    for u, value in hand.items():
        scale = np.abs(value).max()
        assert np.abs(stepper.state[u] - value).max() <= 1e-12 * scale, u
        moved = max(moved, np.abs(value - initial[u]).max() / scale)
    assert moved > 1e-4
