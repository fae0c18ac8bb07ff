"""Sweep tables from job directories (no decrun process): one row per planned job with
its state, nullable integers, the result column, load_sweep == read_csv, stacking and
selection; the objective a job returns to an optimising sweeper; the job cache."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from decrun.apps.base import Result
from decrun.errors import ConfigError
from decrun.runner.command.table import table_main
from decrun.runner.job.config import OptimizeConfig
from decrun.runner.results.checked import RESULT_RECORD, file_record
from decrun.runner.results.recorder import ResultRecorder, write_result
from decrun.runner.sweep.manifest import FORMAT, MANIFEST
from decrun.runner.sweep.tables import load_sweep, select, stack, sweep_table, write_sweep_table


def make_sweep(root, jobs: dict[str, dict | str | None], hashes: dict[str, str] | None = None):
    """A sweep directory with a manifest planning ``jobs`` (name → metrics.json content,
    "killed" for a journal without metrics, None for a job that never started)."""
    root.mkdir(parents=True)
    hashes = hashes or {}
    planned = [{"job": name, "overrides": [f"app.dt={0.1 * (i + 1):g}", "mesh.subdiv=2"],
                "config_hash": hashes.get(name, f"h{name}")} for i, name in enumerate(jobs)]
    (root / MANIFEST).write_text(json.dumps({"format": FORMAT, "overrides": ["app.dt=0.1,0.2"], "jobs": planned,
                                             "runs": [{"started": "t", "jobs": list(jobs), "finished": None}]}))
    (root / "multirun.yaml").write_text("hydra: {}\n")
    for name, content in jobs.items():
        if content is None:
            continue
        job = root / name
        (job / ".hydra").mkdir(parents=True)
        if content == "killed":
            recorder = ResultRecorder(job / "result.h5", vertices=np.zeros((3, 3)), simplices=np.array([[0, 1, 2]]))
            for step in range(5):
                recorder.record(step, energy=float(step))
            continue
        write_job(job, {"config_hash": f"h{name}", **content})
    return root


def write_job(job, metrics: dict) -> None:
    """What a finished job writes: ``result.h5`` (when ok) and ``metrics.json``, which
    records the result's size and sha256 as the runner does."""
    if metrics.get("status") == "ok":
        write_result(job / "result.h5", Result(metrics=metrics), vertices=np.eye(3), simplices=np.array([[0, 1, 2]]))
        metrics = {**metrics, RESULT_RECORD: file_record(job / "result.h5")}
    (job / "metrics.json").write_text(json.dumps(metrics))


def test_every_planned_job_has_a_row_with_its_state(tmp_path):
    sweep = make_sweep(tmp_path / "s", {
        "0": {"status": "ok", "iterations": 10240, "stable": True, "energy": 0.5},
        "1": {"status": "failed", "error": "app.dt: must be > 0"},
        "2": "killed",
        "3": None,
    })
    table = sweep_table(sweep)
    assert list(table["status"]) == ["ok", "failed", "killed", "missing"]
    assert "5 recorded steps" in table.loc[2, "error"] and table.loc[3, "error"] == "never started"
    # the planned overrides are known also for the jobs that never wrote anything
    assert list(table["app.dt"]) == [0.1, 0.2, 0.3, 0.4]
    assert list(table["result"]) == ["0/result.h5", "", "2/result.h5.partial", ""]
    # the path the table prints reads back, a killed job's journal included (and a job directory)
    from decrun.runner.results import read_result

    killed = read_result(sweep / table.loc[2, "result"])
    assert not killed.complete and killed.steps_recorded == 5 and list(killed.series["energy"]) == [0, 1, 2, 3, 4]
    assert read_result(sweep / "2").steps_recorded == 5 and read_result(sweep / table.loc[0, "result"]).complete
    # integers stay integers where a row lacks them
    assert str(table["iterations"].dtype) == "Int64"
    written = write_sweep_table(sweep)
    csv = (sweep / "metrics.csv").read_text()
    assert ",10240," in csv and "10240.0" not in csv and "1.024e+04" not in (sweep / "metrics.md").read_text()
    pd.testing.assert_frame_equal(load_sweep(sweep), pd.read_csv(sweep / "metrics.csv"))
    assert len(written) == 4 and "config_hash" not in written.columns
    assert table_main([str(sweep)]) == 1  # a killed sweep never looks complete


