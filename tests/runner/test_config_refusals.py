"""Configs Hydra cannot read end as one line naming the override or the file (issue 24,
item 7): overrides nested thousands of levels deep (refused before Hydra's parser would
overflow Python's stack), YAML python tags (refused by the loader, never run), YAML
errors and config files too deep to load — in single runs and in ``-m`` sweeps."""

from __future__ import annotations

import pytest
from test_bad_input import assert_one_clear_line, decrun

from decrun.runner.failures import MAX_NESTING, nesting_depth, override_nesting_error


@pytest.mark.parametrize("value, depth", [("1", 0), ("[[0,0,1,0.5]]", 2), ("{a:{b:[1]}}", 3), ("'[[[['", 0),
                                          ('"a\\"[[" ', 0), ("[" * 5000, 5000), ("[[]][[[]]]", 3)])
def test_nesting_depth_counts_brackets_outside_quotes(value, depth):
    assert nesting_depth(value) == depth


def test_only_overrides_deeper_than_the_limit_are_refused():
    ok = "+app.x=" + "[" * MAX_NESTING + "]" * MAX_NESTING
    assert override_nesting_error(["-m", ok, "app.dt=1,2", "hydra.searchpath=[file:///x]"]) is None
    deep = "+app.x=" + "[" * (MAX_NESTING + 1) + "]" * (MAX_NESTING + 1)
    assert override_nesting_error([ok, deep]).startswith("error: +app.x=[[[[")


DEEP = {"unclosed-list": "app.x=" + "[" * 5000, "dict": "+foo=" + "{a:" * 10000 + "1" + "}" * 10000}


@pytest.mark.parametrize("multirun", [False, True], ids=["run", "sweep"])
@pytest.mark.parametrize("override", DEEP.values(), ids=DEEP.keys())
def test_a_deeply_nested_override_is_one_line_naming_it(tmp_path, override, multirun):
    args = ["-m", override, "app.steps=1,2"] if multirun else [override]
    proc = decrun(*args, cwd=tmp_path)
    key = override.partition("=")[0]
    line = assert_one_clear_line(proc, f"error: {key}={override.partition('=')[2][:8]}", "levels deep",
                                 f"at most {MAX_NESTING} levels")
    assert len(line) < 300  # the value is shortened, not echoed 10000 times
    assert not (tmp_path / "outputs").exists()  # refused before anything ran


def test_an_override_within_the_limit_reaches_the_config_check(tmp_path):
    nested = "+app.x=" + "{a:" * MAX_NESTING + "1" + "}" * MAX_NESTING
    proc = decrun("-m", nested, "app.steps=1,2", cwd=tmp_path)
    assert_one_clear_line(proc, "app.x: unknown option of app=smoothing")


PYTHON_TAG = "# @package _global_\napp:\n  steps: !!python/object/apply:os.system [\"touch {marker}\"]\n"


@pytest.mark.parametrize("how", ["--config-dir", "hydra.searchpath", "swept"])
def test_a_python_tag_in_an_experiment_file_is_refused_naming_the_file(tmp_path, how):
    marker = tmp_path / "executed"
    experiment = tmp_path / "configs" / "experiment" / "evil.yaml"
    experiment.parent.mkdir(parents=True)
    experiment.write_text(PYTHON_TAG.format(marker=marker))
    if how == "--config-dir":
        args = [f"--config-dir={tmp_path / 'configs'}", "+experiment=evil"]
    elif how == "hydra.searchpath":
        args = [f"hydra.searchpath=[file://{tmp_path / 'configs'}]", "+experiment=evil"]
    else:  # a sweep over experiments: the sweeper composes the job that loads the file
        args = ["-m", f"hydra.searchpath=[file://{tmp_path / 'configs'}]", "+experiment=fig5_5_flat_hole,evil"]
    proc = decrun(*args, cwd=tmp_path)
    assert_one_clear_line(proc, f"error: {experiment}, line 3", "!!python/object/apply:os.system is refused")
    assert not marker.exists()
    assert not list(tmp_path.rglob("metrics.json"))  # no job ran


@pytest.mark.parametrize("body, words", [
    ("x: " + "[" * 5000 + "]" * 5000, [": nested too deeply to load"]),
    ("x: " + "{a: " * 5000 + "1" + "}" * 5000, [": nested too deeply to load"]),
    ("x: [1, 2", [", line 4, column 1: invalid YAML: while parsing a flow sequence"]),
], ids=["deep-list", "deep-dict", "syntax"])
@pytest.mark.parametrize("multirun", [False, True], ids=["run", "sweep"])
def test_an_unreadable_experiment_file_is_one_line_naming_it(tmp_path, body, words, multirun):
    experiment = tmp_path / "configs" / "experiment" / "broken.yaml"
    experiment.parent.mkdir(parents=True)
    experiment.write_text("# @package _global_\napp:\n  " + body + "\n")
    sweep = ["-m", "app.steps=1,2"] if multirun else []
    proc = decrun(f"--config-dir={tmp_path / 'configs'}", *sweep, "+experiment=broken", cwd=tmp_path)
    assert_one_clear_line(proc, f"error: {experiment}", *words)
