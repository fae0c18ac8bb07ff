"""Issue 24 (items 3, 4): a corrupt result is never called complete, and hostile job files
are one line each naming the file -- in ``decrun-table`` (the other jobs still listed) and
in resume (``hydra.sweeper.resume=true``), never a traceback, a TiB allocation or a read
outside the file. Every damage is done to a copy of one real 3-job sweep."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from decrun.apps.base import Result
from decrun.errors import CorruptFileError
from decrun.runner.command.table import table_main
from decrun.runner.results import read_mesh, read_provenance, read_result, write_result
from decrun.runner.results.checked import RESULT_RECORD
from decrun.runner.results.journal import read_journal
from decrun.runner.sweep.tables import sweep_table

from cli_processes import decrun

SWEEP = ["-m", "app.dt=0.001,0.002,0.003", "mesh.subdiv=2", "app.steps=2", "figures=false"]
DEEP = "[" * 100_000 + "]" * 100_000


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    root = tmp_path_factory.mktemp("made")
    proc = decrun(*SWEEP, "hydra.sweep.dir=s", cwd=root)
    assert proc.returncode == 0, proc.stderr
    return root / "s"


@pytest.fixture
def sweep(made, tmp_path):
    """A fresh copy of the finished sweep (jobs 0, 1, 2 all ok)."""
    return shutil.copytree(made, tmp_path / "s")


def without_record(job) -> None:
    """metrics.json as decrun wrote it before results were recorded (no size / sha256):
    result.h5 is then checked by its content."""
    metrics = json.loads((job / "metrics.json").read_text())
    metrics.pop(RESULT_RECORD, None)
    (job / "metrics.json").write_text(json.dumps(metrics))


def decrun_attributes(job) -> dict:
    with h5py.File(job / "result.h5", "r") as f:
        return dict(f.attrs)


def forged_result(job, build) -> None:
    """Replace the job's result.h5 by a file with decrun's root attributes whose /fields
    ``build(group)`` fills (a forged file), and drop metrics.json's record of it."""
    attrs = decrun_attributes(job)
    (job / "result.h5").unlink()
    with h5py.File(job / "result.h5", "w") as f:
        f.attrs.update(attrs)
        build(f.create_group("fields"))
        f.create_group("series")
    without_record(job)


def truncate(job):
    path = job / "result.h5"
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def alter(job):  # same size, one byte changed in the middle
    path = job / "result.h5"
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))


def no_decrun_attributes(job):
    (job / "result.h5").unlink()
    with h5py.File(job / "result.h5", "w") as f:
        f["x"] = np.arange(3)
    without_record(job)


def huge_shape(job):  # declares 2.4 TB, stores nothing
    forged_result(job, lambda g: g.create_dataset("u", shape=(10 ** 11, 3), dtype="f8", chunks=(1024, 3)))


def external_storage(job):  # raw data in a file outside the sweep
    outside = job.parent.parent / "outside.bin"
    outside.write_bytes(np.arange(8, dtype="f8").tobytes())
    forged_result(job, lambda g: g.create_dataset("u", shape=(8,), dtype="f8", external=[(str(outside), 0, 64)]))


def virtual_dataset(job):
    outside = job.parent.parent / "outside.h5"
    with h5py.File(outside, "w") as f:
        f["data"] = np.arange(8.0)
    layout = h5py.VirtualLayout(shape=(8,), dtype="f8")
    layout[:] = h5py.VirtualSource(str(outside), "data", shape=(8,))
    forged_result(job, lambda g: g.create_virtual_dataset("u", layout))


def external_link(job):
    outside = job.parent.parent / "outside.h5"
    with h5py.File(outside, "w") as f:
        f["data"] = np.arange(8.0)
    forged_result(job, lambda g: g.__setitem__("u", h5py.ExternalLink(str(outside), "data")))


def metrics_array(job):
    (job / "metrics.json").write_text("[1, 2, 3]")


def metrics_deep(job):
    (job / "metrics.json").write_text('{"status": "ok", "x": ' + DEEP + "}")


