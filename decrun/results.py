"""Results of one run: :class:`Result` (what an application returns).

Applications never touch the disk; the runner writes a ``Result`` to ``result.h5`` and
``metrics.json``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class Result:
    """What an application returns.

    Attributes
    ----------
    fields : dict[str, np.ndarray]
        Named arrays living on the mesh: per vertex ``(n0, ...)``, per edge ``(n1, ...)``,
        per face ``(n2, ...)`` (the first axis says which), plus any other array a figure or
        a later run needs (e.g. ``uv``, ``vertices_final``).
    series : dict[str, np.ndarray]
        Per-step 1-D arrays (e.g. ``area`` of each time step).
    metrics : dict[str, float | int | bool | str]
        Flat scalars. Names say their unit or meaning (``solve_seconds``,
        ``angle_distortion_mean_deg``, ``stable``).
    figures : dict[str, Any]
        Optional matplotlib figures, keyed by file stem; the runner saves them as PNG.
    """

    fields: dict[str, np.ndarray] = field(default_factory=dict)
    series: dict[str, np.ndarray] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)
    figures: dict[str, Any] = field(default_factory=dict)
