"""Config-driven regression tests: every ``tests/regression/*.yaml`` is a list of cases,
each run through the same composition as the ``decrun`` command.

Case file format::

    common: [override, ...]          # optional, prepended to every case
    cases:                           # or a single case at top level (overrides/expect)
      - name: short_id
        overrides: [key=value, ...]
        expect:
          metric: value              # exact (bool, int, str) or float within 1e-12
          metric: {value: x, rtol: r, atol: a}
          metric: {min: lo, max: hi} # bounds; a bound may be "<factor> * <other metric>"
        expect_error: "words"        # instead of expect: the run must fail with a DecrunError
                                     # whose message matches these words (a regex)
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from decrun.errors import DecrunError
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import run_experiment

HERE = Path(__file__).parent


def _cases():
    for path in sorted(HERE.glob("*.yaml")):
        spec = yaml.safe_load(path.read_text())
        common = list(spec.get("common", []))
        cases = spec.get("cases") or [dict(name="case", overrides=spec.get("overrides", []), expect=spec["expect"])]
        for case in cases:
            expect = case["expect"] if "expect" in case else {"__error__": case["expect_error"]}
            yield pytest.param(common + list(case.get("overrides", [])), expect,
                               id=f"{path.stem}::{case.get('name', 'case')}")


def _bound(bound, metrics):
    if isinstance(bound, str):
        factor, _, name = bound.partition("*")
        return float(factor) * float(metrics[name.strip()]) if name else float(metrics[factor.strip()])
    return float(bound)


def check(metrics: dict, expect: dict) -> list[str]:
    """Messages for every expectation ``metrics`` violates (empty when all hold)."""
    problems = []
    for name, want in expect.items():
        if name not in metrics:
            problems.append(f"{name}: missing (have {sorted(metrics)})")
            continue
        got = metrics[name]
        if isinstance(want, dict):
            if "value" in want:
                tol = want.get("atol", 0.0) + want.get("rtol", 1e-12) * abs(want["value"])
                if not abs(got - want["value"]) <= tol:
                    problems.append(f"{name} = {got!r}, expected {want['value']} ± {tol:.3g}")
            if "min" in want and not got >= _bound(want["min"], metrics):
                problems.append(f"{name} = {got!r} < min {want['min']} = {_bound(want['min'], metrics):.6g}")
            if "max" in want and not got <= _bound(want["max"], metrics):
                problems.append(f"{name} = {got!r} > max {want['max']} = {_bound(want['max'], metrics):.6g}")
        elif isinstance(want, float) and isinstance(got, float):
            if not (math.isclose(got, want, rel_tol=1e-12) or (math.isnan(got) and math.isnan(want))):
                problems.append(f"{name} = {got!r}, expected {want!r}")
        elif got != want:
            problems.append(f"{name} = {got!r}, expected {want!r}")
    return problems


@pytest.mark.parametrize("overrides, expect", list(_cases()))
def test_regression_case(overrides, expect):
    cfg = compose_config(overrides)
    if "__error__" in expect:  # a case whose point is a clear refusal (expect_error: words)
        with pytest.raises(DecrunError, match=expect["__error__"]):
            run_experiment(cfg)
        return
    result = run_experiment(cfg).result
    problems = check(result.metrics, expect)
    assert not problems, f"decrun {' '.join(overrides)}:\n  " + "\n  ".join(problems)


def test_check_rejects_violations():
    """The checker itself fails on a wrong value, a broken bound and a missing metric."""
    metrics = {"stable": True, "a": 1.0, "b": 4.0}
    assert check(metrics, {"stable": True, "a": {"value": 1.0}, "b": {"max": "4 * a"}}) == []
    assert len(check(metrics, {"stable": False})) == 1
    assert len(check(metrics, {"a": {"value": 1.1, "rtol": 0.01}})) == 1
    assert len(check(metrics, {"b": {"max": "3 * a"}})) == 1
    assert len(check(metrics, {"missing": 1})) == 1
