"""Composing a sweep's jobs as Hydra does, in a few ms each instead of ~0.3 s.

A grid sweep's jobs mostly differ in plain values (``app.dt=0.1`` → ``app.dt=0.2``: no
config group, no ``+``/``~``, no dict or list, no interpolation). Jobs with the same keys
in the same order and the same non-plain overrides form a *group* (:func:`shape`); Hydra
composes the first job of each group (the group's *template*, ``load_sweep_config``), and
every other job is the template with its plain overrides applied — what Hydra's own
composition does for them, with public API: ``OmegaConf.update(cfg, key, value,
merge=True)`` (Hydra's ``_apply_overrides_to_config`` for a changed key), then the job's
``hydra.overrides`` lists and ``hydra.job.override_dirname`` (:func:`apply`).

Checked, not trusted: before a group's jobs are derived, its last job is also composed by
Hydra and compared (the whole YAML, ``hydra`` node included) with its derivation; if they
differ, every job of the group is composed by Hydra (with a message). A group whose
overrides are all plain (or lines the master composition applied as well) takes the
master composition with its first job's overrides applied as its template, so Hydra
composes only the last job (:meth:`Composer._from_master`; the same check decides).

Planning (:meth:`Composer.each`) derives the jobs of a group one after the other into one
working copy of the template, for the sweep's checks and hashes; the launcher gets each
job's own copy when it asks for it (:class:`PlannedConfigs`), so a sweep of 10 000 jobs
holds one config per group, not 10 000.
"""

from __future__ import annotations

import copy
import pickle
import re
import sys
from typing import Any, Callable, Iterator, cast

from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.core.override_parser.types import Override, OverrideType
from omegaconf import DictConfig, OmegaConf

__all__ = ["Composer", "PlannedConfigs", "apply", "override_dirname", "shape"]

#: the value types of a plain override
PLAIN = (str, int, float, bool, type(None))
#: whether an override is plain (:meth:`Parsed.plain`)
Plain = Callable[[Override], bool]


class Parsed:
    """Hydra's override parser with a cache: a sweep's jobs repeat most of their overrides."""

    def __init__(self, loader: Any) -> None:
        self.loader = loader
        self._parser: OverridesParser | None = None
        self._cache: dict[str, Override] = {}
        #: parent group → the names of its child groups
        self._groups: dict[str, frozenset[str]] = {}

    def __call__(self, lines: list[str]) -> list[Override]:
        missing = [line for line in lines if line not in self._cache]
        if missing:
            if self._parser is None:
                self._parser = OverridesParser.create(config_loader=self.loader)
            parsed = self._parser.parse_overrides(missing)
            self._cache.update(zip(missing, parsed, strict=True))
        return [self._cache[line] for line in lines]

    def plain(self, override: Override) -> bool:
        """A changed value of a key that is no config group: a str (no interpolation), a
        number, a bool or null."""
        if override.type != OverrideType.CHANGE or override.package is not None:
            return False
        value = override.value()
        if not isinstance(value, PLAIN) or (isinstance(value, str) and "${" in value):
            return False
        return not self.is_group(override.key_or_group)

    def is_group(self, key: str) -> bool:
        """Whether ``key`` (``mesh``, ``hydra.launcher``) names a config group: one of the
        groups the config loader lists under its parent (its public ``list_groups``)."""
        parent, _, name = key.replace(".", "/").rpartition("/")
        if parent not in self._groups:
            self._groups[parent] = frozenset(self.loader.list_groups(parent))
        return name in self._groups[parent]

    def __getstate__(self):  # pickled to a launcher's workers: the parser is rebuilt there
        return {"loader": self.loader, "_parser": None, "_cache": {}, "_groups": {}}


def shape(parsed: list[Override], plain: Plain) -> tuple:
    """The group of a job: its keys in order, and the whole line of each override that is
    not plain (``plain``: :meth:`Parsed.plain`)."""
    return tuple((o.key_or_group, None if plain(o) else o.input_line) for o in parsed)