def journal_claims_a_terabyte(job):  # killed while recording, its header forged
    for name in ("metrics.json", "result.h5"):
        (job / name).unlink()
    (job / "result.h5.partial").write_bytes(b"DECRUNJ1" + (10 ** 12).to_bytes(8, "little") + b"{}")


#: damage to job 1 → what its row's error must say (besides the file's name)
JOB_DAMAGE = {
    "truncated result.h5": (truncate, "result.h5", "truncated"),
    "altered result.h5": (alter, "result.h5", "sha256"),
    "result.h5 without decrun attributes": (no_decrun_attributes, "result.h5", "not a decrun result"),
    "dataset claiming (10^11, 3)": (huge_shape, "result.h5", "claims shape (100000000000, 3)"),
    "external storage": (external_storage, "result.h5", "keeps its data in another file"),
    "virtual dataset": (virtual_dataset, "result.h5", "virtual dataset"),
    "external link": (external_link, "result.h5", "a link to another file"),
    "metrics.json an array": (metrics_array, "metrics.json", "not an object of metrics"),
    "metrics.json 100k deep": (metrics_deep, "metrics.json", "nested too deeply"),
    "journal header claiming 10^12 bytes": (journal_claims_a_terabyte, "result.h5.partial", "claims 1000000000000"),
}


def one_line_per_corrupt_job(err: str) -> list[str]:
    lines = err.strip().splitlines()
    assert "Traceback" not in err and all(line.startswith("decrun-table: job ") for line in lines), err
    return lines


@pytest.mark.parametrize("damage, file, says", JOB_DAMAGE.values(), ids=JOB_DAMAGE.keys())
def test_a_damaged_job_is_a_corrupt_row_naming_its_file_and_the_others_are_listed(sweep, capsys, damage, file, says):
    assert table_main([str(sweep)]) == 0  # the undamaged sweep is ok (its results verify)
    capsys.readouterr()
    damage(sweep / "1")
    assert table_main([str(sweep), "--csv"]) == 1
    out, err = capsys.readouterr()
    [line] = one_line_per_corrupt_job(err)
    assert line.startswith("decrun-table: job 1 corrupt: ") and str(sweep / "1" / file) in line and says in line, line
    table = sweep_table(sweep)
    assert list(table["status"]) == ["ok", "corrupt", "ok"] and list(table["app.dt"]) == [0.001, 0.002, 0.003]
    assert out.count("\n") == 4  # header + the three jobs


