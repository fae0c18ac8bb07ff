"""One time-stepping driver for every app that steps a state (smoothing, fluid).

An app wraps its method in a :class:`Stepper` (its state and one step) and hands it to
:func:`run_steps`, which owns everything around the steps: the loop and its progress bar,
recording every ``record_every`` steps (``record(step, **values)``), blow-up detection (the
stepper's own reason, or non-finite floats in its state: the run stops with a clear
:attr:`StepReport.reason`, never an exception), per-step timing, and periodic checkpoints
through a :class:`Checkpoint` (the runner's writes an atomic, checksummed HDF5 file in the
run directory; this layer knows no files). On start a valid checkpoint of the same run is
loaded and the loop continues from its step: the state, the records and the driver's
counters are those of the uninterrupted run at that step, so the result is bitwise equal.

Determinism contract of a stepper: :meth:`Stepper.state_dict` holds *everything* a later
step reads (arrays, step index, counters, RNG state if any) as numpy arrays or Python
scalars, and :meth:`Stepper.load_state` of it makes the next steps exactly those of the
run it came from.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Optional, Protocol

import numpy as np

__all__ = ["Stepper", "Checkpoint", "StepReport", "run_steps", "nonfinite_in", "state_mismatch"]


class Stepper(Protocol):
    """A state and one step of a time-stepping method."""

    #: record the step at which the state blew up (smoothing: its NaN measures) or not (fluid:
    #: its state stays the last finite one)
    record_divergent_step: bool
    #: optional: dotted paths of the state (e.g. ``("series",)``) whose size changes as the
    #: run goes -- an array there may differ from the fresh state's in its first axis and
    #: hold NaN (a history of measures), a dict there may have more keys (diagnostics).
    #: Everything else of a checkpoint's state must have the fresh state's structure
    #: (:func:`state_mismatch`).
    state_variable: tuple[str, ...]

    def values(self) -> dict[str, Any]:
        """What is recorded for the current state: scalars and fixed-shape arrays."""

    def step(self, n: int) -> str:
        """Advance the state from step ``n - 1`` to ``n``; returns ``""`` or why the state blew up."""

    def state_dict(self) -> dict[str, Any]:
        """Everything a later step reads: nested dicts of numpy arrays and Python scalars (or None)."""

    def load_state(self, state: dict[str, Any]) -> None:
        """Restore a :meth:`state_dict`."""


class Checkpoint(Protocol):
    """Where :func:`run_steps` keeps its state while it runs (the runner's is an HDF5 file)."""

    def load(self, check: Callable[[int, dict[str, Any]], str]) -> Optional[tuple[int, dict[str, Any]]]:
        """``(step, state)`` of a valid checkpoint of this same run (also setting the records
        back to that step), or None: none, another config's, corrupt, or one whose
        ``check(step, state)`` is not ``""`` (why it is not a state of this run; said in the
        log). ``check`` runs before anything is changed (the records)."""

    def due(self, step: int) -> bool:
        """Whether to write a checkpoint after ``step`` (every k steps, every s seconds)."""

    def save(self, step: int, state: dict[str, Any]) -> None:
        """Write ``state`` after ``step`` (atomically: the old checkpoint or the new one)."""


@dataclass
class StepReport:
    """What :func:`run_steps` did.

    ``steps_done``: steps computed (the diverging one included); ``diverged_at_step``: the
    step that blew up, or None; ``reason``: why (empty when none did); ``seconds``: wall time
    of the steps (s, over all the run's parts when it was resumed); ``step_seconds_max``:
    the slowest step (s); ``resumed_from_step``: the checkpoint's step, or None;
    ``checkpoints``: checkpoints written by this process."""

    steps_done: int = 0
    diverged_at_step: Optional[int] = None
    reason: str = ""
    seconds: float = 0.0
    step_seconds_max: float = 0.0
    resumed_from_step: Optional[int] = None
    checkpoints: int = 0
    extra: dict = field(default_factory=dict)

    @property
    def stable(self) -> bool:
        return self.diverged_at_step is None

    def metrics(self) -> dict[str, Any]:
        """The driver's metrics: ``steps_done``, ``solve_seconds``, ``steps_per_second``,
        ``step_seconds_max``, ``diverged_at_step`` and ``unstable_reason`` (only when a step
        blew up), ``resumed_from_step`` (only when resumed)."""
        out = {"steps_done": self.steps_done, "solve_seconds": self.seconds,
               "steps_per_second": self.steps_done / self.seconds if self.seconds > 0 else float("inf"),
               "step_seconds_max": self.step_seconds_max}
        if self.diverged_at_step is not None:
            out["diverged_at_step"] = self.diverged_at_step
            out["unstable_reason"] = self.reason
        if self.resumed_from_step is not None:
            out["resumed_from_step"] = self.resumed_from_step
        return out


def nonfinite_in(state: dict[str, Any], prefix: str = "") -> str:
    """The name of the first float array of ``state`` (nested dicts) holding a NaN or ±inf,
    or ``""`` (scalars are counters and diagnostics, which may be ±inf by design)."""
    for name, value in state.items():
        if isinstance(value, dict):
            found = nonfinite_in(value, f"{prefix}{name}.")
            if found:
                return found
        elif isinstance(value, np.ndarray) and value.dtype.kind in "fc" and not np.all(np.isfinite(value)):
            return prefix + name
    return ""


def _kind(value: Any) -> str:
    """The kind of a state leaf: dict, none, bool, int, float, array or other."""
    if isinstance(value, dict):
        return "dict"
    if value is None:
        return "none"
    if isinstance(value, (bool, np.bool_)):
        return "bool"
    if isinstance(value, (int, np.integer)):
        return "int"
    if isinstance(value, (float, np.floating)):
        return "float"
    return "array" if isinstance(value, np.ndarray) else "other"


def _a(kind: str) -> str:
    return f"an {kind}" if kind[0] in "aeiou" else f"a {kind}"


def _under(path: str, variable: tuple[str, ...]) -> bool:
    return any(path == v or path.startswith(v + ".") for v in variable)


def state_mismatch(state: Any, template: Any, variable: tuple[str, ...] = (), prefix: str = "") -> str:
    """Why ``state`` (read back from a checkpoint) is not a state with the structure of
    ``template`` (the fresh stepper's :meth:`~Stepper.state_dict`), or ``""``.

    Every dict has the template's keys (no fewer, no more); a leaf has the template's kind
    (a number where the template has a float; None where it has None, which also stands for
    an optional number); an array has the template's dtype and shape -- on this mesh: (n0, 3)
    is (n0, 3) -- and finite values. Under ``variable`` (:attr:`Stepper.state_variable`) an
    array's first axis is free and it may hold NaN, and a dict may have extra keys."""
    where = prefix or "the state"
    kind, expected = _kind(state), _kind(template)
    free = _under(prefix, variable)
    if expected == "dict":
        if kind != "dict":
            return f"{where} is {_a(kind)}, not a group"
        missing = [name for name in template if name not in state]
        if missing:
            return f"{prefix + '.' if prefix else ''}{missing[0]} is missing"
        extra = [name for name in state if name not in template]
        if extra and not free:
            return f"{prefix + '.' if prefix else ''}{extra[0]} is not part of this run's state"
        for name in template:
            found = state_mismatch(state[name], template[name], variable, f"{prefix}.{name}" if prefix else name)
            if found:
                return found
        return ""
    if expected == "none":
        return "" if kind in ("none", "bool", "int", "float") else f"{where} is {_a(kind)}, not a number or None"
    if expected == "float":
        return "" if kind in ("int", "float") else f"{where} is {_a(kind)}, not a number"
    if expected in ("int", "bool"):
        return "" if kind == expected else f"{where} is {_a(kind)}, not {_a(expected)}"
    if kind != "array":
        return f"{where} is {_a(kind)}, not an array"
    if state.dtype != template.dtype:
        return f"{where} has dtype {state.dtype}, this run's has {template.dtype}"
    shape_ok = state.shape[1:] == template.shape[1:] if free and state.ndim == template.ndim and state.ndim \
        else state.shape == template.shape
    if not shape_ok:
        return f"{where} has shape {state.shape}, this run's has {template.shape}"
    if not free and state.dtype.kind in "fc" and not np.all(np.isfinite(state)):
        return f"{where} holds {int(np.sum(~np.isfinite(state)))} non-finite values"
    return ""


def _passthrough(iterable: Iterable, **_) -> Iterable:
    return iterable


def run_steps(stepper: Stepper, steps: int, *, progress: Callable | None = None,
              record: Callable[..., None] | None = None, record_every: int = 1,
              checkpoint: Checkpoint | None = None, desc: str = "", check_finite: bool = True) -> StepReport:
    """Run ``stepper`` from step 0 (or a checkpoint's step) to ``steps``.

    Step 0 (the initial state) is recorded unless resumed; then step n is recorded when
    ``n % record_every == 0`` or ``n == steps`` (and the diverging step when the stepper
    says ``record_divergent_step``). After a step the state blows up when the stepper
    returns a reason, or (``check_finite``) a float of its :meth:`~Stepper.state_dict` is
    not finite: the loop stops there (``diverged_at_step``, ``reason``). A checkpoint is
    written after step n when ``checkpoint.due(n)`` (not after the last step: the run is
    ending). ``progress(iterable, total=, desc=, initial=)`` is a tqdm-like factory.

    A checkpoint's state is used only when its step is within [0, ``steps``] and it has the
    structure of the fresh stepper's :meth:`~Stepper.state_dict` (:func:`state_mismatch`,
    with :attr:`Stepper.state_variable`) and finite, non-negative driver times; the
    checkpoint is asked (``checkpoint.load(check)``) before it changes anything.
    """
    progress = progress or _passthrough
    report = StepReport()
    start = 0
    loaded = None
    if checkpoint is not None:
        template = {"stepper": stepper.state_dict(), "driver": {"seconds": 0.0, "step_seconds_max": 0.0}}
        variable = tuple(f"stepper.{path}" for path in getattr(stepper, "state_variable", ()))

        def check(step: int, state: dict[str, Any]) -> str:
            if not 0 <= step <= steps:
                return f"step {step} is outside [0, {steps}] (this run has {steps} steps)"
            found = state_mismatch(state, template, variable)
            if found:
                return found
            driver = state["driver"]
            bad = [name for name in driver if not 0 <= driver[name] < float("inf")]
            return f"driver.{bad[0]} is {driver[bad[0]]}, not a time in seconds" if bad else ""

        loaded = checkpoint.load(check)
    if loaded is not None:
        start, state = loaded
        stepper.load_state(state["stepper"])
        driver = state["driver"]
        report.seconds, report.step_seconds_max = float(driver["seconds"]), float(driver["step_seconds_max"])
        report.resumed_from_step = start
    elif record is not None:
        record(0, **stepper.values())
    report.steps_done = start
    bar = progress(range(start + 1, steps + 1), total=steps, desc=desc, initial=start)
    for n in bar:
        t = time.perf_counter()
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            reason = stepper.step(n)
            if not reason and check_finite:
                bad = nonfinite_in(stepper.state_dict())
                reason = f"non-finite values in {bad} at step {n}" if bad else ""
        seconds = time.perf_counter() - t
        report.seconds += seconds
        report.step_seconds_max = max(report.step_seconds_max, seconds)
        report.steps_done = n
        if reason:
            report.diverged_at_step, report.reason = n, reason
            if record is not None and stepper.record_divergent_step:
                record(n, **stepper.values())
            break
        if record is not None and (n % record_every == 0 or n == steps):
            record(n, **stepper.values())
        if checkpoint is not None and n < steps and checkpoint.due(n):
            checkpoint.save(n, {"stepper": stepper.state_dict(),
                                "driver": {"seconds": report.seconds, "step_seconds_max": report.step_seconds_max}})
            report.checkpoints += 1
    close = getattr(bar, "close", None)
    if close is not None:
        close()
    return report
