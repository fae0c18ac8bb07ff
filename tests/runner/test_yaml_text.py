"""decrun.runner.yaml_text: OmegaConf's YAML text from libyaml's emitter. The same text as
``OmegaConf.to_yaml`` for every config decrun composes (each option of each group, the
default config, a sweep job's whole config with Hydra's node), resolved or not, sorted or
not; and on unusual strings the same data back where PyYAML's emitter loses some."""

from __future__ import annotations

import random
from pathlib import Path

import pytest
import yaml
from omegaconf import OmegaConf

from decrun.runner.config import GROUPS, compose_config, load_option
from decrun.runner.yaml_text import FastDumper, PythonDumper, to_yaml

CONF = Path(__file__).resolve().parents[2] / "conf"


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
    as a sweep job's .hydra/hydra.yaml has it, and the resolved task config (result.h5)."""
    from hydra import compose, initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra

    from decrun.runner.config import config_dir, register_configs

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


def _string(rng: random.Random) -> str:
    alphabet = list("abz09 :-#'\"\\\n\t{}[],&*!|>%@`?~=.+_/") + ["é", "∂", "⋆", "\u00a0", "\u2028", "\x85", "😀",
                                                             "\x07", "\ufeff"]
    return "".join(rng.choice(alphabet) for _ in range(rng.choice([1, 3, 12, 90])))


def test_unusual_strings_read_back_as_written_through_libyaml():
    """libyaml's text reads back as the data; PyYAML's emitter (OmegaConf's) writes U+0085
    and U+2028 raw, which a loader takes for line breaks: FastDumper is not the weaker one."""
    rng = random.Random(7)
    lost = {PythonDumper: 0, FastDumper: 0}
    for _ in range(400):
        data = {_string(rng): _string(rng), _string(rng): [_string(rng), 1.5, None, True]}
        for dumper in lost:
            text = yaml.dump(data, default_flow_style=False, allow_unicode=True, sort_keys=False, Dumper=dumper)
            lost[dumper] += yaml.load(text, Loader=yaml.SafeLoader) != data
    if FastDumper is not PythonDumper:  # PyYAML built with libyaml (every wheel)
        assert lost[FastDumper] == 0 and lost[PythonDumper] > 0
    else:
        pytest.skip("PyYAML without libyaml: FastDumper is PythonDumper")
