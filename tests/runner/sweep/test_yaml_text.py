"""decrun.runner.io.yaml_text: the dumper of config hashes writes ``OmegaConf.to_yaml``'s text
for every config decrun composes (each option of each group, a sweep job's whole config
with Hydra's node), resolved or not, sorted or not — so a manifest's hashes do not depend
on OmegaConf's private dumper."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from omegaconf import OmegaConf

from decrun.runner.io.yaml_text import PythonDumper
from decrun.runner.job.config import GROUPS, compose_config, load_option

CONF = Path(__file__).resolve().parents[3] / "conf"


def to_yaml(cfg, resolve: bool = False, sort_keys: bool = False) -> str:
    container = OmegaConf.to_container(cfg, resolve=resolve, enum_to_str=True)
    return yaml.dump(container, default_flow_style=False, allow_unicode=True, sort_keys=sort_keys, Dumper=PythonDumper)


def _options():
    for group in GROUPS:
        for path in sorted((CONF / group.key).glob("*.yaml")):
            if not path.stem.startswith("_"):
                yield group.key, path.stem


@pytest.mark.parametrize("group, name", list(_options()))
def test_every_option_in_conf_has_omegaconfs_text(group, name):
    node = load_option(group, name)
    for sort_keys in (False, True):
        assert to_yaml(node, sort_keys=sort_keys) == OmegaConf.to_yaml(node, sort_keys=sort_keys)


def test_a_sweep_jobs_whole_config_has_omegaconfs_text(tmp_path):
    """Hydra's own node (help templates with newlines, logging dicts, lists of overrides)
    as a sweep job's .hydra/hydra.yaml has it, and the resolved task config."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    from decrun.runner.job.config import config_dir, register_configs

    register_configs()
    GlobalHydra.instance().clear()
    try:
        with initialize_config_dir(config_dir=str(config_dir()), version_base="1.3"):
            cfg = compose("config", overrides=["app=fluid", "mesh.subdiv=2", f"hydra.sweep.dir={tmp_path}"],
                          return_hydra_config=True)
    finally:
        GlobalHydra.instance().clear()
    assert to_yaml(cfg.hydra) == OmegaConf.to_yaml(cfg.hydra) and "\n" in str(cfg.hydra.help.template)
    task = compose_config(["app=fluid"])
    assert to_yaml(task, resolve=True) == OmegaConf.to_yaml(task, resolve=True)
    assert to_yaml(task) == OmegaConf.to_yaml(task)
    quoted = OmegaConf.create({"flag": "yes", "n": "1_0", "s": "x"})  # a bool-like key and values, a number
    assert to_yaml(quoted) == OmegaConf.to_yaml(quoted) == "flag: 'yes'\n'n': '1_0'\ns: x\n"
