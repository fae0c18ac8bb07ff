"""decrun's translators of Hydra's and OmegaConf's error texts, each held to the real error the
installed hydra-core and omegaconf raise: every case provokes the error through the ``decrun``
command's own Hydra app in this process (:func:`decrun.run`), checks that the translator meant for
it reads Hydra's exception (not a fallback) and that the command's line is its translation.

A new wording in a Hydra or OmegaConf release fails here, not in front of a user;
``scripts/check_hydra_versions.sh`` runs this file against every hydra-core release the
dependency pin admits."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

import decrun
from decrun.runner.command import errors
from decrun.runner.job import failures, hints

UNSET = "DECRUN_TEST_SURELY_UNSET"
SMALL = ["app=heat", "mesh.subdiv=1", "figures=false"]


@pytest.fixture
def here(tmp_path, monkeypatch):
    """The working directory is ``tmp_path``; ``UNSET`` is not in the environment."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv(UNSET, raising=False)
    return tmp_path


def refused(overrides: list[str], monkeypatch) -> tuple[str, BaseException]:
    """The command's line for ``overrides`` and the exception Hydra or OmegaConf raised; then
    ``sys.argv`` is the command line again (the translators read it)."""
    with pytest.raises(decrun.RunError) as info:
        decrun.run(overrides, dir="run")
    cause = info.value.__cause__
    assert cause is not None, str(info.value)
    monkeypatch.setattr(sys, "argv", ["decrun", *overrides, "hydra.run.dir=run"])
    return str(info.value), cause


def test_a_misspelt_plugin_option(here, monkeypatch):
    """Hydra: ``Could not override 'app.stpes'`` with a ConfigAttributeError/ConfigKeyError cause."""
    line, raw = refused([*SMALL, "app.stpes=3"], monkeypatch)
    assert str(raw).startswith("Could not override 'app.stpes'")
    assert errors.typo_message(raw) == line
    assert line.startswith("error: app.stpes: unknown option of app=model") and "did you mean app.steps?" in line


def test_a_launcher_whose_plugin_is_not_installed(here, monkeypatch):
    """Hydra: ``Could not find 'hydra/launcher/<name>'`` (a MissingConfigException)."""
    monkeypatch.setitem(hints.PLUGIN_EXTRAS, "hydra/launcher",
                        {**hints.PLUGIN_EXTRAS["hydra/launcher"], "absent": ("hydra-absent-launcher", "absent")})
    line, raw = refused([*SMALL, "hydra/launcher=absent"], monkeypatch)
    assert errors.missing_plugin_message(raw) == line
    assert line == 'error: hydra/launcher=absent: hydra-absent-launcher is not installed; pip install "decrun[absent]"'


def test_a_models_part_that_no_config_directory_has(here, monkeypatch):
    """Hydra: ``In 'app/halfar': Could not find 'app/parts/glen_lw'`` with the search path's
    ``path=file://…`` lines."""
    line, raw = refused(["app=halfar", "app/parts@app=[halfar_dynamics,glen_lw]", "figures=false"], monkeypatch)
    assert errors.part_missing_message(raw) == line
    assert line == ("error: app=halfar: no part glen_lw (app/parts/glen_lw.yaml is in no config directory of the "
                    "search path); did you mean glen_law? (the parts: glen_law | halfar_dynamics)")


def test_a_group_option_that_does_not_exist(here, monkeypatch):
    """Hydra: ``Could not find 'app/smooth'`` with the group's options on the exception."""
    line, raw = refused(["app=smooth", "figures=false"], monkeypatch)
    assert errors.group_typo_message(raw) == line
    assert line.startswith("error: app=smooth: no such option; did you mean `app=smoothing`? (the options: ")
    assert " | heat | " in line and "_model" not in line


def test_a_group_outside_the_defaults_list_without_a_plus(here, monkeypatch):
    """Hydra: ``Could not override 'experiment'. No match in the defaults list. To append to
    your default list use +experiment=…``."""
    line, raw = refused(["experiment=fig5_8_t_hole"], monkeypatch)
    assert errors.append_message(raw) == line
    assert line == ("error: experiment=fig5_8_t_hole: experiment is not in the config's defaults list, it is added "
                    "with +; use `+experiment=fig5_8_t_hole`")


def test_a_root_option_that_is_no_boolean(here, monkeypatch):
    """Hydra: ``Error merging override progress=maybe`` caused by OmegaConf's ``Value 'maybe'
    is not a valid bool``."""
    line, raw = refused([*SMALL, "progress=maybe"], monkeypatch)
    assert errors.root_value_message(raw) == line
    assert line == "error: progress=maybe: not a boolean; use `progress=true` or `progress=false`"


@pytest.mark.parametrize("override, words", [
    (f"app.dt=${{oc.env:{UNSET}}}", [f"app.dt='${{oc.env:{UNSET}}}': the environment variable {UNSET} is not set"]),
    ("app.dt=${nowhere:1}", ["app.dt='${nowhere:1}': there is no resolver 'nowhere' (resolvers: oc.env, "]),
    ("app.dt=${app.dt}", ["app.dt='${app.dt}': the interpolation refers to itself (a cycle)"]),
    ("app.steps=${app.nowhere}", ["app.steps='${app.nowhere}': the interpolation refers to app.nowhere, which the "
                                  "config does not have"]),
], ids=["unset-env", "unknown-resolver", "self-reference", "missing-key"])
def test_an_interpolation_that_does_not_resolve(here, monkeypatch, override, words):
    """OmegaConf: ``Environment variable '…' not found``, ``Unsupported interpolation type …``,
    ``Recursive interpolation detected``, ``Interpolation key '…' not found``; the line names the
    override's raw text (read back unresolved) and the fix."""
    line, raw = refused([*SMALL, override], monkeypatch)
    assert hints.resolution_error(raw) is not None
    assert all(word in line for word in words), line
    assert "the interpolation cannot be resolved" not in line  # not the fallback
    key = override.partition("=")[0]
    assert line.startswith("error: ") and line.endswith(f"; drop the override of {key}, or give it a plain value")


def test_a_config_file_nested_too_deeply(here, monkeypatch):
    """A RecursionError while Hydra loads a config file: the line names that file (the config
    file of the search path nested deeper than MAX_NESTING, found by reading it, not Hydra's frames)."""
    (here / "my_conf" / "app").mkdir(parents=True)
    deep = here / "my_conf" / "app" / "deep.yaml"
    deep.write_text("x: " + "[" * 5000 + "]" * 5000 + "\n")
    line, raw = refused(["+app=deep", "hydra.searchpath=[file://my_conf]", "figures=false"], monkeypatch)
    assert failures.config_error_message(raw, sys.argv[1:]) == line
    assert line.startswith(f"error: {Path('my_conf').absolute() / 'app' / 'deep.yaml'}: nested too deeply to load")
