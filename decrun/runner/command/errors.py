"""The ``decrun`` command's one line for an error Hydra or OmegaConf let through
(:func:`error_message`): each translator reads the text of one Hydra or OmegaConf error
(tests/runner/test_hydra_error_texts.py holds each to the real error of the installed versions;
scripts/check_hydra_versions.sh to every hydra-core release the pin admits) and returns None
for any other."""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any

from decrun.core.choices import Choice, choice_error
from decrun.errors import DecrunError
from decrun.runner.job.failures import (
    config_error_message,
    find_memory_error,
    find_os_error,
    memory_error_text,
    os_error_message,
    shorten_words,
)


def error_message(exc: Exception) -> str | None:
    """What the ``decrun`` command prints for an exception Hydra let through (one line; two
    for a Hydra error with an OmegaConf cause, as Hydra prints it), or None for a bug (the
    command shows its traceback). Overrides are read from ``sys.argv`` (the command line)."""
    from hydra.errors import CompactHydraException
    from omegaconf.errors import OmegaConfBaseException

    message = config_error_message(exc, sys.argv[1:]) or typo_message(exc) or missing_plugin_message(exc) or \
        part_missing_message(exc) or group_typo_message(exc) or root_value_message(exc) or append_message(exc)
    if not message and not isinstance(exc, DecrunError):  # hydra.run.dir=${oc.env:UNSET}: Hydra's own keys
        from decrun.runner.job.hints import resolution_message

        unresolved = resolution_message(exc)
        message = f"error: {unresolved}" if unresolved else None
    if message:
        return message
    if isinstance(exc, CompactHydraException):  # what Hydra's run_and_report prints
        cause: Any = exc.__cause__  # an OmegaConf validation error when choices is not None
        choices = _choices_of(cause)
        if choices is not None:  # a schema field with a closed set of values (optimize.direction)
            return f"error: {choice_error(cause.full_key, cause.value, choices)}"
        if isinstance(exc.__cause__, OmegaConfBaseException):
            return f"{exc}\n{exc.__cause__}"
        return str(exc)
    if isinstance(exc, DecrunError):
        return f"error: {exc}"
    os_error = find_os_error(exc)
    if os_error is not None:
        return f"error: {_name_too_long(os_error) or os_error_message(os_error)}"
    memory = find_memory_error(exc)  # outside a run (composing a sweep): no run config to name
    if memory is not None:
        return f"error: {memory_error_text(memory)}"
    return None


def _name_too_long(exc: OSError) -> str | None:
    """For a name too long for the file system (``mesh=<120 kB>``, ``+app.<120 kB>=1``: Hydra
    looks the name up as a config file or group), the command-line override it came from —
    the longest one — as the culprit; None for any other OS error."""
    import errno

    if exc.errno != errno.ENAMETOOLONG:
        return None
    args = [a for a in sys.argv[1:] if not a.startswith("-")]
    if not args:
        return None
    culprit = max(args, key=len)
    return f"{culprit}: a name too long for the file system ({os.strerror(exc.errno)}: a file or directory " \
           f"name has at most 255 bytes); shorten it"


def typo_message(exc: Exception) -> str | None:
    """For an option of a plugin group Hydra refuses to override (``app.stpes=3``: not in
    the group's config), the decrun message of its ``+`` form — the group's options and the
    closest one — instead of Hydra's advice to append it; also for a plugin whose config
    directory the command adds with ``hydra.searchpath``. None for any other error."""
    import re

    from omegaconf.errors import ConfigAttributeError, ConfigKeyError

    from decrun.runner.job.config import PLUGIN_GROUPS

    match = re.match(r"Could not override '([^']+)'", str(exc))
    if match is None or not isinstance(exc.__cause__, (ConfigAttributeError, ConfigKeyError)):
        return None
    key = match.group(1)
    if key.split(".", 1)[0] not in PLUGIN_GROUPS:
        return None
    overrides = []  # the group choices and experiments of the command, the key in its + form
    for arg in sys.argv[1:]:
        name, sep, value = arg.partition("=")
        bare = name.lstrip("+~")
        if sep and bare == "hydra.searchpath":  # where a plugin's config directory is
            overrides.append(arg)
            continue
        if not sep or bare.startswith(("hydra.", "hydra/")):
            continue
        if bare == key:
            overrides.append(f"+{key}={value.split(',')[0]}")  # a sweep: its first value
        elif "." not in bare:
            overrides.append(f"{name}={value.split(',')[0]}")
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.experiment import validate  # lazy: the numerical stack (start-up speed)

    try:
        cfg = compose_config(overrides)
        experiment = validate(cfg)
        if key.startswith("app.constants.") and key.count(".") == 2:  # a constant nothing reads: a misspelt one
            from decrun.runner.job.model_checks import check_model

            check_model(experiment.app, [key.split(".")[2]])
    except DecrunError as error:
        return f"error: {error}"
    except Exception:  # the command cannot be recomposed this way: Hydra's message stands
        return None
    return model_entry_message(key, cfg.app, _field_existed(key, overrides, compose_config))


