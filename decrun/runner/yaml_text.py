"""The text of ``OmegaConf.to_yaml``, made by decrun: the same representation rules on
PyYAML's Python emitter (:class:`PythonDumper`, what config hashes are made with) or on
libyaml's C emitter (:class:`FastDumper`, 2-3x faster, for the files a sweep writes per
job: ``.hydra/*.yaml`` and the config in ``result.h5``).

OmegaConf's dumper (``OmegaConfDumper``, in its private ``omegaconf._utils``) is PyYAML's
``Dumper`` that single-quotes a string YAML 1.1 would read as a boolean or Python as a
number; both dumpers here represent strings that way. The two emitters write the same text
for every config in ``conf/`` and for Hydra's own node (tests/runner/test_yaml_text.py).
They differ on unusual strings — libyaml wraps long quoted strings at other columns and
writes an empty key inline — and there libyaml is the faithful one: its text reads back
as the data it was given, where PyYAML's emitter writes some characters (U+0085, U+2028)
raw that a loader then takes for line breaks (the test's fuzz: 0 of its strings change
through libyaml, a quarter of them through PyYAML's emitter).
"""

from __future__ import annotations

from typing import Any

import yaml
from omegaconf import OmegaConf

__all__ = ["PythonDumper", "FastDumper", "to_yaml"]

#: strings YAML 1.1 reads as booleans (OmegaConf's list): quoted, so they stay strings
_YAML_BOOLS = frozenset("y Y yes Yes YES n N no No NO true True TRUE false False FALSE on On ON off Off OFF".split())


def _number(text: str) -> bool:
    """Whether ``int(text)`` or ``float(text)`` reads ``text`` (``"1"``, ``" 2.5 "``, ``"1_0"``, ``"nan"``)."""
    for kind in (int, float):
        try:
            kind(text)
            return True
        except ValueError:
            pass
    return False


def _str(dumper: yaml.BaseDumper, data: str) -> yaml.ScalarNode:
    quoted = data in _YAML_BOOLS or _number(data)
    return dumper.represent_scalar(yaml.resolver.BaseResolver.DEFAULT_SCALAR_TAG, data, style="'" if quoted else None)


class PythonDumper(yaml.Dumper):
    """OmegaConf's YAML dumper on PyYAML's Python emitter. The config hashes of sweep
    manifests are made with it (:func:`decrun.runner.sweep.manifest.config_hash`), so that
    the hashes in existing manifests stay what they are whatever OmegaConf's dumper or
    libyaml become (tests/runner/test_sweep_planning.py pins them)."""


PythonDumper.add_representer(str, _str)

if getattr(yaml, "__with_libyaml__", False):
    class FastDumper(yaml.CDumper):
        """OmegaConf's YAML dumper on libyaml's emitter (PyYAML built with libyaml)."""

    FastDumper.add_representer(str, _str)
else:  # PyYAML without libyaml: the same text, at the Python emitter's speed
    FastDumper = PythonDumper


def to_yaml(cfg: Any, *, resolve: bool = False, sort_keys: bool = False) -> str:
    """``OmegaConf.to_yaml(cfg, resolve=resolve, sort_keys=sort_keys)`` written by
    :class:`FastDumper`: the same data, the same text but for unusual strings (module
    docstring); ~1.3 ms instead of ~3.5 ms for a sweep job's ``hydra`` node. ``cfg``: a
    DictConfig or ListConfig (or a plain container)."""
    container = OmegaConf.to_container(cfg, resolve=resolve, enum_to_str=True) if OmegaConf.is_config(cfg) else cfg
    return yaml.dump(container, default_flow_style=False, allow_unicode=True, sort_keys=sort_keys, Dumper=FastDumper)
