"""The verdict of a run that diverged, on a line of its own (not buried in the metrics line).

A run whose metrics say ``stable: false`` is not an answer: the command prints, before
"wrote …", one line with why and where it diverged and a time step that works —
``dt_suggested`` when the app computed one (the model app: :func:`decrun.methods.model.stability.suggested_dt`),
else 0.9 × the explicit critical step it reports (``dt_critical_explicit``, ``dt_stability_limit``),
else a quarter of its step.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = ["unstable_verdict"]


def _suggestion(metrics: dict[str, Any]) -> str:
    """``app.dt=<value>`` that works, or ``""`` when the run has no ``dt`` to name."""
    suggested = metrics.get("dt_suggested")
    if isinstance(suggested, (int, float)) and math.isfinite(suggested) and suggested > 0:
        return f"`app.dt={suggested:.12g}`"
    dt = metrics.get("dt")
    if not isinstance(dt, (int, float)) or not math.isfinite(dt) or dt <= 0:
        return ""
    limits = [metrics.get(key) for key in ("dt_critical_explicit", "dt_stability_limit")]
    finite = [value for value in limits if isinstance(value, (int, float)) and math.isfinite(value) and value > 0]
    step = min([dt / 4, *(0.9 * value for value in finite)])
    return f"`app.dt={float(f'{step:.2g}'):g}`"


def unstable_verdict(metrics: dict[str, Any]) -> str:
    """The one line of a diverged run (``stable`` is False), or ``""``."""
    if metrics.get("stable") is not False:
        return ""
    step = metrics.get("diverged_at_step")
    reason = metrics.get("unstable_reason") or "the run diverged"
    where = f" (diverged at step {step})" if step is not None and f"step {step}" not in str(reason) else ""
    fix = _suggestion(metrics)
    advice = f"; use a smaller time step, e.g. {fix}" if fix else ""
    return f"decrun: UNSTABLE, not an answer: {reason}{where}{advice}"