def _field_existed(key: str, overrides: list[str], compose_config) -> bool:
    """For ``app.fields.<name>.<option>``: whether the model has the field ``name`` without the
    override (its YAML does not list the option, e.g. a border condition), not a misspelt field."""
    parts = key.split(".")
    if len(parts) < 4 or parts[:2] != ["app", "fields"]:
        return False
    try:
        before = compose_config([o for o in overrides if o.split("=", 1)[0] != f"+{key}"])
    except Exception:  # noqa: BLE001 - recomposition is a best effort on an error path
        return False
    return parts[2] in before.app.get("fields", {})


#: a model's named entries: config key → what one is called in a message
_MODEL_ENTRIES = {"fields": "field", "metrics": "metric"}


def model_entry_message(key: str, app: Any, existed: bool = False) -> str | None:
    """For ``app.fields.<name>…`` or ``app.metrics.<name>`` naming an entry the model ``app``
    (its composed node) does not have: one line with the closest entry it has (the override
    meant), and for a metric the ``+`` form that adds a new one; for an option of a field that
    ``existed`` without the override, the ``+`` form that adds it. None for any other key."""
    import difflib

    parts = key.split(".")
    if len(parts) < 3 or parts[0] != "app" or parts[1] not in _MODEL_ENTRIES or parts[1] not in app:
        return None
    group, name, rest = parts[1], parts[2], ".".join(parts[3:])
    what = _MODEL_ENTRIES[group]
    if rest and existed:  # the field exists; its YAML does not list this option (e.g. a border condition)
        value = next((arg.partition("=")[2] for arg in sys.argv[1:] if arg.partition("=")[0] == key), "…")
        return (f"error: {key}: the {what} {name} of app={app.get('model', '?')} does not list {rest} in its config; "
                f"add it with `+{key}={value}`")
    known = sorted(str(entry) for entry in app[group] if entry != name)  # the recomposed node holds it too
    close = difflib.get_close_matches(name, known, n=1)
    meant = f"; did you mean app.{group}.{close[0]}{'.' + rest if rest else ''}?" if close else ""
    listing = f" (its {group}: {', '.join(known) or 'none'})"
    added = f"; a new {what} is added with `+{key}=…`" if group == "metrics" else ""
    return f"error: {key}: unknown {what} of app={app.get('model', '?')}{meant}{listing}{added}"


def missing_plugin_message(exc: Exception) -> str | None:
    """For a Hydra launcher or sweeper whose plugin is not installed (``hydra/launcher=ray``
    without the extra), the pip line that installs it (:data:`decrun.runner.job.hints.PLUGIN_EXTRAS`)."""
    import re

    from hydra.errors import MissingConfigException

    from decrun.runner.job.hints import PLUGIN_EXTRAS

    if not isinstance(exc, MissingConfigException):
        return None
    match = re.search(r"Could not (?:find|load) '(hydra/(?:launcher|sweeper))/([^']+)'", str(exc))
    if match is None or match.group(2) not in PLUGIN_EXTRAS.get(match.group(1), {}):
        return None
    group, name = match.groups()
    plugin, extra = PLUGIN_EXTRAS[group][name]
    return f'error: {group}={name}: {plugin} is not installed; pip install "decrun[{extra}]"'


