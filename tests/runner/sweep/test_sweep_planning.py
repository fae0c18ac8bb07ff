"""The sweep plan's compositions (decrun.runner.sweep.fast.planning) are Hydra's: for a mix of
plain values, config groups, ``+key=``, ``~key`` and interpolations, every planned job's
config hash and every launched job's whole config (``hydra`` node included) equal those of
Hydra's own ``load_sweep_config`` of the same overrides. Timings are the benchmark's
(benchmarks/bench_sweeps.py --planning), never asserted here."""

from __future__ import annotations

import hashlib

import pytest
from hydra import initialize_config_dir
from hydra.core.config_store import ConfigStore
from hydra.core.global_hydra import GlobalHydra
from hydra.types import RunMode
from omegaconf import OmegaConf

from decrun.runner.job.config import DecrunConfig, config_dir, register_configs
from decrun.runner.sweep.fast.planning import Composer, PlannedConfigs, simple_subdir, subdir_of
from decrun.runner.sweep.manifest import UNHASHED, config_hash

#: groups of jobs: plain values only; a config group; + and ~; an interpolation into a
#: swept key; an interpolated override value; quoted strings, null and a root value
JOBS = [
    ("app.dt=0.001", "mesh.subdiv=2", "figures=false"),
    ("app.dt=0.002", "mesh.subdiv=3", "figures=true"),
    ("app.dt=0.003", "mesh.subdiv=3", "figures=false"),
    ("operator=circumcentric", "app.dt=0.001"),
    ("operator=circumcentric", "app.dt=0.004"),
    ("+app.note=first", "~app.rescale", "app.steps=4"),
    ("+app.note=second", "~app.rescale", "app.steps=5"),
    ("+app.note=${app.dt}", "app.dt=0.01"),
    ("+app.note=${app.dt}", "app.dt=0.02"),
    ("app.steps=${mesh.subdiv}", "mesh.subdiv=1"),
    ("app.scheme='explicit'", "app.dt=null", "mesh.radius=2"),
    ("app.scheme=implicit", "app.dt=0.5", "mesh.radius=1"),
]


@pytest.fixture
def hydra_loader(hydra_restore_singletons):
    register_configs()
    ConfigStore.instance().store(name="base_config", node=DecrunConfig)  # restored away after an earlier test
    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(config_dir()), version_base="1.3"):
        loader = GlobalHydra.instance().config_loader()
        master = loader.load_configuration("config", overrides=["hydra.sweep.dir=planned"], run_mode=RunMode.MULTIRUN)
        yield loader, master
    GlobalHydra.instance().clear()


def test_every_planned_job_hashes_as_hydras_composition_and_launches_as_it(hydra_loader):
    loader, master = hydra_loader
    composer = Composer(loader, master)
    planned = []
    for _job, cfg, template in composer.each(JOBS):  # cfg: the group's working copy, valid until the next job
        planned.append(config_hash(cfg, template.blocks, template.fresh) if template is not None else config_hash(cfg))
    hydra = [loader.load_sweep_config(master, list(job)) for job in JOBS]
    assert planned == [config_hash(cfg) for cfg in hydra]
    assert len(set(planned)) == len(JOBS)
    # jobs 7 and 8 interpolate the swept app.dt: each job's note is its own dt
    assert [OmegaConf.select(cfg, "app.note") for cfg in hydra[7:9]] == [0.01, 0.02]
    # one template per group (jobs 0-2, 3-4, 5, 6, 7-8, 9, 10-11; a + line is not a plain value):
    # the other jobs were derived from them, none composed by Hydra for lack of one
    assert len(composer.templates) == 7

    line = "hydra.sweep.subdir='job_x'"
    launcher = PlannedConfigs(loader, composer.templates, extra=(("hydra.sweep.subdir", None),))
    for job in JOBS:
        derived = launcher.load_sweep_config(master, [*job, line])
        assert OmegaConf.to_yaml(derived) == OmegaConf.to_yaml(loader.load_sweep_config(master, [*job, line])), job


