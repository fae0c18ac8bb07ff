"""The option tables of the docs' "Config groups" page, generated from ``conf/`` and the dataclasses.

    python scripts/config_reference.py          # print the Markdown

Every ``conf/<group>/<option>.yaml`` (sub-directories too, e.g. ``mesh=cism_halfar/1km``;
files starting with ``_`` are partials, not options) is composed as ``decrun <group>=<option>``
would compose it; its ``_target_`` dataclass gives the keys. Each key's default is the composed
value, its description the YAML comment on that key (the option's file, then the group's
partials), else the ``#:`` or trailing comment on the dataclass field. The mesh sources' shared
post-processing keys (``decrun.runner.mesh.MeshSource``) are one table of their own. The docs
build (``scripts/mkdocs_hooks.py``) puts the result where a page says ``<!-- config-options -->``,
so an option added to ``conf/`` appears on the site without editing any page.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import re
import sys
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "conf"
#: the config groups a run composes, in the order of conf/config.yaml
GROUPS = ("mesh", "operator", "boundary", "app", "solver", "export", "tracker")
_FIELD = re.compile(r"^\s+(\w+)\s*:\s*[^=#]+?(?:=.*?)?(?:#\s*(.*))?$")


def options(group: str) -> list[str]:
    """The option names of a group: every YAML under ``conf/<group>/`` not starting with ``_``."""
    base = CONF / group
    return sorted(str(p.relative_to(base).with_suffix("")) for p in base.rglob("*.yaml")
                  if not any(part.startswith("_") for part in p.relative_to(base).parts))


def header(path: Path) -> str:
    """The leading comment of a YAML file (its description), joined into one paragraph;
    indented example commands (``#   decrun ...``) are left out."""
    text = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if not line.startswith("#"):
            break
        body = line[1:]
        if body.startswith("   ") and body.strip().startswith(("decrun", "python")):
            continue
        text.append(body.strip())
    return " ".join(t for t in text if t)


def yaml_comments(path: Path) -> dict[str, str]:
    """``key: value  # comment`` → {key: comment} for the top-level keys of a YAML file."""
    found = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        match = re.match(r"^(\w+)\s*:.*?\s#\s*(.*)$", line)
        if match:
            found[match.group(1)] = match.group(2).strip()
    return found


@lru_cache(maxsize=None)
def field_comments(cls: type) -> dict[str, str]:
    """{field: comment} from the class source (and its bases'): the ``#:`` lines above a field
    or the comment after it."""
    found: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        if klass is object or not dataclasses.is_dataclass(klass):
            continue
        try:
            source = inspect.getsource(klass)
        except (OSError, TypeError):
            continue
        pending: list[str] = []
        for line in source.splitlines():
            stripped = line.strip()
            if stripped.startswith("#:"):
                pending.append(stripped[2:].strip())
                continue
            match = _FIELD.match(line)
            if match and not stripped.startswith(("def ", "return", "class ")):
                comment = " ".join(pending) or (match.group(2) or "").strip()
                if comment:
                    found[match.group(1)] = comment
            pending = []
    return found


def _compose(group: str, option: str):
    from decrun.runner.job.config import compose_config

    return compose_config([f"{group}={option}"])[group]


def _cell(value) -> str:
    from omegaconf import OmegaConf

    if OmegaConf.is_config(value):
        value = OmegaConf.to_container(value)
    if hasattr(value, "name") and hasattr(value, "value"):  # an Enum option
        value = value.name
    text = "null" if value is None else str(value).lower() if isinstance(value, bool) else str(value)
    if len(text) > 60:
        text = text[:57] + "…"
    return "`" + text.replace("|", "\\|").replace("`", "'") + "`"


def _text(comment: str) -> str:
    """A comment as a table cell: ``|`` escaped, and ``[``/``]`` outside code spans too — a comment's
    ASCII matrix (conf/app/darcy.yaml's ``[u] [p]``) would read as a Markdown reference link."""
    parts = comment.replace("|", "\\|").split("`")
    return "`".join(part if n % 2 else part.replace("[", "\\[").replace("]", "\\]") for n, part in enumerate(parts))


def _fields(cls: type) -> list[str]:
    return [f.name for f in dataclasses.fields(cls) if f.init]


def _target(node) -> type | None:
    target = node.get("_target_") if hasattr(node, "get") else None
    if not target:
        return None
    module, _, name = str(target).rpartition(".")
    return getattr(importlib.import_module(module), name)


def _key_table(group: str, node, keys: list[str], comments: dict[str, str]) -> list[str]:
    rows = ["| key | default | meaning |", "|---|---|---|"]
    for key in keys:
        rows.append(f"| `{group}.{key}` | {_cell(node.get(key))} | {_text(comments.get(key, ''))} |")
    return rows


def group_section(group: str) -> list[str]:
    """The Markdown of one group: an overview table, then each option's keys."""
    from decrun.runner.mesh.source import MeshSource

    lines = [f"### `{group}`", "", "| option | class | what it is |", "|---|---|---|"]
    detail: list[str] = []
    partials = [p for p in (CONF / group).glob("_*.yaml")]
    shared = set(_fields(MeshSource)) if group == "mesh" else set()
    for option in options(group):
        path = CONF / group / f"{option}.yaml"
        node = _compose(group, option)
        cls = _target(node)
        about = header(path)
        lines.append(f"| `{group}={option}` | {'`' + cls.__module__ + '.' + cls.__qualname__ + '`' if cls else '–'} "
                     f"| {_text(about)} |")
        comments = dict(field_comments(cls)) if cls else {}
        for partial in partials:
            comments.update(yaml_comments(partial))
        comments.update(yaml_comments(path))
        keys = [k for k in (_fields(cls) if cls else [k for k in node if k != "_target_"]) if k not in shared]
        if group == "mesh":  # a shared key this source sets differently is shown with the source
            keys += [k for k in sorted(shared) if k in yaml_comments(path) or _own_default(path, k)]
        detail += [f"#### `{group}={option}`", ""]
        detail += (_key_table(group, node, keys, comments) if keys else ["No options."]) + [""]
    lines.append("")
    if group == "mesh":
        from omegaconf import OmegaConf

        node = OmegaConf.load(CONF / "mesh" / "_post_processing.yaml")
        comments = dict(field_comments(MeshSource))
        comments.update(yaml_comments(CONF / "mesh" / "_post_processing.yaml"))
        lines += ["#### Every mesh source: post-processing (`conf/mesh/_post_processing.yaml`)", "",
                  "A source that sets one of these differently shows it in its own table.", ""]
        lines += _key_table("mesh", node, _fields(MeshSource), comments) + [""]
    return lines + detail


def _own_default(path: Path, key: str) -> bool:
    return any(re.match(rf"^{key}\s*:", line) for line in path.read_text(encoding="utf-8").splitlines())


def root_section() -> list[str]:
    """The plain root keys (``progress``, ``figures``, ``checkpoint.*``, ``optimize.*``)."""
    from decrun.runner.job.config import DecrunConfig, compose_config

    cfg = compose_config([])
    comments = field_comments(DecrunConfig)
    rows = ["### Root keys", "", "| key | default | meaning |", "|---|---|---|"]
    root_yaml = yaml_comments(CONF / "config.yaml")
    for f in dataclasses.fields(DecrunConfig):
        if f.name in GROUPS:
            continue
        value = cfg[f.name]
        if hasattr(value, "keys"):
            sub = field_comments(type(f.default_factory()))
            for key in value:
                rows.append(f"| `{f.name}.{key}` | {_cell(value[key])} | {_text(sub.get(key, ''))} |")
        else:
            rows.append(f"| `{f.name}` | {_cell(value)} | {_text(root_yaml.get(f.name) or comments.get(f.name, ''))} |")
    return rows + [""]


def listing(kind: str) -> list[str]:
    """The files of ``conf/<kind>`` with their header comments (experiments, launchers, sweepers)."""
    prefix = "+experiment" if kind == "experiment" else kind
    rows = [f"### `{prefix}`", "", "| option | what it is |", "|---|---|"]
    for path in sorted((CONF / kind).glob("*.yaml")):
        rows.append(f"| `{prefix}={path.stem}` | {_text(header(path))} |")
    return rows + [""]


def reference() -> str:
    """The whole generated reference (Markdown)."""
    lines = ["## Every option", "",
             "Generated from `conf/` and the option dataclasses when the site is built "
             "(`scripts/config_reference.py`).", ""]
    lines += root_section()
    for group in GROUPS:
        lines += group_section(group)
    for kind in ("experiment", "hydra/launcher", "hydra/sweeper"):
        lines += listing(kind)
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    print(reference())