def part_missing_message(exc: Exception) -> str | None:
    """For a part a composed model names that no config directory has (``- parts@_here_:
    [halfar_dynamics, glen_lw]`` in ``app/halfar``): one line naming the model and the part,
    with the closest part and every part of the search path's ``<group>/parts/`` directories
    (decrun's and those added with ``hydra.searchpath``). None for any other error."""
    import difflib
    import re

    from hydra.errors import MissingConfigException

    if not isinstance(exc, MissingConfigException):
        return None
    text = str(exc)
    match = re.search(r"In '([^'/]+)/([^']+)': Could not (?:find|load) '([^']+?)/parts/([^']*)'", text)
    if match is None or match.group(1) != match.group(3):
        return None
    group, model, _, part = match.groups()
    # ``parts=[/etc/passwd]``, ``parts=['']``: no part's name (examples of refused input, not hints;
    # tests/runner/test_hostile_models.py::test_a_part_named_by_a_path_or_nothing_is_one_line runs both)
    named = part and "/" not in part and part not in (".", "..")
    options: set[str] = set()
    for root in re.findall(r"path=file://(\S+)", text):
        directory = Path(root) / group / "parts"
        if directory.is_dir():
            options.update(p.stem for p in directory.glob("*.yaml") if not p.stem.startswith("_"))
    close = difflib.get_close_matches(part, sorted(options), n=1)
    hint = f"; did you mean {close[0]}?" if close else ""
    listing = f" (the parts: {' | '.join(sorted(options))})" if options else " (there are none)"
    if not named:
        return f"error: {group}={model}: {shorten_words(repr(part))} is not a part's name (a file in {group}/parts/, " \
               f"no path){listing}"
    return (f"error: {group}={model}: no part {part} ({group}/parts/{part}.yaml is in no config directory of the "
            f"search path){hint}{listing}")


def group_typo_message(exc: Exception) -> str | None:
    """For a config-group option that does not exist (``app=smooth``, ``mesh=icosahedron``,
    ``hydra/launcher=nonexistent``): one line with the closest option and every option of the
    group (not the files that are shared pieces of one, ``_``-prefixed), instead of Hydra's
    listing with the config search path. None for any other error."""
    import difflib
    import re

    from hydra.errors import MissingConfigException

    if not isinstance(exc, MissingConfigException):
        return None
    match = re.search(r"Could not (?:find|load) '([^']+)/([^'/]+)'", str(exc))
    if match is None:
        return None
    group, name = match.groups()
    options = sorted(option for option in (exc.options or []) if not option.startswith("_"))
    if not options:
        return None
    close = difflib.get_close_matches(name, options, n=1) or _same_stem(name, options)
    # as the command line gave it: a group outside the defaults list is added with + (+experiment=...)
    plus = next((arg[:len(arg) - len(arg.lstrip("+"))] for arg in sys.argv[1:]
                 if arg.lstrip("+") == f"{group}={name}"), "")
    hint = f"; did you mean `{plus}{group}={close[0]}`?" if close else ""
    local = searchpath_hint(group, name)
    if local or (not close and group in _PLUGIN_KEYS):
        hint = f"; {local or _own_config_hint(group, name)}"
    return f"error: {plus}{group}={name}: no such option{hint} (the options: {' | '.join(options)})"


#: the groups whose options a user writes in a config directory of their own
_PLUGIN_KEYS = ("app", "mesh", "operator", "boundary", "solver", "export", "tracker")
#: directories never searched for a user's config file
_SKIPPED = {"outputs", "multirun", "node_modules", "__pycache__", "site-packages"}


def _own_config_hint(group: str, name: str) -> str:
    """The general advice for an option of one's own that Hydra did not find."""
    return (f"an option of your own is a file <dir>/{group}/{name}.yaml, found with "
            f"`hydra.searchpath=[file://<dir>]` (e.g. `hydra.searchpath=[file://$PWD/my_conf]`)")