def test_the_hash_of_a_config_is_the_hash_of_its_whole_yaml(hydra_loader):
    """config_hash hashes root key by root key (a plan reuses the blocks of the keys its
    jobs do not change): the same digest as the YAML of the whole resolved config."""
    loader, master = hydra_loader
    for overrides in ([], ["app=hodge", "+app.note=${mesh.subdiv}"], ["operator=circumcentric", "optimize.metric=stable"]):
        cfg = loader.load_sweep_config(master, overrides)
        node = {key: OmegaConf.to_container(cfg[key], resolve=True) if OmegaConf.is_config(cfg[key]) else cfg[key]
                for key in cfg if key not in UNHASHED and key != "hydra"}
        whole = OmegaConf.to_yaml(OmegaConf.create(node), sort_keys=True)
        assert config_hash(cfg) == hashlib.sha256(whole.encode()).hexdigest()[:16], overrides


@pytest.mark.parametrize("pattern, simple, job3", [
    ("${hydra.job.num}", True, "3"), ("run_${hydra.job.id}/x", True, "run_3/x"), ("fixed", True, "fixed"),
    ("${hydra.job.override_dirname}", False, None), ("${hydra:job.num}", False, None), ("a\\${b}", False, None)])
def test_a_directory_pattern_of_the_job_number_only_is_resolved_without_its_config(pattern, simple, job3):
    assert simple_subdir(pattern) is simple
    if simple:
        assert subdir_of(pattern, 3) == job3
        cfg = OmegaConf.create({"hydra": {"job": {"num": 3, "id": 3}, "sweep": {"subdir": pattern}}})
        assert str(OmegaConf.select(cfg, "hydra.sweep.subdir")) == job3  # as the sweeper reads it


def _plugins(experiment) -> dict:
    from decrun.runner.job.config import GROUPS

    return {group.attribute: getattr(experiment, group.attribute) for group in GROUPS}


def test_a_derived_job_is_checked_as_a_full_build_is_with_one_build_per_plugin(hydra_loader, monkeypatch):
    """The plan's check of a derived job (validate with a JobDelta: only the swept leaves
    assigned to the last typed config) builds the same plugins as a full check of the same
    config, and refuses a bad value with the full check's message; a group's plugins are
    each built in full once (issue 24: a 2000-job sweep built all six plugins of every job)."""
    import copy

    import decrun.runner.job.experiment as run_module
    import decrun.runner.job.plugins as plugins
    from decrun.errors import ConfigError
    from decrun.runner.job.run import validate
    from decrun.runner.sweep.fast import JobDelta

    loader, master = hydra_loader
    jobs = [(f"app.steps={n}", f"app.dt={dt}") for n in (3, 4, 5) for dt in (0.001, 0.25)]
    jobs += [("app.steps=6", "app.dt=oops"), ("app.steps=7", "app.dt=0.5")]
    composer = Composer(loader, master)
    planned = []
    for job, cfg, template in composer.each(jobs):  # the full checks, on copies of each job's config
        assert template is not None and template.varying_keys == ("app.steps", "app.dt")
        try:
            planned.append((job, copy.deepcopy(cfg), _plugins(validate(cfg))))
        except ConfigError as exc:
            planned.append((job, copy.deepcopy(cfg), exc))
    builds = []
    full_build = plugins.build

    def counted(*args, **kwargs):
        builds.append(args[1])
        return full_build(*args, **kwargs)

    monkeypatch.setattr(plugins, "build", counted)
    monkeypatch.setattr(run_module, "build", counted)
    memo: dict = {}
    delta = JobDelta("group", template.varying_keys, template.interpolated)
    work = copy.deepcopy(planned[0][1])
    for job, cfg, expected in planned:
        for key in delta.keys:  # the plan's working copy: only the swept leaves change
            OmegaConf.update(work, key, OmegaConf.select(cfg, key), merge=True)
        if isinstance(expected, ConfigError):
            with pytest.raises(ConfigError) as caught:
                validate(work, memo=memo, delta=delta)
            assert str(caught.value) == str(expected) and "app.dt" in str(expected), job
            continue
        assert _plugins(validate(work, memo=memo, delta=delta)) == expected, job
    # seven plugins built in full for the first job; after it only the app, once, when job 6's
    # bad value was refused (the full build names the key); job 7 is rebuilt from its leaves
    assert sorted(builds) == sorted(["app", "operator", "boundary", "solver", "mesh", "export", "tracker", "app"])


