"""Two runs compared field by field (``decrun-table --compare RUN_A RUN_B``, or
:func:`compare_runs`).

For every field of either result: its shape, max |a − b|, the L2 difference ‖a − b‖₂ (the
plain Euclidean norm over the field's values) and that relative to ‖a‖₂. A field only one run
has, or whose shapes differ, is a row saying so (its differences empty), never skipped. A run is
a run or job directory, its ``result.h5``, or a killed job's ``result.h5.partial``.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import pandas as pd

__all__ = ["compare_runs", "COLUMNS"]

COLUMNS = ["field", "shape", "max_abs_difference", "l2_difference", "l2_difference_relative", "note"]


def _values(field) -> np.ndarray:
    """A field's numbers as an array (a 1-form's values without its edge list)."""
    return np.asarray(getattr(field, "values", field), dtype=np.float64)


def compare_runs(run_a: str | os.PathLike, run_b: str | os.PathLike) -> pd.DataFrame:
    """One row per field (sorted by name; :data:`COLUMNS`): ``max_abs_difference`` =
    max |a − b|, ``l2_difference`` = ‖a − b‖₂, ``l2_difference_relative`` = ‖a − b‖₂ / ‖a‖₂
    (empty when ‖a‖₂ = 0), ``note`` why a row has no differences ("only in A", "shapes differ")."""
    from decrun.runner.results import read_result

    a, b = read_result(run_a).fields, read_result(run_b).fields
    rows: list[dict[str, Any]] = []
    for name in sorted(set(a) | set(b)):
        if name not in b or name not in a:
            only = "A" if name in a else "B"
            rows.append({"field": name, "shape": str(_values((a if only == "A" else b)[name]).shape),
                         "note": f"only in {only}"})
            continue
        first, second = _values(a[name]), _values(b[name])
        if first.shape != second.shape:
            rows.append({"field": name, "shape": f"{first.shape} vs {second.shape}", "note": "shapes differ"})
            continue
        difference = first - second
        norm = float(np.linalg.norm(first))
        l2 = float(np.linalg.norm(difference))
        rows.append({"field": name, "shape": str(first.shape),
                     "max_abs_difference": float(np.abs(difference).max()) if difference.size else 0.0,
                     "l2_difference": l2, "l2_difference_relative": l2 / norm if norm > 0 else None, "note": ""})
    return pd.DataFrame(rows, columns=COLUMNS)
