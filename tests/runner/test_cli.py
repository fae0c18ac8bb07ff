"""The ``decrun`` command end to end: default run, bad input, sweeps, tables, installs."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
import yaml

from decrun.runner.command.table import table_main
from decrun.runner.job.config import compose_config, config_dir, unique_stamp
from decrun.runner.results import read_provenance, read_result
from decrun.runner.results.checked import RESULT_RECORD, file_record
from decrun.runner.results.provenance import content_sha256

REPO = Path(__file__).resolve().parents[2]


def decrun(*args, cwd, env_extra=None, pythonpath=None, timeout=240):
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")}
    env.update(env_extra or {})
    if pythonpath:
        env["PYTHONPATH"] = str(pythonpath)
    return subprocess.run([sys.executable, "-m", "decrun", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)


def only_run_dir(tmp_path):
    runs = list((tmp_path / "outputs" / "runs").iterdir())
    assert len(runs) == 1
    return runs[0]


def test_default_run_writes_result_metrics_figure_and_log(tmp_path):
    proc = decrun(cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    run = only_run_dir(tmp_path)
    assert f"decrun: wrote outputs/runs/{run.name}/" in proc.stdout
    for name in ("result.h5", "metrics.json", "smoothing.png", "decrun.log", ".hydra/config.yaml"):
        assert (run / name).is_file(), name
    metrics = json.loads((run / "metrics.json").read_text())
    result = read_result(run / "result.h5")
    # the size and sha256 of the result, and the hash of its content (README: "Reproducible records")
    assert metrics.pop(RESULT_RECORD) == {**file_record(run / "result.h5"),
                                          "content_sha256": content_sha256(run / "result.h5")}
    assert result.metrics == metrics
    assert metrics["status"] == "ok" and metrics["stable"] is True
    assert metrics["distance_to_clean_rms"] < 0.35 * metrics["distance_to_clean_rms_initial"]
    attrs = read_provenance(run / "result.h5")
    config = yaml.safe_load(attrs["config_yaml"])
    assert config["mesh"]["_target_"].endswith("Icosphere") and config["app"]["_target_"].endswith("Smoothing")
    assert attrs["mesh_hash"] and attrs["timings"]["app_seconds"] > 0
    assert not list(run.glob(".*.tmp-*"))


BAD_OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 0 -1 0\nf 1 2 3\nf 1 2 4\nf 1 2 5\n"


@pytest.mark.parametrize(
    "args, files, words",
    [
        (["mesh=file", "mesh.path=missing.obj"], {}, ["mesh.path", "missing.obj", "not found"]),
        (["mesh=file", "mesh.path=garbage.ply"], {"garbage.ply": "ply\nformat nonsense\n"}, ["mesh.path", "garbage.ply", "end_header"]),
        (["mesh=file", "mesh.path=zero.obj"], {"zero.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"},
         ["mesh.path='zero.obj'", "line 4", "vertex 0 (OBJ indices start at 1)"]),
        (["mesh=file", "mesh.path=repeat.obj"], {"repeat.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 2 2 3\n"},
         ["mesh.path='repeat.obj'", "line 5"]),
        (["mesh=file", "mesh.path=nan.obj"], {"nan.obj": "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n"},
         ["mesh.path='nan.obj'", "line 2"]),
        (["mesh=file", "mesh.path=empty.obj"], {"empty.obj": ""}, ["mesh.path", "empty"]),
        (["mesh=file", "mesh.path=points.obj"], {"points.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\n"}, ["points.obj", "no faces"]),
        (["mesh=file", "mesh.path=fin.obj"], {"fin.obj": BAD_OBJ}, ["fin.obj", "non-manifold", "edge"]),
        (["mesh.colour=red"], {}, ["mesh.colour"]),
        (["+mesh.colour=red"], {}, ["mesh.colour: unknown option of mesh=icosphere"]),
        (["+app.stpes=3"], {}, ["app.stpes: unknown option of app=smoothing"]),
        (["mesh.major_radius=2"], {}, ["mesh.major_radius"]),
        (["app.dt=fast"], {}, ["app.dt", "Float"]),
        (["app=nosuchapp"], {}, ["app=nosuchapp: no such option", "smoothing"]),
        (["app.dt=-0.1"], {}, ["app.dt", "> 0"]),
        (["app.steps=-3"], {}, ["app.steps", ">= 0"]),
        (["operator=hexagonal"], {}, ["operator=hexagonal: no such option", "whitney"]),
        (["boundary=flux"], {}, ["boundary=flux: app=smoothing supports boundary=none"]),
        (["app=hodge", "mesh=sample", "mesh.sample=dragon"], {}, ["mesh.sample", "dragon"]),
    ],
    ids=["missing-file", "unreadable", "obj-index-0", "repeated-vertex", "nan-vertex", "empty-file", "no-faces", "non-manifold", "unknown-key", "unknown-key-plus",
         "unknown-app-key-plus", "other-source-key", "wrong-type", "unknown-option", "negative-dt", "negative-steps",
         "unknown-star", "unsupported-boundary", "unknown-sample"],
)
def test_bad_input_gives_one_clear_message(tmp_path, args, files, words):
    for name, text in files.items():
        (tmp_path / name).write_text(text)
    proc = decrun(*args, cwd=tmp_path)
    assert proc.returncode != 0
    assert "Traceback" not in proc.stderr + proc.stdout
    for word in words:
        assert word in proc.stderr, proc.stderr
    assert not list(tmp_path.rglob("result.h5"))
    assert not list(tmp_path.rglob("*.tmp-*"))


def test_verbose_shows_the_traceback(tmp_path):
    proc = decrun("-v", "app.dt=-1", cwd=tmp_path)
    assert proc.returncode != 0 and "Traceback" in proc.stderr and "app.dt" in proc.stderr
    proc = decrun("hydra.verbose=true", "app.dt=-1", cwd=tmp_path)
    assert proc.returncode != 0 and "Traceback" in proc.stderr


def test_sweeps_tables_failures_and_unique_dirs(tmp_path):
    """A 2×3 joblib sweep and a basic sweep whose job 1 fails while it runs (its mesh file
    passes the checks before the sweep, not loading), started in the same second."""
    common = ["mesh.subdiv=2", "app.steps=5", "figures=false"]
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")}
    (tmp_path / "tet.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
    (tmp_path / "huge.obj").write_text((tmp_path / "tet.obj").read_text().replace("v 1 0 0", "v 1e300 0 0"))
    procs = [
        subprocess.Popen([sys.executable, "-m", "decrun", "-m", "hydra/launcher=joblib", "hydra.launcher.n_jobs=2",
                          "app.scheme=explicit,implicit", "app.dt=0.001,0.01,0.1", *common],
                         cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True),
        subprocess.Popen([sys.executable, "-m", "decrun", "-m", "mesh=file", "mesh.path=tet.obj,huge.obj",
                          "app.steps=5", "figures=false"],
                         cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True),
    ]
    (ok_out, ok_err), (bad_out, bad_err) = (p.communicate(timeout=300) for p in procs)
    assert procs[0].returncode == 0, ok_err
    assert procs[1].returncode != 0
    sweeps = sorted((tmp_path / "outputs" / "sweeps").iterdir())
    assert len(sweeps) == 2  # distinct directories
    tables = {len(pd.read_csv(s / "metrics.csv")): s for s in sweeps}
    assert set(tables) == {6, 2}
    table = pd.read_csv(tables[6] / "metrics.csv")
    # one column per overridden parameter, then status/error, then one per metric
    assert list(table.columns[:8]) == ["job", "app.scheme", "app.dt", "mesh.subdiv", "app.steps", "figures",
                                       "status", "error"]
    assert sorted(zip(table["app.scheme"], table["app.dt"], strict=True)) == sorted(
        (s, d) for s in ("explicit", "implicit") for d in (0.001, 0.01, 0.1))
    assert (table["status"] == "ok").all() and "stable" in table.columns and "area_ratio" in table.columns
    assert (tables[6] / "metrics.md").read_text().startswith("| job |")
    # explicit Euler at dt = 0.1 (3.6 × 2/λ_max) diverges; implicit does not
    unstable = table[(table["app.scheme"] == "explicit") & (table["app.dt"] == 0.1)]
    assert not unstable["stable"].iloc[0]
    assert table[table["app.scheme"] == "implicit"]["stable"].all()
    failed = pd.read_csv(tables[2] / "metrics.csv")
    assert sorted(failed["status"]) == ["failed", "ok"]
    assert "mesh.path='huge.obj'" in failed.loc[failed["status"] == "failed", "error"].iloc[0]
    assert "failed" in bad_err
    assert not (tables[2] / "1" / "result.h5").exists()
    # decrun-table rebuilds the same table
    (tables[6] / "metrics.csv").unlink()
    assert table_main([str(tables[6])]) == 0
    pd.testing.assert_frame_equal(pd.read_csv(tables[6] / "metrics.csv"), table)
    assert table_main([str(tables[2])]) == 1  # a failed job
    assert table_main([str(tmp_path / "nope")]) == 2


def test_stamps_are_unique():
    stamps = {unique_stamp() for _ in range(2000)}
    assert len(stamps) == 2000


def test_compose_rejects_misspelt_keys_before_any_work():
    from omegaconf.errors import ConfigKeyError

    with pytest.raises(Exception) as info:
        compose_config(["app.stpes=3"])
    assert "stpes" in str(info.value) or isinstance(info.value, ConfigKeyError)


def test_every_plugin_yaml_names_a_class_of_its_kind():
    """Contract: every conf/<group>/<option>.yaml names with `_target_` a dataclass of the
    group's kind, and its keys are options of that class (declared once, in the class)."""
    import dataclasses

    from decrun.runner.job.config import GROUPS
    from decrun.runner.job.plugins import option, target_class

    assert {path.name for path in config_dir().iterdir() if path.is_dir()} - {"hydra", "experiment"} \
        == {group.key for group in GROUPS}  # the table lists every group directory of conf/
    for group_row in GROUPS:
        group = group_row.key
        files = sorted(p for p in group_row.conf_dir().glob("*.yaml") if not p.stem.startswith("_"))
        assert files, group
        for path in files:
            node = compose_config([f"{group}={path.stem}"])[group]
            assert str(node._target_).startswith(group_row.builtins), (path, node._target_)
            cls = target_class(node, group, group_row.base_class())
            fields = {f.name for f in dataclasses.fields(cls)}
            # every option is in the composed node (overridable as group.key=value), nothing else is
            assert set(node) - {"_target_"} == fields, (path, set(node) ^ fields)
            if path.stem not in ("file", "result"):  # (those two need a path)
                option(group, path.stem)  # builds with its defaults