def test_the_table_of_a_damaged_sweep_through_the_console_script(sweep):
    truncate(sweep / "0")
    table = shutil.which("decrun-table", path=os.path.dirname(sys.executable))
    proc = subprocess.run([table, str(sweep)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1
    assert proc.stderr.strip() == (f"decrun-table: job 0 corrupt: {sweep / '0' / 'result.h5'}: "
                                   f"{(sweep / '0' / 'result.h5').stat().st_size} bytes, metrics.json records "
                                   f"{json.loads((sweep / '0' / 'metrics.json').read_text())[RESULT_RECORD]['bytes']} "
                                   "(truncated or altered)")
    assert "| 0 | 0.001 | corrupt |" in proc.stdout and "| 2 | 0.003 | ok |" in proc.stdout


MANIFEST_DAMAGE = {
    "missing fields": (lambda m: json.dumps({**m, "jobs": [{"job": "0"}] + m["jobs"][1:]}), "lacks its job"),
    "a JSON array": (lambda m: json.dumps(m["jobs"]), "not a decrun sweep manifest"),
    "100k-deep nesting": (lambda m: DEEP, "nested too deeply"),
}


@pytest.mark.parametrize("damage, says", MANIFEST_DAMAGE.values(), ids=MANIFEST_DAMAGE.keys())
def test_a_hostile_manifest_is_one_line_the_table_lists_the_job_directories_and_resume_refuses(
        sweep, capsys, damage, says):
    path = sweep / "manifest.json"
    path.write_text(damage(json.loads(path.read_text())))
    assert table_main([str(sweep)]) == 1
    out, err = capsys.readouterr()
    [line] = one_line_per_corrupt_job(err)
    assert line.startswith(f"decrun-table: job manifest.json corrupt: {path}: ") and says in line, line
    table = sweep_table(sweep)
    assert list(table["job"]) == ["manifest.json", 0, 1, 2]
    assert list(table["status"]) == ["corrupt", "ok", "ok", "ok"]
    assert list(table["app.dt"].iloc[1:]) == [0.001, 0.002, 0.003]  # from each job's overrides.yaml

    proc = decrun(*SWEEP, f"hydra.sweep.dir={sweep}", "hydra.sweeper.resume=true", cwd=sweep.parent)
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()], proc.stderr  # one line, no traceback
    assert proc.stderr.startswith(f"error: hydra.sweeper.resume=true: {path}: ") and says in proc.stderr


def test_overrides_yaml_with_a_python_tag_is_refused_never_built(sweep, capsys):
    (sweep / "manifest.json").unlink()  # a sweep of another sweeper: the table reads each overrides.yaml
    pwned = sweep.parent / "pwned"
    (sweep / "1" / ".hydra" / "overrides.yaml").write_text(f"- !!python/object/apply:os.system ['touch {pwned}']\n")
    assert table_main([str(sweep)]) == 1
    _, err = capsys.readouterr()
    [line] = one_line_per_corrupt_job(err)
    overrides = sweep / "1" / ".hydra" / "overrides.yaml"
    assert line.startswith(f"decrun-table: job 1 corrupt: {overrides}: not YAML decrun reads"), line
    assert not pwned.exists()
    assert list(sweep_table(sweep)["status"]) == ["ok", "corrupt", "ok"]


RESUMED = {k: JOB_DAMAGE[k][0] for k in ("truncated result.h5", "metrics.json an array",
                                         "journal header claiming 10^12 bytes", "dataset claiming (10^11, 3)")}


@pytest.mark.parametrize("damage", RESUMED.values(), ids=RESUMED.keys())
def test_resume_reruns_a_corrupt_job_and_keeps_the_others(sweep, damage):
    damage(sweep / "1")
    kept = (sweep / "0" / "metrics.json").stat().st_mtime_ns
    proc = decrun(*SWEEP, f"hydra.sweep.dir={sweep}", "hydra.sweeper.resume=true", cwd=sweep.parent)
    assert proc.returncode == 0, proc.stderr
    assert "2 of 3 jobs are ok; running 1" in proc.stderr and "Traceback" not in proc.stderr
    assert (sweep / "0" / "metrics.json").stat().st_mtime_ns == kept
    assert list(sweep_table(sweep)["status"]) == ["ok", "ok", "ok"]
    assert read_result(sweep / "1" / "result.h5").complete


@pytest.mark.parametrize("damage, says", [(no_decrun_attributes, "not a decrun result"),
                                          (huge_shape, "claims shape"), (external_storage, "another file"),
                                          (virtual_dataset, "virtual dataset"), (external_link, "link to another")],
                         ids=["no attributes", "huge shape", "external storage", "virtual", "external link"])
def test_the_result_readers_refuse_a_hostile_result_h5_naming_it(sweep, damage, says):
    damage(sweep / "1")
    path = sweep / "1" / "result.h5"
    started = time.perf_counter()
    with pytest.raises(CorruptFileError, match=says) as caught:
        read_result(path)
    assert str(caught.value).startswith(f"{path}: ") and time.perf_counter() - started < 5
    if damage is no_decrun_attributes:
        with pytest.raises(CorruptFileError, match="not a decrun result"):
            read_provenance(path)


def test_read_mesh_refuses_a_mesh_dataset_with_external_storage(sweep):
    path = sweep / "1" / "result.h5"
    outside = sweep.parent / "outside.bin"
    outside.write_bytes(np.zeros(9).tobytes())
    with h5py.File(path, "a") as f:
        del f["mesh/vertices"]
        f["mesh"].create_dataset("vertices", shape=(3, 3), dtype="f8", external=[(str(outside), 0, 72)])
    with pytest.raises(CorruptFileError, match=f"{path}: dataset /mesh/vertices keeps its data in another file"):
        read_mesh(path)


def test_a_forged_journal_header_is_refused_before_anything_is_allocated(tmp_path):
    path = tmp_path / "result.h5.partial"
    path.write_bytes(b"DECRUNJ1" + (10 ** 12).to_bytes(8, "little") + b"{}")
    with pytest.raises(CorruptFileError, match="claims 1000000000000 bytes, the file has 18"):
        read_journal(path)
    header = json.dumps({"format": "decrun-journal-1", "record_size": 24, "data_offset": 0, "columns": [],
                         "blobs": {"mesh/vertices": {"dtype": "<f8", "shape": [10 ** 11, 3], "offset": 0}},
                         "attrs": {}}).encode()
    path.write_bytes(b"DECRUNJ1" + len(header).to_bytes(8, "little") + header)
    with pytest.raises(CorruptFileError, match="blob 'mesh/vertices' .* lies outside the file"):
        read_journal(path)
    path.write_bytes(b"DECRUNJ1" + (7).to_bytes(8, "little") + b'"x": 1}')
    with pytest.raises(CorruptFileError, match="journal header: not valid JSON"):
        read_result(tmp_path / "result.h5")


def test_a_highly_compressed_result_is_not_taken_for_a_forged_one(tmp_path):
    """Zeros compress ~1000:1 with gzip, below the refused ratio (deflate's limit is 1032:1)."""
    path = write_result(tmp_path / "result.h5", Result(fields={"u": np.zeros((400_000, 3))}, metrics={"e": 1.0}),
                        vertices=np.eye(3), simplices=np.array([[0, 1, 2]]))
    assert path.stat().st_size < 100_000
    assert read_result(path).fields["u"].shape == (400_000, 3)


def test_a_failed_rerun_sets_the_earlier_result_aside(tmp_path):
    args = ["mesh.subdiv=2", "app.steps=2", "figures=false", "hydra.run.dir=r"]
    assert decrun(*args, cwd=tmp_path).returncode == 0
    run = tmp_path / "r"
    earlier = (run / "result.h5").read_bytes()
    failed = decrun(*args, "app.dt=-1", cwd=tmp_path)
    assert failed.returncode == 1
    assert f"the earlier run's result.h5 is now {run / 'result.h5.stale'}" in failed.stderr, failed.stderr
    assert not (run / "result.h5").exists() and (run / "result.h5.stale").read_bytes() == earlier
    assert json.loads((run / "metrics.json").read_text())["status"] == "failed"


def test_a_run_chained_on_a_hostile_result_is_one_line_naming_the_key(sweep):
    external_storage(sweep / "1")
    proc = decrun("mesh=result", f"mesh.path={sweep / '1'}", "app.steps=2", "figures=false", "hydra.run.dir=r",
                  cwd=sweep.parent)
    assert proc.returncode == 1 and proc.stderr.strip().splitlines() == [proc.stderr.strip()], proc.stderr
    assert proc.stderr.startswith(f"error: mesh.path={str(sweep / '1')!r}: cannot read it as a decrun result")
    assert "dataset /fields/u keeps its data in another file" in proc.stderr


def test_an_override_hydra_cannot_parse_is_a_corrupt_row_naming_the_file(sweep, capsys):
    path = sweep / "manifest.json"
    manifest = json.loads(path.read_text())
    manifest["jobs"][1]["overrides"] = ["app.dt=[1,"]
    path.write_text(json.dumps(manifest))
    assert table_main([str(sweep)]) == 1
    [line] = one_line_per_corrupt_job(capsys.readouterr().err)
    assert line.startswith(f"decrun-table: job manifest.json corrupt: {path}: an override Hydra cannot parse"), line
    (sweep / "manifest.json").unlink()
    (sweep / "2" / ".hydra" / "overrides.yaml").write_text("- app.dt=[1,\n")
    assert table_main([str(sweep)]) == 1
    [line] = one_line_per_corrupt_job(capsys.readouterr().err)
    assert line.startswith(f"decrun-table: job 2 corrupt: {sweep / '2' / '.hydra' / 'overrides.yaml'}: an override")
