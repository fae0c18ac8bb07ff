"""Sweeps without padding: a thesis experiment sweeps only keys that change its result, and a
sweep that does repeat a result (a key that does not act for the other values) says so — the
table's ``same_as`` column and one line at the end — through the real CLI."""

from __future__ import annotations

import pandas as pd
import pytest


def sweep(decrun_cli, tmp_path, name, *args):
    done = decrun_cli("-m", *args, "figures=false", f"hydra.sweep.dir={tmp_path / name}")
    assert done.returncode == 0, done.stderr
    return done, pd.read_csv(tmp_path / name / "metrics.csv")


def test_fig6_7_sweeps_each_result_once_and_a_padded_sweep_is_marked(decrun_cli, tmp_path):
    """Fig. 6.7 compares fixed and precomputed magnitudes: 2 jobs, 2 results (it ran three
    identical precomputed jobs, one per stroke length, which precomputed magnitudes ignore).
    Sweeping the stroke length under precomputed magnitudes anyway repeats job 0's result."""
    coarse = "mesh.refine_iterations=2"
    done, table = sweep(decrun_cli, tmp_path, "fig", "+experiment=fig6_7_cube", coarse)
    assert list(table["app.stroke_magnitude"]) == ["fixed", "precomputed"] and "app.stroke_length" not in table
    assert "same_as" not in table and "repeat" not in done.stdout
    assert table["content_sha256"].nunique() == 2
    done, table = sweep(decrun_cli, tmp_path, "padded", "+experiment=fig6_7_cube", coarse,
                        "app.stroke_magnitude=precomputed", "app.stroke_length=0.2,1.0,5.0")
    assert table["same_as"].isna().tolist() == [True, False, False] and list(table["same_as"][1:]) == [0, 0]
    assert "2 jobs repeat an earlier job's result exactly (column same_as: 1 = 0, 2 = 0)" in done.stdout
    done, _ = sweep(decrun_cli, tmp_path, "one", "+experiment=fig6_7_cube", coarse,
                    "app.stroke_magnitude=precomputed", "app.stroke_length=0.2,1.0")
    assert "decrun: 1 job repeats an earlier job's result exactly (column same_as: 1 = 0)" in done.stdout
    # the λ sweep of the experiment's comment: three results
    _, table = sweep(decrun_cli, tmp_path, "lambda", "+experiment=fig6_7_cube", coarse,
                     "app.stroke_magnitude=fixed", "app.stroke_length=0.2,1.0,5.0")
    assert "same_as" not in table and table["content_sha256"].nunique() == 3


@pytest.mark.slow
def test_fig5_8_sweeps_reflex_rows_only_where_they_act(decrun_cli, tmp_path):
    """Fig. 5.8 (T-hole, coarser sphere): 4 borders × 3 weights, 12 distinct results — the
    reflex rows, which only the conformal border reads, are no longer swept under the other
    three (9 identical jobs before); under the conformal border they differ."""
    _, table = sweep(decrun_cli, tmp_path, "fig", "+experiment=fig5_8_t_hole", "mesh.subdiv=4")
    assert len(table) == 12 and "same_as" not in table and table["content_sha256"].nunique() == 12
    _, table = sweep(decrun_cli, tmp_path, "reflex", "+experiment=fig5_8_t_hole", "mesh.subdiv=4",
                     "app.border=conformal", "app.reflex_rows=cauchy_riemann,harmonic")
    assert len(table) == 6 and "same_as" not in table
