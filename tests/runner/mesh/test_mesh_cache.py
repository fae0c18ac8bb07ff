"""decrun.runner.mesh.cache: the meshes pymeshlab makes come back bit for bit from the cache,
without importing pymeshlab; a bad entry is reported and rebuilt, never used."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from decrun.runner.mesh import cache

from meshes_for_tests import mesh


@pytest.fixture
def cache_dir(tmp_path, monkeypatch) -> Path:
    """A fresh, empty cache directory for the test (``DECRUN_MESH_CACHE``)."""
    directory = tmp_path / "mesh-cache"
    monkeypatch.setenv(cache.CACHE_ENV, str(directory))
    return directory


@pytest.fixture
def no_pymeshlab(monkeypatch):
    """``no_pymeshlab()``: from then on ``import pymeshlab`` fails, so what runs after cannot use it
    (finding its package directory, which imports nothing, still works)."""
    import builtins

    real = builtins.__import__

    def refuse(name, *args, **kwargs):
        if name == "pymeshlab" or name.startswith("pymeshlab."):
            raise ImportError("pymeshlab is blocked in this test")
        return real(name, *args, **kwargs)

    return lambda: monkeypatch.setattr(builtins, "__import__", refuse)


def entries(directory: Path) -> list[Path]:
    return sorted(directory.glob("*.npz"))


def pymeshlab_sphere(subdiv: int, radius: float) -> tuple[np.ndarray, np.ndarray]:
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.create_sphere(radius=radius, subdiv=subdiv)
    return ms.current_mesh().vertex_matrix(), ms.current_mesh().face_matrix()


def test_an_icosphere_comes_back_bit_for_bit_without_pymeshlab(cache_dir, no_pymeshlab, monkeypatch):
    """The first load makes the icosphere with pymeshlab and stores one entry; the second reads it
    with pymeshlab unimportable; both equal pymeshlab's own arrays exactly, vertex order included,
    and so does a load with the cache off."""
    first = mesh(source="icosphere", subdiv=2, radius=1.5)
    assert len(entries(cache_dir)) == 1
    vertices, faces = pymeshlab_sphere(2, 1.5)
    no_pymeshlab()
    second = mesh(source="icosphere", subdiv=2, radius=1.5)
    for m in (first, second):
        assert m.vertices.dtype == np.float64 and m.simplices.dtype == np.int64
        assert np.array_equal(m.vertices, vertices) and np.array_equal(m.simplices, faces)
    assert second.meta == first.meta and second.meta["hash"] == first.meta["hash"]
    monkeypatch.undo()  # pymeshlab importable again, the cache off
    monkeypatch.setenv(cache.CACHE_ENV, "off")
    uncached = mesh(source="icosphere", subdiv=2, radius=1.5)
    assert uncached.meta["hash"] == first.meta["hash"] and len(entries(cache_dir)) == 1


def test_the_key_holds_the_generator_its_parameters_and_pymeshlabs_version(cache_dir, monkeypatch):
    """Other parameters, another generator, or another pymeshlab version: another entry."""
    import importlib.metadata

    mesh(source="icosphere", subdiv=1)
    mesh(source="icosphere", subdiv=1, radius=2.0)
    mesh(source="torus", major_segments=8, minor_segments=5)
    mesh(source="icosphere", subdiv=1)  # read back: no new entry
    assert len(entries(cache_dir)) == 3
    real = importlib.metadata.version
    monkeypatch.setattr(importlib.metadata, "version", lambda name: "0.0-other" if name == "pymeshlab" else real(name))
    mesh(source="icosphere", subdiv=1)
    assert len(entries(cache_dir)) == 4


def corrupt_by_truncation(path: Path) -> None:
    path.write_bytes(path.read_bytes()[:100])


def corrupt_a_vertex(path: Path) -> None:
    """A well-formed entry whose vertices no longer match its recorded hash."""
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    arrays["vertices"][0, 0] += 1e-9
    with open(path, "wb") as out:
        np.savez(out, **arrays)


def corrupt_the_dtype(path: Path) -> None:
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    arrays["faces"] = arrays["faces"].astype(np.int32)
    with open(path, "wb") as out:
        np.savez(out, **arrays)


@pytest.mark.parametrize("corrupt, reason", [(corrupt_by_truncation, "unreadable"),
                                             (corrupt_a_vertex, "mesh hash does not match"),
                                             (corrupt_the_dtype, "faces int32")])
def test_a_corrupt_entry_is_reported_and_rebuilt_never_used(cache_dir, caplog, corrupt, reason):
    """A truncated file, a changed vertex or a wrong dtype: the load logs a warning naming the
    entry and the failed check, makes the mesh again (the same one) and rewrites the entry."""
    good = mesh(source="icosphere", subdiv=1)
    (path,) = entries(cache_dir)
    corrupt(path)
    with caplog.at_level(logging.WARNING, logger="decrun"):
        again = mesh(source="icosphere", subdiv=1)
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and str(path) in warnings[0] and reason in warnings[0], warnings
    assert np.array_equal(again.vertices, good.vertices) and np.array_equal(again.simplices, good.simplices)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="decrun"):
        mesh(source="icosphere", subdiv=1)  # the rewritten entry passes its checks
    assert caplog.records == [] and entries(cache_dir) == [path]


def test_an_entry_for_another_key_is_not_used(cache_dir, caplog):
    """An entry copied under another key's name (its own key's text inside) is reported, not used."""
    small = mesh(source="icosphere", subdiv=0)
    (path,) = entries(cache_dir)
    mesh(source="icosphere", subdiv=1)
    (other,) = [p for p in entries(cache_dir) if p != path]
    other.write_bytes(path.read_bytes())
    with caplog.at_level(logging.WARNING, logger="decrun"):
        again = mesh(source="icosphere", subdiv=1)
    assert len(again.vertices) == 42 and len(small.vertices) == 12
    assert any("key's text differs" in r.getMessage() for r in caplog.records)


def test_an_unwritable_cache_is_reported_and_the_run_goes_on(tmp_path, monkeypatch, caplog):
    """A cache path that cannot be a directory (here: a file): one warning naming the way to turn
    the cache off; the mesh is made all the same."""
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setenv(cache.CACHE_ENV, str(blocker / "meshes"))
    with caplog.at_level(logging.WARNING, logger="decrun"):
        m = mesh(source="icosphere", subdiv=1)
    assert len(m.vertices) == 42
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 1 and "cannot write" in messages[0] and "DECRUN_MESH_CACHE=off" in messages[0]


def test_where_the_cache_lives(monkeypatch, tmp_path):
    """DECRUN_MESH_CACHE, else XDG_CACHE_HOME/decrun/meshes, else ~/.cache/decrun/meshes; off turns it off."""
    monkeypatch.delenv(cache.CACHE_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_dir() == tmp_path / "xdg" / "decrun" / "meshes"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache.cache_dir() == tmp_path / "home" / ".cache" / "decrun" / "meshes"
    for off in ("off", "0", "false", "", "OFF"):
        monkeypatch.setenv(cache.CACHE_ENV, off)
        assert cache.cache_dir() is None


def test_a_sample_is_repaired_once_and_read_back_with_the_same_report(cache_dir, no_pymeshlab):
    """``mesh=sample`` (pymeshlab's repair filters, then clean): the second load reads the repaired
    mesh with pymeshlab unimportable, the same arrays and the same repair counts; the sample's file
    is found without importing pymeshlab too."""
    first = mesh(source="sample", sample="cow")
    assert first.meta["repair"]["vertices_in"] > 0
    no_pymeshlab()
    second = mesh(source="sample", sample="cow")
    assert np.array_equal(second.vertices, first.vertices) and np.array_equal(second.simplices, first.simplices)
    assert second.meta == first.meta


def test_refinement_is_cached_and_a_refused_mesh_is_not(cache_dir, no_pymeshlab):
    """``mesh.refine=loop`` comes back the same without pymeshlab; the refusal of a mesh pymeshlab
    cannot refine stores nothing."""
    first = mesh(source="cube", refine="loop", refine_iterations=2)
    count = len(entries(cache_dir))
    no_pymeshlab()
    second = mesh(source="cube", refine="loop", refine_iterations=2)
    assert np.array_equal(second.vertices, first.vertices) and np.array_equal(second.simplices, first.simplices)
    assert len(first.simplices) == 12 * 16 and len(entries(cache_dir)) == count == 2  # the cube, its refinement


WRITER = """
from meshes_for_tests import mesh
print(mesh(source="icosphere", subdiv=4).meta["hash"])
"""


def test_processes_sharing_a_cache_each_get_the_whole_mesh(cache_dir, tmp_path):
    """Three processes making the same mesh at once into one cache (a sweep's workers, SLURM jobs
    on a shared file system): each gets the same mesh, one whole entry remains, no temporary file."""
    tests = Path(__file__).resolve().parents[2]
    env = {**os.environ, cache.CACHE_ENV: str(cache_dir), "PYTHONPATH": f"{tests}:{os.environ.get('PYTHONPATH', '')}"}
    procs = [subprocess.Popen([sys.executable, "-c", WRITER], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True) for _ in range(3)]
    outs = [p.communicate(timeout=300) for p in procs]
    assert all(p.returncode == 0 for p in procs), [err[-2000:] for _, err in outs]
    assert len({out.strip() for out, _ in outs}) == 1
    assert len(entries(cache_dir)) == 1 and [p.name for p in cache_dir.iterdir()] == [entries(cache_dir)[0].name]
