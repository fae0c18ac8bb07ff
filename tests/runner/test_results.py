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
