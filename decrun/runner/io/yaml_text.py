"""The YAML dumper config hashes are made with: OmegaConf's representation rules on
PyYAML's Python emitter.

OmegaConf's dumper (``OmegaConfDumper``, in its private ``omegaconf._utils``) is PyYAML's
``Dumper`` that single-quotes a string YAML 1.1 would read as a boolean or Python as a
number. :class:`PythonDumper` is that dumper written with public PyYAML API, so that the
hashes in existing sweep manifests (:func:`decrun.runner.sweep.manifest.config_hash`) stay
what they are whatever OmegaConf's own dumper becomes; it writes the same text as
``OmegaConf.to_yaml`` for every config in ``conf/`` and for Hydra's own node
(tests/runner/sweep/test_yaml_text.py).
"""

from __future__ import annotations

import yaml

__all__ = ["PythonDumper"]

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
    """OmegaConf's YAML dumper on PyYAML's Python emitter: ``yaml.dump(container,
    default_flow_style=False, allow_unicode=True, sort_keys=..., Dumper=PythonDumper)`` is
    ``OmegaConf.to_yaml``'s text of the config ``container`` came from."""


PythonDumper.add_representer(str, _str)