def apply(cfg: DictConfig, parsed: list[Override], plain: Plain, template_hydra_lines: int) -> None:
    """Turn ``cfg`` (a composition of a job of the same group) into the composition of the
    job ``parsed``, in place: each plain override applied as Hydra applies it (the key
    must exist, the node's type converts or refuses the value), ``hydra.overrides.task`` /
    ``.hydra`` (the master's hydra lines first: the template's minus its own
    ``template_hydra_lines``) and ``hydra.job.override_dirname``."""
    for override in parsed:
        if plain(override):
            OmegaConf.update(cfg, override.key_or_group, override.value(), merge=True)
    hydra_lines = [o.input_line for o in parsed if o.is_hydra_override()]
    task = [o for o in parsed if not o.is_hydra_override()]
    lines = cast(list, OmegaConf.to_container(cfg.hydra.overrides.hydra, resolve=False))  # a line may hold ${...}
    cfg.hydra.overrides.hydra = lines[:len(lines) - template_hydra_lines] + hydra_lines
    cfg.hydra.overrides.task = [o.input_line for o in task]
    dirname = cfg.hydra.job.config.override_dirname
    cfg.hydra.job.override_dirname = override_dirname(task, exclude_keys=list(dirname.exclude_keys),
                                                      item_sep=dirname.item_sep, kv_sep=dirname.kv_sep)


def override_dirname(task: list[Override], exclude_keys: list[str], item_sep: str, kv_sep: str) -> str:
    """``hydra.job.override_dirname`` of a job whose task overrides are ``task``: the lines
    of those whose key is not in ``exclude_keys``, sorted, joined with ``item_sep``, every
    ``=`` then replaced by ``kv_sep`` (``b=2,a=1`` → ``a=1,b=2``; ``kv_sep`` is a
    ``re.sub`` replacement, as Hydra's: ``\\`` escapes in it are processed). The same text
    as Hydra's own (``get_overrides_dirname``, private to Hydra:
    tests/runner/sweep/test_sweep_planning.py compares them)."""
    lines = sorted(cast(str, o.input_line) for o in task if o.key_or_group not in exclude_keys)
    return re.sub("=", kv_sep, item_sep.join(lines))


class Template:
    """A group's Hydra composition, the number of its own hydra override lines, and for
    hashing its jobs (:func:`~decrun.runner.sweep.manifest.config_hash`) the root keys
    whose value may differ between them (``fresh``: those its plain task overrides
    change, and those holding an interpolation) and the YAML blocks of the others."""

    def __init__(self, cfg: DictConfig, members: list[list[Override]], plain: Plain) -> None:
        self.cfg = cfg
        first = members[0]
        self.hydra_lines = sum(1 for o in first if o.is_hydra_override())
        #: the positions of the plain overrides whose line differs between the group's jobs
        self.varying = tuple(i for i, o in enumerate(first)
                             if plain(o) and any(m[i].input_line != o.input_line for m in members))
        #: the task keys those overrides set (``app.dt``)
        self.varying_keys = tuple(first[i].key_or_group for i in self.varying if not first[i].is_hydra_override())
        changed = {key.split(".")[0] for key in self.varying_keys}
        raw = cast(dict, OmegaConf.to_container(cfg, resolve=False))
        self.interpolated = frozenset(str(key) for key, value in raw.items() if key != "hydra" and "${" in repr(value))
        self.fresh = frozenset(changed | self.interpolated)
        #: the job's hydra.sweep.subdir before resolution (None: it varies between the jobs)
        self.subdir = (None if any(first[i].key_or_group == "hydra.sweep.subdir" for i in self.varying)
                       else raw["hydra"]["sweep"]["subdir"])
        self.blocks: dict[str, str] = {}
        self._pickled: bytes | None = None

    def update(self, cfg: DictConfig, parsed: list[Override], plain: Plain, hydra: bool) -> None:
        """Turn the working copy ``cfg`` (the composition of an earlier job of the group)
        into job ``parsed``'s for the plan: its varying overrides applied, and with
        ``hydra`` its ``hydra.overrides`` and ``override_dirname`` (:func:`apply`)."""
        if hydra:
            apply(cfg, parsed, plain, self.hydra_lines)
            return
        for i in self.varying:
            OmegaConf.update(cfg, parsed[i].key_or_group, parsed[i].value(), merge=True)

    def __getstate__(self):  # the hash blocks are the plan's, not the launcher's
        return {**self.__dict__, "blocks": {}, "_pickled": None}

    def copy(self) -> DictConfig:
        """A copy of the template's composition: unpickled from its pickle, made once (0.6 ms
        against ``copy.deepcopy``'s 4 ms for decrun's config; the same nodes, values,
        metadata and flags — as a launcher's worker gets the template anyway). A config
        that does not pickle is deep-copied."""
        if self._pickled is None:
            try:
                self._pickled = pickle.dumps(self.cfg, protocol=pickle.HIGHEST_PROTOCOL)
            except Exception:  # noqa: BLE001 — e.g. an object node (allow_objects): copied as before
                self._pickled = b""
        return pickle.loads(self._pickled) if self._pickled else copy.deepcopy(self.cfg)

    def derive(self, parsed: list[Override], plain: Plain, master: DictConfig) -> DictConfig:
        """A job's own composition: a copy of the template (:meth:`copy`) with ``parsed`` applied."""
        cfg = self.copy()
        apply(cfg, parsed, plain, self.hydra_lines)
        OmegaConf.copy_cache(from_config=master, to_config=cfg)
        return cfg