def test_a_job_directory_from_another_config_is_stale(tmp_path):
    sweep = make_sweep(tmp_path / "s", {"0": {"status": "ok", "x": 1}}, hashes={"0": "other"})
    row = sweep_table(sweep).iloc[0]
    assert row["status"] == "stale" and "other" in row["error"]


def test_stack_select_sort_and_drop_constant(tmp_path):
    a = make_sweep(tmp_path / "a", {"0": {"status": "ok", "e": 3.0, "n": 7}, "1": {"status": "ok", "e": 1.0, "n": 7}})
    b = make_sweep(tmp_path / "b", {"0": {"status": "ok", "e": 2.0, "n": 7, "extra": 1}})
    table = stack([a, b])
    assert list(table.columns[:2]) == ["sweep", "job"] and list(table["sweep"]) == [str(a), str(a), str(b)]
    assert table["extra"].isna().tolist() == [True, True, False]
    shown = select(table, metrics=["e"], sort=["e"], drop_constant=True)
    assert list(shown["e"]) == [1.0, 2.0, 3.0]
    # mesh.subdiv, status-less error and n are constant: dropped; sweep/job/status kept
    assert list(shown.columns) == ["sweep", "job", "app.dt", "status", "e", "result"]
    assert list(select(table, sort=["e"], descending=True)["e"]) == [3.0, 2.0, 1.0]
    with pytest.raises(KeyError, match="no column 'nope'"):
        select(table, metrics=["nope"])


def test_decrun_table_options_and_exit_codes(tmp_path, capsys):
    a = make_sweep(tmp_path / "a", {"0": {"status": "ok", "e": 3.0, "n": 7}, "1": {"status": "ok", "e": 1.0, "n": 7}})
    b = make_sweep(tmp_path / "b", {"0": {"status": "ok", "e": 2.0, "n": 7}})
    capsys.readouterr()
    assert table_main([str(a), str(b), "--csv", "--metrics", "e", "--sort", "e"]) == 0
    csv = capsys.readouterr().out.splitlines()
    # CSV keeps constant columns unless asked
    assert csv[0] == "sweep,job,app.dt,mesh.subdiv,status,error,e,result"
    assert [line.split(",")[6] for line in csv[1:]] == ["1.0", "2.0", "3.0"]
    assert table_main([str(a), "--drop-constant", "--csv"]) == 0
    assert "mesh.subdiv" not in capsys.readouterr().out.splitlines()[0]
    assert table_main([str(a), "--all"]) == 0  # every column, the constant ones (mesh.subdiv, error, n) too
    assert capsys.readouterr().out.splitlines()[0] == "| job | app.dt | mesh.subdiv | status | error | e | n | result |"
    assert table_main([str(a), "--all", "--drop-constant"]) == 0  # unless asked
    assert capsys.readouterr().out.splitlines()[0] == "| job | app.dt | status | e | result |"
    assert table_main([str(a)]) == 0  # by default only the apps' headline metrics (e is none)
    assert capsys.readouterr().out.splitlines()[0] == "| job | app.dt | status | result |"
    assert table_main([str(a), "--metrics", "n"]) == 0  # asked for: kept although constant
    assert capsys.readouterr().out.splitlines()[0] == "| job | app.dt | status | n | result |"
    assert table_main([str(a), "--sort", "nope"]) == 2
    assert "no column 'nope'" in capsys.readouterr().err


def test_decrun_table_does_not_write_into_a_directory_of_single_runs(tmp_path, capsys):
    runs = tmp_path / "outputs" / "runs"
    for name, metrics in (("2026-01-01_00-00-00_aaaaaa", {"status": "ok", "e": 1.0}),
                          ("2026-01-01_00-00-01_bbbbbb", {"status": "ok", "e": 2.0})):
        (runs / name / ".hydra").mkdir(parents=True)
        write_job(runs / name, metrics)
    before = sorted(p.name for p in runs.iterdir())
    assert table_main([str(runs)]) == 0
    assert "| 2026-01-01_00-00-01_bbbbbb |" in capsys.readouterr().out
    assert sorted(p.name for p in runs.iterdir()) == before
    with pytest.raises(NotADirectoryError):
        write_sweep_table(runs)


