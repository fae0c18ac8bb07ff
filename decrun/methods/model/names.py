"""Names a model declares, checked against the parser and the run's record (issue 50, items 3 and 4).

- **Look-alike names.** Python's parser reads every identifier in its NFKC form (``𝕜`` is read
  as ``k``, ``ﬁ`` as ``fi``), so a declared name that is not in NFKC form is never the name its
  equations read: with constants ``k = 1`` and ``𝕜 = 5`` every ``𝕜`` in an equation is ``k``,
  silently 1. Such a name is refused, naming the name it folds onto (and the other declaration
  when there is one).
- **The run's record.** The metrics a run writes to ``metrics.json`` and the sweep table hold
  decrun's own entries beside the model's (:data:`RECORD_NAMES`, and per field ``<field>_<suffix>``
  for :data:`FIELD_SUFFIXES`); a declared metric of one of those names would be replaced, so it
  is refused.
"""

from __future__ import annotations

import unicodedata

from decrun.methods.model.language import ModelError

__all__ = ["RECORD_NAMES", "FIELD_SUFFIXES", "check_lookalike_names", "check_metric_names"]

#: entries the runner writes into a run's metrics.json and a sweep table's row, beside the model's
#: own metrics (decrun.runner.job.run, .failures, .results, .sweep.tables: the test of this module
#: reads them there)
RECORD_NAMES = frozenset({
    "result_h5", "config_hash", "status", "error", "warnings", "n_vertices", "n_faces", "total_seconds",
    "setup_seconds", "figures_error", "figures_interrupted", "figures_not_drawn", "export_error",
    "chained_result_status", "headline_metrics", "job", "result", "same_as", "sweep",
    *(f"{step}_{what}" for step in ("clean", "largest_component", "holes")
      for what in ("components", "dropped_vertices", "dropped_faces")),
})

#: what a model run reports per unknown of a solve (decrun.methods.model.metrics.model_metrics)
FIELD_SUFFIXES = ("newton_iterations", "kernel_pieces", "rhs_mean_removed", "rhs_mean")


def check_lookalike_names(key: str, groups: dict[str, dict]) -> None:
    """Refuse a declared name (``groups``: ``{"fields": {...}, "constants": {...}}``) whose NFKC
    form differs from it: the equations could never read it under its own name."""
    declared = {name: group for group, names in groups.items() for name in names if isinstance(name, str)}
    for name, group in declared.items():
        folded = unicodedata.normalize("NFKC", name)
        if folded == name:
            continue
        if folded in declared:
            raise ModelError(f"{key}.{group}.{name}: {name!r} reads as {folded!r} in equations (Unicode NFKC folds "
                             f"it), the name of {key}.{declared[folded]}.{folded}, so both would be one; rename "
                             f"{name!r} to a name of plain letters")
        raise ModelError(f"{key}.{group}.{name}: {name!r} reads as {folded!r} in equations (Unicode NFKC folds it); "
                         f"declare it as {folded!r}")


def check_metric_names(key: str, metrics, fields) -> None:
    """Refuse a declared metric named as an entry of the run's record (:data:`RECORD_NAMES`) or as
    a per-field report (``u_rhs_mean``: :data:`FIELD_SUFFIXES`)."""
    per_field = {f"{field}_{suffix}" for field in fields for suffix in FIELD_SUFFIXES}
    for name in metrics:
        if name in RECORD_NAMES or name in per_field:
            raise ModelError(f"{key}.metrics.{name}: {name!r} is an entry decrun writes into every run's record "
                             f"(metrics.json, the sweep table), so yours would be replaced; name yours otherwise, "
                             f"e.g. {name}_value")