def test_repeated_values_run_as_jobs_of_their_own(tmp_path):
    """``app.steps=2,2`` plans two equal jobs: each runs in its own directory (Hydra's basic
    launcher failed with a traceback on the second, joblib left it missing)."""
    from cli_processes import decrun

    proc = decrun("-m", "app.steps=2,2", "figures=false", "progress=false", f"hydra.sweep.dir={tmp_path}/s",
                  cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    import pandas as pd

    table = pd.read_csv(tmp_path / "s" / "metrics.csv")
    assert list(table["status"]) == ["ok", "ok"] and list(table["steps_done"]) == [2, 2]


def test_a_sweep_without_the_speed_layer_plans_runs_and_writes_what_it_does_with_it(tmp_path):
    """``hydra.sweeper.fast=false`` (Hydra composes every job, its public API only; no loader
    swap, no memo, no warm-up) plans the same jobs, directories and config hashes as the
    speed layer, and every job writes the same ``.hydra/`` files, metrics and result fields;
    a bad value is refused the same way, naming the job."""
    import json
    import re

    from cli_processes import decrun, result_contents

    runs, refusals = {}, {}
    for fast in ("true", "false"):
        proc = decrun("-m", "app.steps=1,2", "app.dt=0.001,0.002", "operator=circumcentric,barycentric",
                      "figures=false", "progress=false", f"hydra.sweeper.fast={fast}",
                      f"hydra.sweep.dir={tmp_path}/{fast}", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr[-2000:]
        sweep = tmp_path / fast
        jobs = json.loads((sweep / "manifest.json").read_text())["jobs"]
        files = {}
        for job in jobs:
            where = sweep / job["dir"]
            for name in ("config.yaml", "overrides.yaml", "hydra.yaml"):
                text = (where / ".hydra" / name).read_text().replace(str(sweep), "<sweep>")
                files[job["dir"], name] = re.sub(r"fast(=|: )(true|false)", "fast", text)
            metrics = json.loads((where / "metrics.json").read_text())
            files[job["dir"], "metrics"] = {k: v for k, v in metrics.items() if "seconds" not in k and k != "result_h5"}
            files[job["dir"], "result"] = {k: v.tolist() if hasattr(v, "tolist") else v
                                           for k, v in result_contents(where / "result.h5").items()}
        runs[fast] = ([(job["dir"], job["overrides"], job["config_hash"]) for job in jobs], files)
        bad = decrun("-m", "app.steps=1,2", "app.dt=0.001,oops", "figures=false", f"hydra.sweeper.fast={fast}",
                     f"hydra.sweep.dir={tmp_path}/bad_{fast}", cwd=tmp_path)
        refusals[fast] = (bad.returncode, bad.stderr.strip().splitlines()[-1])
    assert len(runs["true"][0]) == 8 and runs["true"][0] == runs["false"][0]
    assert runs["true"][1].keys() == runs["false"][1].keys()
    for key, value in runs["true"][1].items():
        assert value == runs["false"][1][key], key
    assert refusals["true"] == refusals["false"] and refusals["true"][0] == 1
    assert "error: job 1 (app.steps=1 app.dt=oops " in refusals["true"][1], refusals["true"]


#: strings whose YAML needs care: booleans and numbers to YAML or Python (quoted), empty,
#: null-like, flow and block markers, a comment sign, non-ASCII, a newline, quotes, an
#: escaped interpolation (a literal ``${x}`` once resolved), a long line
TRICKY = ["yes", "No", "on", "OFF", "y", "n", "1", "-2", "1.5", " 3 ", "1_000", "1e3", "nan", "-inf", "0x10", "",
          "null", "~", "true!", "a: b", "#x", "é ü", "line\nbreak", "'q'", '"d"', "\\${x}", "- item", "[1]", "{a: 1}",
          "12:30", "0o7", "x" * 90]
PINNED = {"a": {"s": TRICKY, "n": [0, -1, 1.5, 1e-12, 1e300, float("inf"), None, True, False]},
          "b": {"nested": {"z": 1, "y": {"x": [{"k": "v"}, []], "e": {}}}}, "c": "plain", "d": 3, "ref": "${a.n}",
          "progress": True}


def test_config_hashes_are_those_of_existing_manifests_and_their_yaml_is_omegaconfs():
    """A config's hash is what earlier decrun versions wrote into their manifests (pinned:
    computed with OmegaConf's own dumper, before decrun had its own), so an existing sweep
    resumes; and each root key's YAML is ``OmegaConf.to_yaml``'s text, tricky strings and
    keys (``n``, ``y``: YAML booleans) included."""
    from decrun.runner.sweep.manifest import yaml_block

    cfg = OmegaConf.create(PINNED)
    assert config_hash(cfg) == "236fc614c45ef279"
    for key in cfg:
        value = OmegaConf.to_container(cfg[key], resolve=True) if OmegaConf.is_config(cfg[key]) else cfg[key]
        assert yaml_block(key, cfg[key]) == OmegaConf.to_yaml(OmegaConf.create({key: value}), sort_keys=True), key
    for text in TRICKY + [str(i) for i in range(-3, 4)] + ["1.", ".5", "+1", "1e-3", "Infinity", "NaN", "True1"]:
        assert yaml_block("k", text) == OmegaConf.to_yaml(OmegaConf.create({"k": text})), text
        assert yaml_block(text or "e", 1) == OmegaConf.to_yaml(OmegaConf.create({text or "e": 1})), text


def test_override_dirname_is_hydras():
    """decrun's ``hydra.job.override_dirname`` (planning.override_dirname) is the text of
    Hydra's own function (in ``hydra._internal``, which the package does not import), for
    group, plain, ``+``, ``~``, ``++``, quoted and swept-value lines and any separators."""
    from hydra._internal.config_loader_impl import get_overrides_dirname
    from hydra.core.override_parser.overrides_parser import OverridesParser

    from decrun.runner.sweep.fast.planning import override_dirname

    lines = ["app.dt=0.1", "mesh.subdiv=3", "operator=circumcentric", "+app.note=first", "~app.rescale",
             "++figures=false", "app.label='a=b, c'", "seed=1", "a.b.c=[1,2]", "x={k:v}", "name=${mesh.subdiv}",
             "z=null", "b=2", "a=1"]
    parsed = OverridesParser.create().parse_overrides(lines)
    separators = [(",", "="), ("/", "_"), ("__", ":"), ("", ""), (",", "\\\\")]
    excluded = [[], ["seed"], ["seed", "app.dt", "mesh"], ["app"]]
    for n in range(len(parsed) + 1):
        for task in (parsed[:n], parsed[n:], parsed[::-1][:n]):
            for item_sep, kv_sep in separators:
                for exclude in excluded:
                    assert override_dirname(task, exclude, item_sep, kv_sep) == get_overrides_dirname(
                        overrides=task, exclude_keys=exclude, item_sep=item_sep, kv_sep=kv_sep), (task, exclude)


def test_recent_plugins_are_new_instances_of_the_same_values_and_refuse_as_build_does():
    """plugins.Recent (a sweep's jobs in one process): a node equal to the last one built gets
    its own instance with the same values; a changed node is built anew; a refused value is
    build's ConfigError, and the next good node is built again."""
    from decrun.apps.base import App
    from decrun.errors import ConfigError
    from decrun.runner.job.config import load_option
    from decrun.runner.job.plugins import Recent, build

    recent, node = Recent(), load_option("app", "smoothing")
    first, second = recent.build(node, "app", App), recent.build(node, "app", App)
    assert first is not second and first == second == build(node, "app", App)
    changed = OmegaConf.merge(node, {"dt": 0.5})
    assert recent.build(changed, "app", App).dt == 0.5
    bad = OmegaConf.merge(node, {"steps": "many"})
    with pytest.raises(ConfigError) as refused:
        recent.build(bad, "app", App)
    with pytest.raises(ConfigError) as built:
        build(bad, "app", App)
    assert str(refused.value) == str(built.value)
    assert recent.build(node, "app", App) == first


@pytest.mark.parametrize("master_overrides, jobs, composed", [
    # plain values only: the template is the master with the first job's values, Hydra composes the last job
    ([], [("app.dt=0.001", "mesh.subdiv=2"), ("app.dt=0.002", "mesh.subdiv=2"), ("app.dt=0.003", "mesh.subdiv=3")], 1),
    # a group choice the master was composed with (a non-swept command-line override): the same
    (["operator=circumcentric", "app.dt=0.001,0.002"], [("operator=circumcentric", "app.dt=0.001"),
                                                         ("operator=circumcentric", "app.dt=0.002")], 1),
    # a group choice the master lacks: Hydra composes the first job as the template too
    ([], [("operator=circumcentric", "app.dt=0.001"), ("operator=circumcentric", "app.dt=0.002")], 2),
    # the master has a value the jobs do not (its derivation is not Hydra's): the first job's template
    (["app.steps=7"], [("app.dt=0.001",), ("app.dt=0.002",)], 2),
], ids=["plain", "master-choice", "other-choice", "master-differs"])
def test_a_group_of_plain_jobs_is_derived_from_the_master_with_one_hydra_composition(
        hydra_loader, capsys, master_overrides, jobs, composed):
    """Composer: every derived job hashes and launches as Hydra's composition; Hydra composed
    ``composed`` configs for the group; a master whose derivation fails the check falls back
    to the first job's template without a word (nothing is composed for every job)."""
    loader, _ = hydra_loader
    master = loader.load_configuration("config", overrides=["hydra.sweep.dir=planned", *master_overrides],
                                       run_mode=RunMode.MULTIRUN)
    composer = Composer(loader, master)
    calls = []
    hydra = composer._hydra
    composer._hydra = lambda job: calls.append(job) or hydra(job)
    hashes = [config_hash(cfg, template.blocks, template.fresh) for _, cfg, template in composer.each(jobs)]
    assert len(calls) == composed and len(composer.templates) == 1
    hydra_composed = [loader.load_sweep_config(master, list(job)) for job in jobs]
    assert hashes == [config_hash(cfg) for cfg in hydra_composed]
    launcher = PlannedConfigs(loader, composer.templates)  # what each job launches with: its whole config
    for job, cfg in zip(jobs, hydra_composed, strict=True):
        assert OmegaConf.to_yaml(launcher.load_sweep_config(master, list(job))) == OmegaConf.to_yaml(cfg), job
    assert "differs from Hydra's" not in capsys.readouterr().err


def test_config_groups_are_known_through_the_loaders_public_listing_as_hydras_repository_knows_them(hydra_loader):
    """A plain override is one whose key names no config group: the planner asks the
    loader's public ``list_groups``; Hydra's own (private) repository agrees on every group,
    nested group, plain key and missing key."""
    from decrun.runner.sweep.fast.planning import Parsed

    loader, _ = hydra_loader
    parse = Parsed(loader)
    keys = ["mesh", "app", "operator", "boundary", "solver", "hydra.launcher", "hydra.sweeper", "hydra.job_logging",
            "app.parts", "app.dt", "mesh.subdiv", "figures", "hydra.sweep.dir", "nothing", "nothing.deeper",
            "app.parts.none"]
    known = {key: parse.is_group(key) for key in keys}
    assert known == {key: loader.repository.group_exists(key.replace(".", "/")) for key in keys}
    assert known["mesh"] and known["hydra.launcher"] and not known["app.dt"] and not known["nothing.deeper"]
    assert [o.key_or_group for o in parse(["app.dt=0.5", "mesh=icosphere"]) if parse.plain(o)] == ["app.dt"]