def test_the_objective_a_job_returns():
    maximize = OptimizeConfig(metric="dt", direction="maximize", require="stable")
    assert maximize.objective({"dt": 0.02, "stable": True}) == 0.02
    assert maximize.objective({"dt": 0.03, "stable": False}) == -math.inf
    assert maximize.objective(None) == -math.inf  # a failed job
    minimize = OptimizeConfig(metric="err")
    assert minimize.objective({"err": float("nan")}) == math.inf
    with pytest.raises(ConfigError, match="no metric 'err'"):
        minimize.objective({"dt": 1.0})
    with pytest.raises(ConfigError, match="optimize.direction"):
        OptimizeConfig(metric="dt", direction="up")


def test_jobs_of_one_process_share_mesh_complex_and_operators():
    from decrun.runner.io import job_cache
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment

    job_cache.clear()
    common = ["mesh.subdiv=2", "app.steps=2", "figures=false"]
    plain = run_experiment(compose_config([*common, "app.dt=0.002"])).result
    hits = job_cache.stats["hits"]
    run1 = run_experiment(compose_config([*common, "app.dt=0.002"]), cache=True)
    run2 = run_experiment(compose_config([*common, "app.dt=0.004"]), cache=True)
    first, second = run1.result, run2.result
    assert job_cache.stats["hits"] == hits + 2  # mesh and DEC of the second job
    assert run1.complex is run2.complex and run1.dec is run2.dec and run1.mesh is not run2.mesh
    assert run2.timings["mesh_seconds"] == 0 and run2.complex is not None
    # the critical step was solved once and kept by the shared DEC; results are unchanged
    assert second.metrics["dt_critical_explicit"] == first.metrics["dt_critical_explicit"]
    for key in ("area_ratio", "roughness_ratio", "dt_critical_explicit", "distance_to_clean_rms"):
        assert first.metrics[key] == plain.metrics[key]
    other = run_experiment(compose_config([*common, "app.dt=0.002", "mesh.seed=1"]), cache=True).result
    assert other.metrics["distance_to_clean_rms_initial"] != first.metrics["distance_to_clean_rms_initial"]
    job_cache.clear()


def test_other_sweepers_refuse_a_non_empty_sweep_dir(tmp_path, capsys):
    """Sweepers without a manifest (optuna) cannot resume: the end-of-sweep callback
    refuses to mix a new sweep into an old directory, in one line."""
    from omegaconf import OmegaConf

    from decrun.runner.command.callbacks import SweepTable

    old = tmp_path / "old"
    (old / "0").mkdir(parents=True)
    config = OmegaConf.create({"hydra": {"sweep": {"dir": str(old)},
                                         "sweeper": {"_target_": "hydra_plugins.hydra_optuna_sweeper.optuna_sweeper.OptunaSweeper"}}})
    with pytest.raises(SystemExit) as info:
        SweepTable().on_multirun_start(config)
    assert info.value.code == 1
    assert "is not empty" in capsys.readouterr().err
    SweepTable().on_multirun_start(OmegaConf.create({"hydra": {"sweep": {"dir": str(tmp_path / "new")},
                                                               "sweeper": config.hydra.sweeper}}))


def test_derived_job_compositions_equal_hydras(capsys, monkeypatch):
    """The sweeper derives jobs that differ only in plain values from one composition:
    every derived config (hydra node included) is the one Hydra composes; when a
    derivation differs, the sweeper says so and uses Hydra's."""
    import copy

    from hydra import initialize_config_dir
    from hydra.core.global_hydra import GlobalHydra
    from hydra.types import RunMode
    from omegaconf import OmegaConf

    from decrun.runner.job.config import config_dir
    from decrun.runner.sweep.fast import planning
    from decrun.runner.sweep.fast.planning import Composer

    GlobalHydra.instance().clear()
    with initialize_config_dir(config_dir=str(config_dir()), version_base="1.3"):
        loader = GlobalHydra.instance().config_loader()
        master = loader.load_configuration("config", ["hydra.sweep.dir=x"], RunMode.MULTIRUN)
        jobs = [(f"app.dt={dt}", f"operator={op}", "mesh.subdiv=2", f"hydra.sweep.subdir={i}")
                for i, (dt, op) in enumerate((dt, op) for op in ("mixed_area", "barycentric") for dt in (0.1, 0.2, 0.4))]
        derived = {job: copy.deepcopy(cfg) for job, cfg, _ in Composer(loader, master).each(jobs)}
        for job in jobs:
            assert OmegaConf.to_yaml(derived[job]) == OmegaConf.to_yaml(loader.load_sweep_config(master, list(job))), job
        assert derived[jobs[1]].app.dt == 0.2 and derived[jobs[1]].hydra.sweep.subdir == "1"
        assert derived[jobs[4]].operator != derived[jobs[1]].operator  # the other group option
        assert list(derived[jobs[1]].hydra.overrides.task) == list(jobs[1][:-1])
        capsys.readouterr()

        def wrong(cfg, *args):
            right(cfg, *args)
            cfg.app.steps = 99

        right = planning.apply
        monkeypatch.setattr(planning, "apply", wrong)
        composer = Composer(loader, master)
        checked = [(copy.deepcopy(cfg), template) for _, cfg, template in composer.each(jobs[:3])]
        assert "differs from Hydra's" in capsys.readouterr().err
        assert all(cfg.app.steps != 99 and template is None for cfg, template in checked)
        assert not composer.templates  # nothing for the launcher to derive from
    GlobalHydra.instance().clear()