def searchpath_hint(group: str, name: str, depth: int = 3, budget: int = 2000) -> str | None:
    """For ``<group>=<name>`` that no config directory has, when a file ``<name>.yaml`` is in
    the current directory or a subfolder (``depth`` levels, at most ``budget`` folders; hidden
    ones and outputs skipped): the exact ``hydra.searchpath=[file://<dir>]`` override that
    finds it — ``<dir>`` the folder holding ``<group>/<name>.yaml`` — or, for a file outside a
    ``<group>/`` folder, where to move it. None when there is no such file."""
    root = Path.cwd()
    level = [root]
    seen = 0
    for _ in range(depth + 1):
        following = []
        for folder in level:
            seen += 1
            if seen > budget:
                return None
            candidate = folder / f"{name}.yaml"
            if candidate.is_file():
                if folder.name == group:
                    return f"{_shown(candidate, root)} is there: add `hydra.searchpath=[file://{folder.parent}]`"
                return (f"{_shown(candidate, root)} is there, outside a {group}/ folder: move it to "
                        f"{_shown(folder / group / candidate.name, root)} and add "
                        f"`hydra.searchpath=[file://{folder}]`")
            try:
                following += sorted(p for p in folder.iterdir()
                                    if p.is_dir() and not p.name.startswith((".", "_")) and p.name not in _SKIPPED)
            except OSError:  # a folder that cannot be listed: not searched
                continue
        level = following
    return None


def _shown(path: Path, root: Path) -> str:
    """``path`` relative to ``root`` where it is under it."""
    try:
        return str(path.relative_to(root))
    except ValueError:
        return str(path)


def append_message(exc: Exception) -> str | None:
    """For a group outside the config's defaults list chosen without ``+``
    (``experiment=fig5_8_t_hole``): one line with the ``+`` form Hydra advises, instead of
    its two. None for any other error."""
    import re

    from hydra.errors import ConfigCompositionException

    if not isinstance(exc, ConfigCompositionException):
        return None
    match = re.match(r"Could not override '([^']+)'\. No match in the defaults list\.\s+"
                     r"To append to your default list use (\S+)", str(exc))
    if match is None:
        return None
    key, fix = match.groups()
    return f"error: {fix.lstrip('+')}: {key} is not in the config's defaults list, it is added with +; use `{fix}`"


def _same_stem(name: str, options: list[str], least: int = 4) -> list[str]:
    """The option sharing the longest start with ``name``, of at least ``least`` characters
    (``cholesky`` → ``cholmod``), as a one-item list; empty when none shares that much. For
    names a spelling distance misses because they are another word of the same stem."""
    import os.path

    shared = {option: len(os.path.commonprefix([name.lower(), option.lower()])) for option in options}
    best = max(shared, key=lambda option: shared[option], default=None)
    return [best] if best is not None and shared[best] >= least else []


def root_value_message(exc: Exception) -> str | None:
    """For a root option given a value of the wrong type (``progress=maybe``): one line naming
    the option, the value and what it takes, instead of Hydra's merge report."""
    import re

    from omegaconf.errors import ValidationError

    cause = exc.__cause__ if isinstance(exc.__cause__, ValidationError) else None
    match = re.match(r"Error merging override (\S+)=(.*)", str(exc))
    if cause is None or match is None:
        return None
    key, value = match.groups()
    if "not a valid bool" not in str(cause):  # other types keep their own handling (closed choices)
        return None
    return f"error: {key}={value}: not a boolean; use `{key}=true` or `{key}=false`"


def _choices_of(cause: BaseException | None) -> type[Choice] | None:
    """The :class:`~decrun.core.choices.Choice` type of the schema field an OmegaConf
    ValidationError is about, or None (another error, or a field of another type)."""
    import typing

    from omegaconf.errors import ValidationError

    owner, key = getattr(cause, "object_type", None), getattr(cause, "key", None)
    if not (isinstance(cause, ValidationError) and isinstance(owner, type) and isinstance(key, str)):
        return None
    try:
        hint = typing.get_type_hints(owner).get(key)
    except Exception:  # an owner whose annotations cannot be resolved
        return None
    return hint if isinstance(hint, type) and issubclass(hint, Choice) else None
