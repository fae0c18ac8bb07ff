"""Config files checked before Hydra composes them: YAML alias bombs refused in one line.

YAML's anchors and aliases (``&a`` … ``*a``) let a few hundred bytes stand for a tree of 10⁹
nodes ("billion laughs"); OmegaConf, which builds the config Hydra composes, copies every alias
out into its own nodes, so such a file keeps ``decrun`` busy for minutes to days. Every YAML
file decrun or Hydra reads is first scanned as a stream of parser events (no node is built) and
refused when its aliases stand for more than :data:`MAX_ALIASED_NODES` nodes: one line naming
the file (:func:`check_aliases`). Before composing, :func:`check_config_files` scans the config
files of the search path — decrun's ``conf/`` and every ``file://`` directory of
``hydra.searchpath`` (or ``--config-dir``) — in the config groups decrun has
(``app/``, ``app/parts/``, ``mesh/`` …).
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Iterable, Iterator

from decrun.errors import CorruptFileError

__all__ = ["MAX_ALIASED_NODES", "aliased_nodes", "yaml_depth", "search_roots", "config_files", "check_aliases",
           "check_config_files"]

#: the most nodes the aliases of one YAML file may stand for (a config's own anchors repeat a
#: handful of values; OmegaConf builds 10⁴ nodes in well under a second)
MAX_ALIASED_NODES = 10_000


def aliased_nodes(text: str, limit: int = MAX_ALIASED_NODES) -> int:
    """How many nodes (scalars, lists, mappings) the aliases of the YAML ``text`` stand for once
    expanded, counted from the parser's events without building a node; the count stops as soon
    as it exceeds ``limit`` (an alias of an alias of … is counted by its anchor's size, so the
    scan is linear in the text). Text the parser refuses counts what was read before the error
    (the loader that reads the file reports it)."""
    import yaml

    sizes: dict[str, int] = {}
    open_nodes: list[list] = []  # [anchor, size so far] of each list or mapping being read
    total = 0
    parser = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

    def close(anchor, size: int) -> None:
        if anchor is not None:
            sizes[anchor] = size
        if open_nodes:
            open_nodes[-1][1] += size

    try:
        for event in yaml.parse(text, Loader=parser):
            if isinstance(event, yaml.AliasEvent):
                size = sizes.get(event.anchor, 1)
                total += size
                if total > limit:
                    return total
                close(None, size)
            elif isinstance(event, yaml.ScalarEvent):
                close(event.anchor, 1)
            elif isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
                open_nodes.append([event.anchor, 1])
            elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)) and open_nodes:
                anchor, size = open_nodes.pop()
                close(anchor, size)
    except (yaml.YAMLError, RecursionError):
        pass
    return total


def yaml_depth(data: bytes) -> int:
    """The deepest nesting of lists and mappings in the YAML ``data``, counted from the events of
    PyYAML's Python parser without building a node (it does not recurse, nor stop at libyaml's
    depth limit: any depth is counted); text the parser refuses counts what was read before the
    error."""
    import yaml

    depth = deepest = 0
    try:
        for event in yaml.parse(data, Loader=yaml.SafeLoader):
            if isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
                depth += 1
                deepest = max(deepest, depth)
            elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
                depth -= 1
    except yaml.YAMLError:
        pass
    return deepest


def check_aliases(text: str, where: str | os.PathLike, error: type[Exception] = CorruptFileError) -> None:
    """Raise ``error`` naming ``where`` when the aliases of the YAML ``text`` stand for more than
    :data:`MAX_ALIASED_NODES` nodes (:func:`aliased_nodes`); text without an alias costs a
    substring search."""
    if "*" not in text or "&" not in text:
        return
    count = aliased_nodes(text)
    if count > MAX_ALIASED_NODES:
        raise error(f"{where}: its YAML aliases (*name) expand to more than {MAX_ALIASED_NODES} nodes (an alias "
                    "bomb); decrun reads no such file: write the values out or repeat fewer of them")


def search_roots(args: Iterable[str], conf: Path) -> list[Path]:
    """decrun's config directory ``conf`` and the ``file://`` directories the command line adds
    (``hydra.searchpath=[file://a,…]``, ``--config-dir a`` / ``-cd a``), absolute."""
    roots = [Path(os.path.abspath(conf))]
    args = list(args)
    for i, arg in enumerate(args):
        name, sep, value = arg.partition("=")
        if sep and name.lstrip("+~") == "hydra.searchpath":
            roots += [Path(os.path.abspath(found)) for found in re.findall(r"file://([^,\]\s'\"]+)", value)]
        elif arg in ("--config-dir", "-cd") and i + 1 < len(args):
            roots.append(Path(os.path.abspath(args[i + 1])))
        elif arg.startswith("--config-dir="):
            roots.append(Path(os.path.abspath(arg.partition("=")[2])))
    return roots


def config_files(args: Iterable[str], conf: Path) -> Iterator[Path]:
    """The config files of the search path (:func:`search_roots`; ``conf``: decrun's config
    directory) for the command line ``args``: the ``*.yaml`` files of each root and of its
    config-group directories — decrun's (``app/``, ``app/parts/`` …, recursively), ``hydra/``
    and a group of the user's own chosen on the command line (``+mygroup=x``,
    ``mygroup/sub@pkg=x``) — never the rest of a directory added to the search path (a
    project's ``outputs/`` holds thousands of YAML files Hydra never composes)."""
    args = list(args)
    roots = search_roots(args, conf)
    groups = {p.name for p in roots[0].iterdir() if p.is_dir()} | {"hydra"}
    groups |= {word.lstrip("+~").partition("=")[0].partition("@")[0].partition("/")[0] for word in args
               if "=" in word and not word.startswith("-")} - {"", ".", ".."}
    for root in roots:
        if not root.is_dir():
            continue
        yield from sorted(root.glob("*.yaml"))
        for group in sorted(groups):
            try:
                found = (root / group).is_dir()
            except OSError:  # a name the file system cannot hold (`+app.<120 kB>=1`): no such group; Hydra's lookup says it
                continue
            if found:
                yield from sorted((root / group).rglob("*.yaml"))


def check_config_files(args: Iterable[str], conf: Path) -> None:
    """Raise :class:`~decrun.errors.CorruptFileError` naming the first config file of the search
    path (:func:`config_files`) whose aliases are a bomb (:func:`check_aliases`). Run before
    Hydra composes anything; a file it cannot read is left to the composition, which names it
    (:func:`decrun.runner.job.failures.config_error_message`)."""
    for path in config_files(args, conf):
        try:
            if not path.is_file():
                continue
            text = path.read_bytes().decode("utf-8")
        except (OSError, UnicodeDecodeError):  # said by the composition, naming the file (failures.py)
            continue
        check_aliases(text, path)