def test_a_real_sweep_table_is_narrow_by_default_and_keeps_asked_columns(decrun_cli, tmp_path):
    """A 2-job smoothing sweep through the CLI: the printed table shows the swept key and the
    smoothing headline metrics (8 columns; every column with ``--all``, constant ones too), and
    ``--metrics dt`` keeps dt although every job has the same."""
    import subprocess
    import sys
    from pathlib import Path

    sweep = tmp_path / "sweep"
    proc = decrun_cli("-m", "app.steps=1,2", "mesh.subdiv=1", "figures=false", f"hydra.sweep.dir={sweep}")
    assert proc.returncode == 0, proc.stderr
    assert "more columns in metrics.md (`decrun-table --all" in proc.stdout
    table = str(Path(sys.executable).parent / "decrun-table")

    def header(*args):
        out = subprocess.run([table, str(sweep), *args], capture_output=True, text=True, check=True).stdout
        return out.splitlines()[0].strip("| ").split(" | ")

    narrow, wide = header(), header("--all")
    assert narrow[:3] == ["job", "app.steps", "status"] and "distance_to_clean_rms" in narrow
    assert "roughness_ratio" not in narrow and "roughness_ratio" in wide and len(wide) >= len(narrow) + 5
    assert "figures" in wide and "n_vertices" in wide  # constant in this sweep, shown with --all
    assert "dt" not in narrow and header("--metrics", "dt") == ["job", "app.steps", "status", "dt", "result"]


def test_overrides_are_read_by_hydras_parser():
    from decrun.runner.sweep.tables import parse_overrides

    assert parse_overrides(["app.dt=1e-3", "+x=a", "hydra.verbose=true", "figures=False", "~app.rescale",
                            "mesh.path='a b.obj'", "app.strokes=[{points:[[0.1,0.2]]}]", "solver.tol=1e-10"]) == {
        "app.dt": 0.001, "x": "a", "figures": False, "app.rescale": None, "mesh.path": "a b.obj",
        "app.strokes": "[{points:[[0.1,0.2]]}]", "solver.tol": 1e-10}


#: an override of every root key and config group of decrun's config (each a possible column)
ROOT_OVERRIDES = ["mesh=icosphere", "operator=mixed_area", "boundary=none", "solver=direct", "figures=false",
                  "progress=false", "+experiment=operator_variants"]


@pytest.mark.parametrize("app", ["smoothing", "parametrization", "hodge", "vector_field", "fluid"])
def test_no_override_shares_a_column_with_a_metric(app, tmp_path):
    """Each app's real metrics against an override of every root key and group: one column
    each, the override's value under its key, each metric under :func:`metric_column`."""
    from omegaconf import OmegaConf
    from runner.config.test_app_grid import APP_MESH  # tests/ is on sys.path (conftest)

    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import run_experiment
    from decrun.runner.sweep.tables import metric_column, reserved_names

    result = run_experiment(compose_config([f"app={app}", "figures=false", *APP_MESH[app]])).result
    metrics = {k: v for k, v in result.metrics.items() if isinstance(v, (bool, int, float, str))}
    overrides = [*ROOT_OVERRIDES, f"app={app}"]
    sweep = make_sweep(tmp_path / "s", {"0": metrics})
    manifest = json.loads((sweep / MANIFEST).read_text())
    manifest["jobs"][0]["overrides"] = overrides
    (sweep / MANIFEST).write_text(json.dumps(manifest))
    (sweep / "multirun.yaml").write_text(OmegaConf.to_yaml(compose_config([f"app={app}"])))  # the root keys
    table = sweep_table(sweep)
    assert table.columns.is_unique
    reserved = reserved_names(sweep)
    assert {"mesh", "boundary", "figures", "optimize"} <= reserved  # in every decrun sweep, overridden or not
    assert table.loc[0, "app"] == app and table.loc[0, "boundary"] == "none" and table.loc[0, "experiment"] == \
        "operator_variants"
    for name, value in metrics.items():
        if name not in ("status", "error"):
            assert table.loc[0, metric_column(name, reserved | {"experiment", "app"})] == value, name
    assert table_main([str(sweep)]) == 0