class Composer:
    """The compositions of a sweep's jobs (module docstring)."""

    def __init__(self, loader: Any, master: DictConfig, derive: bool = True) -> None:
        self.loader, self.master, self.derive = loader, master, derive
        self.parse = Parsed(loader)
        #: shape → Template of the groups whose jobs are derived (the others Hydra composes)
        self.templates: dict[tuple, Template] = {}

    def _hydra(self, job: tuple[str, ...]) -> DictConfig:
        return self.loader.load_sweep_config(self.master, list(job))

    def each(self, jobs: list[tuple[str, ...]]) -> Iterator[tuple[tuple[str, ...], DictConfig, Template | None]]:
        """``(job, config, template)`` for each job, in order. ``config`` is only valid
        until the next job (a group's working copy); ``template``: the group's, None for a
        job composed by Hydra."""
        groups: dict[tuple, list[tuple[tuple[str, ...], list[Override]]]] = {}
        member: list[tuple] = []
        for job in jobs:
            parsed = self.parse(list(job))
            key = shape(parsed, self.parse.plain)
            groups.setdefault(key, []).append((job, parsed))
            member.append(key)
        work: dict[tuple, tuple[DictConfig, Template] | None] = {}
        for job, key in zip(jobs, member, strict=True):
            if key not in work:
                work[key] = self._start(key, groups[key]) if self.derive else None
            entry = work[key]
            if entry is None:  # composed by Hydra
                yield job, self._hydra(job), None
                continue
            cfg, template = entry
            template.update(cfg, self.parse(list(job)), self.parse.plain, hydra=self.hydra_needed(template))
            yield job, cfg, template

    @staticmethod
    def hydra_needed(template: Template) -> bool:
        """Whether a planned job needs its ``hydra`` node as Hydra would compose it: when
        a task value interpolates, or its directory pattern names more than the job number."""
        return bool(template.interpolated) or template.subdir is None or not simple_subdir(template.subdir)

    def _start(self, key: tuple, members: list) -> tuple[DictConfig, Template] | None:
        """The working copy and template of a group, after checking the derivation of its
        last job against Hydra's composition; None when they differ.

        A group of several jobs whose overrides are all plain values, or lines the master
        composition applied too (the command line's non-swept overrides), is derived from
        the master composition (:meth:`_from_master`): Hydra composes only its last job, for
        the check (~70 ms less per sweep than composing its first job too). Otherwise, or
        when that derivation does not give Hydra's last job, Hydra composes the first job
        as the template."""
        (first, first_parsed), (last, last_parsed) = members[0], members[-1]
        parsed = [m for _, m in members]
        template = composed_last = None
        if len(members) > 1:
            composed_last = self._hydra(last)
            template = self._from_master(first_parsed, parsed, last_parsed, composed_last)
        if template is None:
            template = Template(self._hydra(first), parsed, self.parse.plain)
            if composed_last is not None and not self._derives(template, last_parsed, composed_last):
                print(f"decrun: derived composition of {' '.join(last)} differs from Hydra's; composing "
                      f"each of its {len(members)} jobs with Hydra", file=sys.stderr)
                return None
        self.templates[key] = template
        cfg = copy.deepcopy(template.cfg)
        OmegaConf.copy_cache(from_config=self.master, to_config=cfg)
        return cfg, template

    def _from_master(self, first: list[Override], members: list[list[Override]], last: list[Override],
                     composed_last: DictConfig) -> Template | None:
        """The group's template made from the master composition (``first``'s overrides
        applied: :func:`apply`), if every override of ``first`` is plain or a line the master
        applied (one of its ``hydra.overrides.task``), and if it derives the group's last job
        as Hydra composed it (``composed_last``); else None."""
        applied = set(cast(list, OmegaConf.to_container(self.master.hydra.overrides.task, resolve=False)))
        if not all(self.parse.plain(o) or o.input_line in applied for o in first):
            return None
        try:
            cfg = copy.deepcopy(self.master)
            apply(cfg, first, self.parse.plain, 0)
            template = Template(cfg, members, self.parse.plain)
        except Exception:  # noqa: BLE001 — e.g. a key the master lacks: Hydra composes the template and says why
            return None
        return template if self._derives(template, last, composed_last) else None

    def _derives(self, template: Template, last: list[Override], composed_last: DictConfig) -> bool:
        """Whether ``template`` derives the job ``last`` as Hydra composed it (the whole YAML,
        ``hydra`` node included)."""
        derived = template.derive(last, self.parse.plain, self.master)
        return OmegaConf.to_yaml(derived) == OmegaConf.to_yaml(composed_last)


