"""The persisted identities keep their values (decrun.core.digest's table): the mesh hash and
mesh cache key, the sweep config hash, a checkpoint's state sha256, a result's file record and
content hash, the tracking fingerprint. Each expected value was computed on these inputs by the
code before the digest module existed: a result file, cache entry, manifest or checkpoint
written then is still recognised now."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
from omegaconf import OmegaConf

from decrun.runner.mesh.cache import _entry, content_hash
from decrun.runner.results import checkpoint
from decrun.runner.results.checked import file_record
from decrun.runner.results.provenance import FORMAT, content_sha256
from decrun.runner.sweep.manifest import config_hash
from decrun.runner.tracking import RunRecord

EXPECTED = {
    "checkpoint": "63978e58b5b855bc61d88fc2656b2f638f26d61b336028974c07160736403f55",
    "config": "0126a5e9b7b1d9be",
    "config_blocks": "0126a5e9b7b1d9be",
    "content": "d6399ec72250a0c3d171f0ef7123c2d3c990f91a9831e798816b2b8610d2ff1a",
    "file": "7e633140064e2f635fbebb3400bc9cd50838f4d1d726eb6263c86201ede65c6f",
    "mesh": "871d3646bc123994bc4a66432fe5b09b47076250bc80aad78d780daf1771cf01",
    "mesh_cache_entry": "fa6b40a6b25df0a13c603a55bc54f4bf6a378dadd3780db7c5d09808397a6097.npz",
    "tracking": "4bcf13a23e9d06de",
}


def _result_file(path: Path) -> Path:
    """A small result.h5: root attributes (some of them not content), a group with attributes,
    datasets of several dtypes and shapes (a scalar, an empty one)."""
    with h5py.File(path, "w") as f:
        f.attrs.update({"format": FORMAT, "metrics_json": '{"error": 0.25, "solve_seconds": 1.5, "stable": true}',
                        "created": "2026-01-01T00:00:00", "app": "heat", "weights": np.arange(3, dtype=np.float32)})
        fields = f.create_group("fields")
        fields.attrs["unit"] = "m"
        fields.create_dataset("u", data=np.linspace(0.0, 1.0, 7).reshape(7, 1))
        fields.create_dataset("faces", data=np.arange(12, dtype=np.int64).reshape(4, 3))
        fields.create_dataset("empty", data=np.zeros((0, 3)))
        f.create_dataset("t", data=np.float64(0.125))
    return path


def identities(tmp: Path) -> dict[str, str]:
    """Every persisted identity on fixed inputs."""
    vertices = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5]])
    faces = np.array([[0, 1, 2]])
    cfg = OmegaConf.create({"app": {"name": "heat", "dt": 0.01}, "mesh": {"n": 8}, "seed": 3,
                            "hydra": {"run": {"dir": "x"}}})
    state = {"u": np.arange(4.0), "step": 3, "ok": True, "none": None, "inner": {"v": np.ones((2, 2), np.int32)}}
    record = RunRecord(name="job0", dir=tmp, status="ok", params={"app.dt": "0.01"}, metrics={"error": 0.5},
                       series={"energy": (np.arange(3), np.array([1.0, 0.5, 0.25]))}, tags={"app": "heat"})
    result = _result_file(tmp / "result.h5")
    return {
        "mesh": content_hash(vertices, faces),
        "mesh_cache_entry": _entry(tmp, '{"format": 1, "generator": "g", "params": {"n": 3}}').name,
        "config": config_hash(cfg),
        "config_blocks": config_hash(cfg, blocks={}),
        "checkpoint": checkpoint._digest(list(checkpoint._leaves(state))),
        "file": file_record(result)["sha256"],
        "content": content_sha256(result),
        "tracking": record.fingerprint(),
    }


def test_persisted_identities_keep_their_values(tmp_path):
    assert identities(tmp_path) == EXPECTED
