"""result.h5 round trip, provenance and atomic writing (decrun.runner.results)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

import decrun
from decrun.runner.results import Result, read_mesh, read_provenance, read_result, write_metrics_json, write_result


def sample_result():
    rng = np.random.default_rng(0)
    return Result(
        fields={"vertices_final": rng.standard_normal((50, 3)), "faces": rng.integers(0, 50, (90, 3)),
                "flags": np.array([True, False, True]), "big": rng.standard_normal(10000)},
        series={"area": np.linspace(1.0, 0.5, 11), "volume": np.full(11, np.nan)},
        metrics={"stable": True, "diverged_at_step": -1, "area_ratio": 0.5, "volume_drift_rel": float("nan"),
                 "scheme": "implicit", "np_float": np.float64(0.25), "np_bool": np.bool_(False), "np_int": np.int64(7)},
    )


def test_round_trip_returns_the_same_result(tmp_path):
    result = sample_result()
    V, F = np.random.default_rng(1).standard_normal((5, 3)), np.array([[0, 1, 2], [2, 3, 4]])
    path = write_result(tmp_path / "result.h5", result, vertices=V, simplices=F, config_yaml="app:\n  dt: 0.1\n",
                        mesh_hash="abc", timings={"app_seconds": 1.5})
    back = read_result(path)
    assert back.fields.keys() == result.fields.keys() and back.series.keys() == result.series.keys()
    for name in result.fields:
        np.testing.assert_array_equal(back.fields[name], result.fields[name])
        assert back.fields[name].dtype == result.fields[name].dtype
    for name in result.series:
        np.testing.assert_array_equal(back.series[name], result.series[name])
    assert back.metrics.keys() == result.metrics.keys()
    for name, value in result.metrics.items():
        got = back.metrics[name]
        if isinstance(value, float) and math.isnan(value):
            assert math.isnan(got)
        else:
            assert got == value and type(got) is type(value.item() if hasattr(value, "item") else value)
    mesh_v, mesh_f = read_mesh(path)
    np.testing.assert_array_equal(mesh_v, V)
    np.testing.assert_array_equal(mesh_f, F)


def test_provenance_attributes(tmp_path):
    path = write_result(tmp_path / "result.h5", sample_result(), config_yaml="app:\n  dt: 0.1\n",
                        mesh_hash="deadbeef", timings={"app_seconds": 1.5})
    attrs = read_provenance(path)
    assert yaml.safe_load(attrs["config_yaml"]) == {"app": {"dt": 0.1}}
    assert attrs["decrun_version"] == decrun.__version__
    assert attrs["numpy_version"] == np.__version__
    for key in ("scipy_version", "pymeshlab_version", "h5py_version", "created"):
        assert attrs[key] and attrs[key] != "unknown"
    assert attrs["mesh_hash"] == "deadbeef"
    assert attrs["timings"] == {"app_seconds": 1.5}
    assert len(attrs.get("git_commit", "0" * 40)) >= 40  # present in a checkout, absent in a wheel


def test_a_failed_write_leaves_no_file(tmp_path):
    bad = Result(fields={"ok": np.zeros(3), "bad": np.array([object()], dtype=object)})
    with pytest.raises(TypeError):
        write_result(tmp_path / "result.h5", bad)
    assert list(tmp_path.iterdir()) == []


def test_rewrite_replaces_atomically(tmp_path):
    path = tmp_path / "result.h5"
    write_result(path, Result(metrics={"a": 1}))
    write_result(path, Result(metrics={"a": 2}))
    assert read_result(path).metrics == {"a": 2}
    assert [p.name for p in tmp_path.iterdir()] == ["result.h5"]


def test_metrics_json_is_plain(tmp_path):
    path = write_metrics_json(tmp_path / "metrics.json", sample_result().metrics)
    data = json.loads(path.read_text())
    assert data["stable"] is True and data["np_bool"] is False and data["np_int"] == 7 and data["np_float"] == 0.25
    assert math.isnan(data["volume_drift_rel"])


# ----------------------------------------------------------------------------------
# issue 34.9: what "reproducible" means for result.h5 and metrics.json
# ----------------------------------------------------------------------------------


def _written(path, result=None, **changes):
    V, F = np.eye(3), np.array([[0, 1, 2]])
    base = dict(config_yaml="app:\n  dt: 0.1\n", mesh_hash="abc", timings={"app_seconds": 1.5})
    return write_result(path, result or sample_result(), vertices=V, simplices=F, **{**base, **changes})


def test_the_content_hash_leaves_out_times_and_provenance_only(tmp_path):
    """Time stamps, timings, wall-time metrics, versions, the config text and how a run was
    made (a sweep job's config_hash, resumed_from_step) do not change the content hash;
    any dataset value, shape, dtype or attribute, and any other metric, does."""
    import h5py

    from decrun.runner.results.provenance import content_sha256, is_wall_time

    assert [is_wall_time(n) for n in ("solve_seconds", "step_seconds_max", "steps_per_second", "seconds",
                                      "total_seconds", "dt", "period_s", "secondsish", "final_time")] == \
        [True, True, True, True, True, False, False, False, False]
    reference = content_sha256(_written(tmp_path / "a.h5"))

    def edited(name, edit, **changes):
        path = _written(tmp_path / f"{name}.h5", **changes)
        if edit is not None:
            with h5py.File(path, "r+") as f:
                edit(f)
        return content_sha256(path)

    def metric(name, value):
        def edit(f):
            metrics = json.loads(f.attrs["metrics_json"])
            metrics[name] = value
            f.attrs["metrics_json"] = json.dumps(metrics)
            f["metrics"].attrs[name] = value
        return edit

    same = {
        "times": edited("times", lambda f: f.attrs.update(created="2000-01-01T00:00:00+00:00", finished="x")),
        "timings": edited("timings", None, timings={"app_seconds": 99.0, "total_seconds": 3.0}),
        "versions": edited("versions", lambda f: f.attrs.update(numpy_version="0.0", git_commit="deadbeef")),
        "config text": edited("config", None, config_yaml="app:\n  dt: 0.1\nprogress: false\n"),
        "wall-time metric": edited("wall", metric("solve_seconds", 12.5)),
        "sweep job's hash": edited("hash", metric("config_hash", "0123456789abcdef")),
        "resumed run": edited("resumed", metric("resumed_from_step", 40)),
    }
    assert all(value == reference for value in same.values()), {k: v == reference for k, v in same.items()}

    def flip(f):
        f["fields/big"][17] = np.nextafter(f["fields/big"][17], np.inf)

    differ = {
        "one ulp of a field": edited("ulp", flip),
        "a metric": edited("metric", metric("area_ratio", 0.5000001)),
        "a dataset's dtype": edited("dtype", lambda f: (f["series"].__delitem__("area"),
                                                        f["series"].create_dataset("area", data=np.linspace(
                                                            1.0, 0.5, 11).astype(np.float32)))),
        "the mesh hash": edited("mesh", None, mesh_hash="abd"),
        "a field's attribute": edited("attr", lambda f: f["fields/big"].attrs.update(on="mesh/vertices")),
    }
    assert all(value != reference for value in differ.values()), {k: v != reference for k, v in differ.items()}


def test_two_runs_of_one_config_have_one_content_hash_and_the_table_shows_it(tmp_path):
    """The README's comparison: `decrun-table outputs/runs --metrics content_sha256` — the file
    sha256 differ (result.h5 stores its times), the content hashes do not."""
    import subprocess
    import sys

    from cli_processes import decrun as run_decrun

    for name in ("a", "b"):
        proc = run_decrun("mesh.subdiv=2", "figures=false", f"hydra.run.dir=outputs/runs/{name}", cwd=tmp_path)
        assert proc.returncode == 0, proc.stderr
    records = [json.loads((tmp_path / "outputs" / "runs" / n / "metrics.json").read_text())["result_h5"]
               for n in ("a", "b")]
    assert records[0]["sha256"] != records[1]["sha256"]  # created, finished, timings
    assert records[0]["content_sha256"] == records[1]["content_sha256"]
    table = subprocess.run([sys.executable, "-c", "import sys; from decrun.runner.command.table import table_main; "
                            "sys.exit(table_main(['outputs/runs', '--metrics', 'content_sha256']))"],
                           cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert table.returncode == 0, table.stderr
    rows = [line for line in table.stdout.splitlines() if line.startswith(("| a ", "| b "))]
    assert len(rows) == 2 and all(records[0]["content_sha256"] in row for row in rows), table.stdout