#: a directory pattern of literal text and the job number only
_SIMPLE = re.compile(r"(?:[^$\\]|\$\{hydra\.job\.(?:num|id)\})*")


def simple_subdir(pattern: str) -> bool:
    """``pattern`` is literal text and ``${hydra.job.num}`` / ``${hydra.job.id}`` only."""
    return _SIMPLE.fullmatch(pattern) is not None


def subdir_of(pattern: str, num: int) -> str:
    """A :func:`simple_subdir` pattern resolved for job ``num`` (its ``hydra.job.num`` and
    ``hydra.job.id``, as a launcher sets them)."""
    return re.sub(r"\$\{hydra\.job\.(?:num|id)\}", str(num), pattern)


class PlannedConfigs:
    """Hydra's config loader, except that ``load_sweep_config`` of a job of a planned group
    derives it from the group's template (:meth:`Template.derive`: a fresh copy each
    call, the launcher sets its job number on it). Everything else, and any other job,
    goes to the wrapped loader. Picklable, so launchers that compose in their workers
    (joblib, submitit, ray) get it too: it holds one config per group, not per job."""

    def __init__(self, loader: Any, templates: dict[tuple, Template], extra: tuple = ()) -> None:
        self.wrapped: Any = loader.wrapped if isinstance(loader, PlannedConfigs) else loader
        self._templates = templates
        #: the shape of the lines the sweeper appends to each job (its directories)
        self._extra = tuple(extra)
        self._parse = Parsed(self.wrapped)

    def load_sweep_config(self, master_config: DictConfig, sweep_overrides: list[str]) -> DictConfig:
        parsed = self._parse(list(sweep_overrides))
        key = shape(parsed, self._parse.plain)
        template = self._templates.get(key[:len(key) - len(self._extra)]) if key[len(key) - len(self._extra):] == \
            self._extra else None
        if template is None:
            return self.wrapped.load_sweep_config(master_config, sweep_overrides)
        return template.derive(parsed, self._parse.plain, master_config)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_") or name == "wrapped":
            raise AttributeError(name)
        return getattr(self.wrapped, name)