def test_decrun_table_prints_a_read_only_sweeps_table_and_says_it_was_not_saved(tmp_path, capsys, monkeypatch):
    """issue 34.6: an OSError traceback before; now the table, then one line saying why it was not saved."""
    import errno

    import decrun.runner.sweep.tables as tables

    sweep = make_sweep(tmp_path / "s", {"0": {"status": "ok", "e": 1.0}, "1": {"status": "ok", "e": 2.0}})

    def read_only(path, text):
        raise OSError(errno.EROFS, "Read-only file system", str(path))

    monkeypatch.setattr(tables, "write_text_atomic", read_only)
    assert table_main([str(sweep), "--csv"]) == 0
    out, err = capsys.readouterr()
    assert out.splitlines()[0].startswith("job,") and len(out.splitlines()) == 3
    assert err.splitlines() == [f"decrun-table: the table above could not be saved in {sweep} (metrics.csv, "
                                f"metrics.md: Read-only file system); it is printed only (`decrun-table --csv "
                                f"{sweep} > FILE` saves it elsewhere)"]
    assert not (sweep / "metrics.csv").exists()


def test_decrun_table_on_a_read_only_mount(tmp_path):
    """The same on a real read-only bind mount (where this machine allows one: root in a mount namespace)."""
    import shutil
    import subprocess
    import sys

    if shutil.which("unshare") is None:
        pytest.skip("no unshare")
    sweep = make_sweep(tmp_path / "s", {"0": {"status": "ok", "e": 1.0}})
    table = f"import sys; from decrun.runner.command.table import table_main; sys.exit(table_main([{str(sweep)!r}]))"
    script = (f"mount --bind {sweep} {sweep} && mount -o remount,ro,bind {sweep} || exit 77; "
              f"{sys.executable} -c {table!r}")
    proc = subprocess.run(["unshare", "-m", "sh", "-c", script], capture_output=True, text=True, timeout=120)
    if proc.returncode == 77 or "unshare:" in proc.stderr:
        pytest.skip(f"no read-only mount here: {proc.stderr.strip()[:200]}")
    assert proc.returncode == 0, proc.stderr
    assert "| job |" in proc.stdout and "Traceback" not in proc.stderr
    assert proc.stderr.strip().startswith(f"decrun-table: the table above could not be saved in {sweep}")
    assert "Read-only file system" in proc.stderr and not (sweep / "metrics.csv").exists()


def test_jobs_that_repeat_an_earlier_result_exactly_are_marked_same_as(tmp_path, capsys):
    """Two planned jobs that computed the same numbers (the same content hash: their configs
    differ in a key that does not act) — the later one names the earlier in ``same_as``,
    shown in the default table; a failed job or a different result is never marked."""
    from decrun.runner.results.provenance import result_record

    sweep = make_sweep(tmp_path / "s", {"0": {"status": "ok", "e": 1.0}, "1": {"status": "ok", "e": 2.0},
                                        "2": {"status": "ok", "e": 1.0}, "3": {"status": "failed", "error": "x"},
                                        "4": {"status": "ok", "e": 2.0}})
    for job in ("0", "1", "2", "4"):  # what the runner records: the result's content hash too
        path = sweep / job / "metrics.json"
        metrics = json.loads(path.read_text())
        path.write_text(json.dumps({**metrics, RESULT_RECORD: result_record(sweep / job / "result.h5")}))
    table = sweep_table(sweep)
    assert table["same_as"].isna().tolist() == [True, True, False, True, False]
    assert table.loc[2, "same_as"] == 0 and table.loc[4, "same_as"] == 1
    assert table_main([str(sweep)]) == 1  # job 3 failed
    header, _, *rows = capsys.readouterr().out.splitlines()
    assert "same_as" in header.split(" | ") and rows[2].split(" | ")[-2] == "0"
    # no repeats: no column
    lone = make_sweep(tmp_path / "t", {"0": {"status": "ok", "e": 1.0}})
    assert "same_as" not in sweep_table(lone)
