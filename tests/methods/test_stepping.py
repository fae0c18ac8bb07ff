"""decrun.methods.stepping.run_steps: the loop, the record schedule, blow-up detection and
resuming from a checkpoint give exactly the uninterrupted run; the fluid's state (with its
shadow) round-trips through state_dict / load_state bitwise."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from decrun.methods.stepping import nonfinite_in, run_steps


class Growth:
    """x_{n+1} = a x_n + sin(n) (a deterministic state with a step index)."""

    record_divergent_step = False

    def __init__(self, a=0.9, blow_at=None):
        self.x, self.a, self.n, self.blow_at = np.linspace(0.0, 1.0, 5), a, 0, blow_at

    def values(self):
        return {"x": self.x.copy(), "norm": float(np.linalg.norm(self.x))}

    def step(self, n):
        self.x = self.a * self.x + np.sin(n)
        if n == self.blow_at:
            self.x[2] = np.inf
        self.n = n
        return ""

    def state_dict(self):
        return {"x": self.x, "n": self.n}

    def load_state(self, state):
        self.x, self.n = np.array(state["x"]), int(state["n"])


class Recorder:
    def __init__(self):
        self.records = []

    def __call__(self, step, **values):
        self.records.append((step, values))

    def truncate(self, n):
        del self.records[n:]


class MemoryCheckpoint:
    """Keeps the last checkpoint (a deep copy, as a file would) and the record count then."""

    def __init__(self, recorder, every):
        self.recorder, self.every, self.saved = recorder, every, None

    def load(self, check):
        if self.saved is None or check(self.saved[0], self.saved[1]):  # a fresh start: a new journal
            self.recorder.truncate(0)
            return None
        step, state, records = self.saved
        self.recorder.truncate(records)
        return step, copy.deepcopy(state)

    def due(self, step):
        return step % self.every == 0

    def save(self, step, state):
        self.saved = (step, copy.deepcopy(state), len(self.recorder.records))


class Killed(Exception):
    pass


def test_records_follow_the_schedule_with_the_initial_and_last_state():
    record = Recorder()
    report = run_steps(Growth(), 10, record=record, record_every=4)
    assert [step for step, _ in record.records] == [0, 4, 8, 10]
    assert report.steps_done == 10 and report.stable and report.resumed_from_step is None
    assert "diverged_at_step" not in report.metrics()  # a metric that does not apply is absent


def test_a_non_finite_state_stops_the_run_with_the_step_and_the_array():
    record = Recorder()
    report = run_steps(Growth(blow_at=6), 10, record=record, record_every=1)
    assert report.diverged_at_step == 6 and report.steps_done == 6
    assert report.reason == "non-finite values in x at step 6"
    assert [step for step, _ in record.records] == [0, 1, 2, 3, 4, 5]  # the diverging step is not recorded
    assert report.metrics()["unstable_reason"] == report.reason
    assert nonfinite_in({"a": {"b": np.array([1.0, np.nan])}, "c": float("inf")}) == "a.b"


@pytest.mark.parametrize("kill_at", [3, 7, 12])
def test_a_run_killed_after_a_checkpoint_resumes_to_the_uninterrupted_records(kill_at):
    reference = Recorder()
    run_steps(Growth(), 15, record=reference, record_every=2)

    record = Recorder()
    checkpoint = MemoryCheckpoint(record, every=5)
    killer = Growth()
    original = killer.step

    def step(n):
        if n == kill_at:
            raise Killed
        return original(n)

    killer.step = step
    with pytest.raises(Killed):
        run_steps(killer, 15, record=record, record_every=2, checkpoint=checkpoint)
    report = run_steps(Growth(), 15, record=record, record_every=2, checkpoint=checkpoint)
    assert report.resumed_from_step == (None if kill_at < 5 else 5 * ((kill_at - 1) // 5))
    assert [s for s, _ in record.records] == [s for s, _ in reference.records]
    for (_, a), (_, b) in zip(record.records, reference.records, strict=True):
        assert np.array_equal(a["x"], b["x"]) and a["norm"] == b["norm"]


def test_the_fluid_and_its_shadow_continue_bitwise_from_a_state_dict():
    from decrun.core.complex import SimplicialComplex
    from decrun.core.dec import DEC
    from decrun.core.solvers import solver_factory
    from decrun.methods.fluid import initial
    from decrun.methods.fluid.shadow import Shadow
    from decrun.methods.fluid.simulation import VorticityFluid

    from meshes_for_tests import icosphere

    V, F = icosphere(2)
    dec = DEC(SimplicialComplex(V, F), star="circumcentric")

    def make():
        fluid = VorticityFluid(dec, solver_factory(None), dt=0.01, viscosity=0.01,
                               initial_vorticity=initial.random_vorticity(dec, seed=3, amplitude=2.0))
        return fluid, Shadow(fluid, 1e-10, seed=4, window_steps=4)

    fluid, shadow = make()
    for _ in range(6):
        fluid.step()
        shadow.step()
    state = copy.deepcopy({"fluid": fluid.state_dict(), "shadow": shadow.state_dict()})
    for _ in range(6):
        fluid.step()
        shadow.step()

    again, again_shadow = make()
    again.load_state(state["fluid"])
    again_shadow.load_state(state["shadow"])
    for _ in range(6):
        again.step()
        again_shadow.step()
    for name in ("vorticity", "psi", "flux"):
        assert np.array_equal(getattr(fluid, name), getattr(again, name)), name
    assert fluid.time == again.time and fluid.steps == again.steps == 12
    assert shadow.metrics() == again_shadow.metrics()