def _copy_package(target: Path) -> Path:
    """The package as a wheel lays it out: decrun/ with a real conf/ directory inside."""
    site = target / "site"
    shutil.copytree(REPO / "decrun", site / "decrun", symlinks=False,
                    ignore=shutil.ignore_patterns("__pycache__"))
    assert (site / "decrun" / "conf").is_dir() and not (site / "decrun" / "conf").is_symlink()
    return site


def _check_installed_run(site: Path, cwd: Path):
    proc = decrun("app.steps=2", cwd=cwd, pythonpath=site)
    assert proc.returncode == 0, proc.stderr
    run = only_run_dir(cwd)
    assert (run / "result.h5").is_file()
    hydra_cfg = yaml.safe_load((run / ".hydra" / "hydra.yaml").read_text())
    sources = [s["path"] for s in hydra_cfg["hydra"]["runtime"]["config_sources"]]
    assert any(str(site) in str(p) for p in sources), sources  # configs came from the install
    where = subprocess.run([sys.executable, "-c", "import decrun; print(decrun.__file__)"], cwd=cwd, text=True,
                           capture_output=True, env=dict(os.environ, PYTHONPATH=str(site))).stdout
    assert where.startswith(str(site))


def test_installed_elsewhere_layout_runs_from_another_directory(tmp_path):
    site = _copy_package(tmp_path)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    _check_installed_run(site, elsewhere)


