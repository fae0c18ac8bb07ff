"""Configs Hydra cannot read end as one line naming the override or the file (issue 24,
item 7): overrides nested thousands of levels deep (refused before Hydra's parser would
overflow Python's stack), YAML python tags (refused by the loader, never run), YAML
errors and config files too deep to load — in single runs and in ``-m`` sweeps."""

from __future__ import annotations

import pytest
from test_bad_input import assert_one_clear_line, decrun

from decrun.runner.job.failures import MAX_NESTING, nesting_depth, override_nesting_error


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


# ----------------------------------------------------------------------------------
# issue 34 item 4: interpolations that do not resolve, and _target_ on plain root nodes
# ----------------------------------------------------------------------------------

UNSET = "DECRUN_TEST_SURELY_UNSET"
#: override → words of the one line; the line's backticked override is the fix (run below)
UNRESOLVED = {
    "unset-env": (f"app.dt=${{oc.env:{UNSET}}}", [f"app.dt='${{oc.env:{UNSET}}}'", f"{UNSET} is not set"]),
    "unknown-resolver": ("app.dt=${nowhere:1}", ["app.dt='${nowhere:1}'", "there is no resolver 'nowhere'"]),
    "self-reference": ("app.dt=${app.dt}", ["app.dt='${app.dt}'", "refers to itself"]),
    "missing-key": ("app.steps=${app.nowhere}", ["app.steps='${app.nowhere}'", "refers to app.nowhere"]),
    "root-value": (f"progress=${{oc.env:{UNSET}}}", [f"progress='${{oc.env:{UNSET}}}'", f"{UNSET} is not set"]),
    "mesh-option": (f"mesh.subdiv=${{oc.env:{UNSET}}}", ["mesh.subdiv=", f"{UNSET} is not set"]),
    "list-option": (f"mesh.post=${{oc.env:{UNSET}}}", ["mesh.post=", "use `mesh.post=[repair,up_axis,"]),
    # no default to offer (the plugin is unknown while its _target_ does not resolve): drop it
    "plugin-target": (f"app._target_=${{oc.env:{UNSET}}}", ["app._target_=", "drop the override of app._target_"]),
}


def _fix(line: str) -> list[str]:
    from test_hints import OVERRIDE

    return OVERRIDE.findall(line)


@pytest.mark.parametrize("multirun", [False, True], ids=["run", "sweep"])
@pytest.mark.parametrize("override, words", UNRESOLVED.values(), ids=UNRESOLVED.keys())
def test_an_interpolation_that_does_not_resolve_is_one_line_naming_the_key(tmp_path, override, words, multirun):
    sweep = ["-m", "app.scheme=implicit,explicit"] if multirun else []
    proc = decrun(*sweep, override, cwd=tmp_path)
    line = assert_one_clear_line(proc, "error: ", *words)
    assert not list(tmp_path.rglob("result.h5"))  # nothing ran
    if multirun:
        assert "nothing ran" in line
        return
    fix = _fix(line)
    assert len(fix) == (0 if "drop the override" in line else 1), line  # e.g. `app.dt=null` (the default)
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    kept = [override] if fix else []  # "drop the override": the command without it
    done = run_experiment(compose_config(["mesh.subdiv=1", "figures=false", *kept, *fix]))
    assert done.result.metrics["status"] == "ok"


def test_an_unresolved_hydra_key_is_one_line_naming_it(tmp_path):
    proc = decrun(f"hydra.run.dir=${{oc.env:{UNSET}}}", cwd=tmp_path)
    assert_one_clear_line(proc, f"error: hydra.run.dir: the environment variable {UNSET} is not set")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("multirun", [False, True], ids=["run", "sweep"])
@pytest.mark.parametrize("root", ["checkpoint", "optimize"])
def test_target_on_a_plain_root_node_is_refused_naming_it(tmp_path, root, multirun):
    marker = tmp_path / "executed"
    sweep = ["-m", "app.steps=1,2"] if multirun else []
    proc = decrun(*sweep, f"+{root}._target_=pathlib.Path.touch", f"+{root}.self={marker}", cwd=tmp_path)
    assert_one_clear_line(proc, "error: ", f"{root}._target_: {root} holds plain options, it builds no class",
                          f"drop +{root}._target_=...")
    assert not marker.exists() and not list(tmp_path.rglob("result.h5"))


def test_an_unknown_option_of_a_plain_root_node_names_the_closest():
    from decrun.errors import ConfigError
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.experiment import validate

    with pytest.raises(ConfigError, match=r"^checkpoint\.stesp: unknown option of checkpoint.*"
                                          r"did you mean checkpoint\.steps\?"):
        validate(compose_config(["+checkpoint.stesp=3"]))
    assert validate(compose_config(["checkpoint.steps=3"])).checkpoint.steps == 3


# ----------------------------------------------------------------------------------
# issue 34.6: a 120 kB override value made a 120 kB error line
# ----------------------------------------------------------------------------------

LONG = "x" * 120_000


def test_shorten_words_cuts_only_long_words():
    from decrun.runner.job.failures import LONG_WORD, shorten_words

    assert shorten_words("app.dt: must be > 0, got -1") == "app.dt: must be > 0, got -1"
    assert shorten_words("a " + "y" * LONG_WORD) == "a " + "y" * LONG_WORD
    cut = shorten_words(f"error: app.dt: Value '{LONG}' of type 'str'")
    assert cut.startswith("error: app.dt: Value 'xxx") and cut.endswith("xxx' of type 'str'")
    assert "(120002 characters)" in cut and len(cut) < 200


@pytest.mark.parametrize("args, words", [
    ([f"app.dt={LONG}"], ["error: app.dt: Value 'xxx", "characters)", "could not be converted to Float"]),
    (["-m", f"app.scheme={LONG},explicit"], ["error: job 0 (app.scheme=xxx", "app.scheme: must be one of"]),
    (["mesh=file", f"mesh.path={LONG}"], ["error: mesh.path='xxx", "cannot be read (File name too long)"]),
    ([f"+app.{LONG}=1"], ["error: +app.xxx", "a name too long for the file system", "shorten it"]),
], ids=["value", "sweep-choice", "mesh-path", "key"])
def test_a_huge_override_value_is_cut_in_the_one_line(tmp_path, args, words):
    proc = decrun(*args, cwd=tmp_path)
    line = assert_one_clear_line(proc, *words)
    assert len(line) < 400, len(line)
    for metrics in tmp_path.rglob("metrics.json"):  # a failed run records the same short error
        assert metrics.stat().st_size < 1000
