"""decrun.runner.mesh.cache: the meshes pymeshlab makes come back bit for bit from the cache,
without importing pymeshlab; a bad entry is reported and rebuilt, never used."""

from __future__ import annotations

import json
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


def rewritten(path: Path, **changes) -> None:
    """The entry at ``path`` written again with ``changes`` to its arrays and its hash recomputed:
    a well-formed entry whose hash vouches for what it holds (issue 50, item 12)."""
    with np.load(path) as data:
        arrays = {name: data[name] for name in data.files}
    arrays.update(changes)
    arrays["hash"] = np.array(cache.content_hash(arrays["vertices"], arrays["faces"]))
    with open(path, "wb") as out:
        np.savez(out, **arrays)


def corrupt_a_face_index(path: Path) -> None:
    """A face pointing past the last vertex, the hash recomputed."""
    with np.load(path) as data:
        faces, count = data["faces"].copy(), len(data["vertices"])
    faces[3, 1] = count + 7
    rewritten(path, faces=faces)


def corrupt_a_coordinate_to_nan(path: Path) -> None:
    with np.load(path) as data:
        vertices = data["vertices"].copy()
    vertices[2, 1] = np.nan
    rewritten(path, vertices=vertices)


def corrupt_extra_by_nesting(path: Path) -> None:
    """``extra`` nested 100 000 levels deep (not covered by the hash): json.loads overflows the stack."""
    rewritten(path, extra=np.array("[" * 100_000 + "]" * 100_000))


def corrupt_extra_by_moderate_nesting(path: Path) -> None:
    """``extra`` nested 50 levels: readable, beyond the bound."""
    rewritten(path, extra=np.array('{"a": ' * 50 + "1" + "}" * 50))


def corrupt_into_a_fifo(path: Path) -> None:
    """A FIFO in place of the entry: opening it for reading would block until a writer comes."""
    path.unlink()
    os.mkfifo(path)


@pytest.mark.parametrize("corrupt, reason", [(corrupt_by_truncation, "unreadable"),
                                             (corrupt_a_vertex, "mesh hash does not match"),
                                             (corrupt_the_dtype, "faces int32"),
                                             (corrupt_a_face_index, "a face index is outside 0 … 41"),
                                             (corrupt_a_coordinate_to_nan, "not finite"),
                                             (corrupt_extra_by_nesting, "RecursionError"),
                                             (corrupt_extra_by_moderate_nesting, "nested at most 8 levels"),
                                             (corrupt_into_a_fifo, "not a regular file")])
def test_a_corrupt_entry_is_reported_and_rebuilt_never_used(cache_dir, caplog, corrupt, reason):
    """A truncated file, a changed vertex or a wrong dtype: the load logs a warning naming the
    entry and the failed check, makes the mesh again (the same one) and rewrites the entry."""
    good = mesh(source="icosphere", subdiv=1)
    (path,) = entries(cache_dir)
    corrupt(path)
    with caplog.at_level(logging.WARNING, logger="decrun"):
        again = within(60, path, lambda: mesh(source="icosphere", subdiv=1))
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert len(warnings) == 1 and str(path) in warnings[0] and reason in warnings[0], warnings
    assert np.array_equal(again.vertices, good.vertices) and np.array_equal(again.simplices, good.simplices)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="decrun"):
        mesh(source="icosphere", subdiv=1)  # the rewritten entry passes its checks
    assert caplog.records == [] and entries(cache_dir) == [path]


def within(seconds: float, path: Path, load):
    """``load()``'s value, failing the test when it takes more than ``seconds`` (a read blocked on
    a FIFO at ``path`` is then released by opening the FIFO for writing, so the test ends)."""
    import threading

    outcome: dict = {}
    worker = threading.Thread(target=lambda: outcome.update(value=load()), daemon=True)
    worker.start()
    worker.join(seconds)
    if worker.is_alive():
        if path.exists() and not path.is_file():
            os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
        worker.join(10)
        pytest.fail(f"loading the mesh blocked for more than {seconds} s on {path}")
    assert "value" in outcome, "the load raised (see the thread's traceback above)"
    return outcome["value"]


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


@pytest.mark.parametrize("corrupt, reason", [(corrupt_a_face_index, "a face index is outside"),
                                             (corrupt_extra_by_nesting, "RecursionError"),
                                             (corrupt_into_a_fifo, "not a regular file")],
                         ids=["face", "extra", "fifo"])
def test_the_command_rebuilds_an_invalid_entry_with_a_warning(cache_dir, tmp_path, corrupt, reason):
    """Through the real ``decrun`` (issue 50, items 7 and 12): an entry with an out-of-range face
    under a recomputed hash, a nested ``extra``, or a FIFO in its place is a miss — the run
    warns naming the entry, rebuilds it and finishes — never a failed run or a blocked one."""
    from cli_processes import decrun

    args = ["app=heat", "mesh.subdiv=1", "app.steps=2", "figures=false"]
    first = decrun(*args, "hydra.run.dir=first", cwd=tmp_path, timeout=120)
    assert first.returncode == 0, first.stderr[-2000:]
    (path,) = entries(cache_dir)
    corrupt(path)
    proc = decrun(*args, "hydra.run.dir=second", cwd=tmp_path, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    warnings = [line for line in proc.stderr.splitlines() if "mesh cache" in line]
    assert len(warnings) == 1 and str(path) in warnings[0] and reason in warnings[0], proc.stderr[-2000:]
    assert path.is_file() and json.loads((tmp_path / "second" / "metrics.json").read_text())["status"] == "ok"