def test_wheel_install_runs_from_another_directory(tmp_path):
    """Build the wheel (pip, isolated build: ~5 s) and run decrun from it, outside the repo."""
    source = tmp_path / "source"  # a clean copy: no stale build/ of the checkout gets packaged
    for name in ("decrun", "conf"):
        shutil.copytree(REPO / name, source / name, symlinks=True, ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, source / name)
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path / "wheel"),
                            str(source)], capture_output=True, text=True, timeout=600)
    if build.returncode != 0 and ("Could not find a version" in build.stderr or "No matching distribution" in build.stderr):
        pytest.skip("no package index reachable for the build requirements (setuptools, wheel)")
    assert build.returncode == 0, build.stderr
    wheel = next((tmp_path / "wheel").glob("decrun-*.whl"))
    site = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(site), str(wheel)],
                   check=True, capture_output=True, timeout=600)
    assert (site / "decrun" / "conf" / "config.yaml").is_file()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    _check_installed_run(site, elsewhere)


def test_a_long_run_killed_with_sigkill_leaves_a_readable_incomplete_result(tmp_path):
    """SIGKILL in the middle of a long smoothing run: the steps recorded so far are on disk
    (the run's journal beside result.h5), read back as incomplete with every series of the
    same length; decrun-table turns it into an incomplete result.h5 (status killed)."""
    import signal
    import time

    from decrun.runner.results import recover_result
    from decrun.runner.results.journal import journal_path

    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")}
    proc = subprocess.Popen([sys.executable, "-m", "decrun", "mesh.subdiv=2", "app.steps=1000000", "app.dt=1e-6",
                             "app.critical_dt=false", "figures=false"], cwd=tmp_path, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 60
    journal = None
    while time.time() < deadline:
        runs = list((tmp_path / "outputs" / "runs").glob("*/result.h5.partial"))
        if runs and runs[0].stat().st_size > 200_000:
            journal = runs[0]
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    assert journal is not None, "the run recorded nothing within 60 s"
    result_path = journal.with_name("result.h5")
    assert not result_path.exists() and journal == journal_path(result_path)
    partial = read_result(result_path)
    assert not partial.complete and partial.status == "unfinished" and partial.steps_recorded > 10
    lengths = {name: len(values) for name, values in partial.series.items()}
    assert set(lengths) == {"step", "area", "volume", "roughness", "distortion"}
    assert set(lengths.values()) == {partial.steps_recorded}
    assert list(partial.series["step"]) == list(range(partial.steps_recorded))
    assert recover_result(result_path) == result_path
    killed = read_result(result_path)
    assert not killed.complete and killed.status == "killed" and killed.steps_recorded == partial.steps_recorded


def test_help_and_completion_list_options_not_schema_pieces(tmp_path):
    """`decrun --help` and shell completion list the options of each group, never the shared
    pieces of a group (conf/mesh/_post_processing.yaml) or schema nodes."""
    help_text = decrun("--help", cwd=tmp_path).stdout
    assert "mesh: annulus, box, bunny, channel" in help_text and "_post_processing" not in help_text
    assert "base_" not in help_text and "boundary: flux, none" in help_text
    env_extra = {"COMP_LINE": "decrun mesh=", "COMP_POINT": "12"}
    words = decrun("-sc", "query=bash", cwd=tmp_path, env_extra=env_extra).stdout.split()
    assert "mesh=icosphere" in words and "mesh=channel" in words
    assert not [w for w in words if "_post" in w or "base_" in w]
    script = decrun("-sc", "install=bash", cwd=tmp_path).stdout
    assert "complete -o nospace" in script and "\n" in script  # the install script is printed verbatim


def test_version_is_decruns_own(tmp_path):
    """`decrun --version` prints decrun's version (the package's), not Hydra's, and exits 0,
    also after overrides; nothing is run or written."""
    import decrun as package

    for args in (["--version"], ["app=heat", "--version"]):
        done = decrun(*args, cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        assert done.stdout == f"decrun {package.__version__}\n" and "Hydra" not in done.stdout, done.stdout
    assert list(tmp_path.iterdir()) == []
