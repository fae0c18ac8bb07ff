"""A corpus of bad input and faults (issue 11, item 1): each is a minimal input made here
and must end as one clear line naming the key or file and the cause — exit 1, no
traceback, no result.h5 unless steps were recorded. Mesh-file contents have their own
corpus (tests/runner/mesh/test_mesh_files.py).

The in-process corpus runs the runner's own path (compose → validate → load → app) without
the cost of a process per case; the CLI corpus runs the real ``decrun`` where the command
line matters (Hydra, output directories, signals, disks).
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
import scipy.sparse as sp

from decrun.errors import DecrunError, SolverError
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import run_experiment
from decrun.runner.mesh import MAX_TRIANGLES

OCTAHEDRON = ("v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
              "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n")
FIN = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 0 -1 0\nf 1 2 3\nf 1 2 4\nf 1 2 5\n"
TETRA_VTK = ("# vtk DataFile Version 2.0\ntet\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 5 float\n0 0 0\n1 0 0\n"
             "0 1 0\n0 0 1\n1 1 1\nCELLS 2 10\n4 0 1 2 3\n4 1 2 3 4\nCELL_TYPES 2\n10\n10\n")


def tetrahedron_obj(scale: float) -> str:
    return (f"v 0 0 0\nv {scale} 0 0\nv 0 {scale} 0\nv 0 0 {scale}\n"
            "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")


def make_files(directory: Path, files: dict) -> None:
    for name, content in files.items():
        if callable(content):
            content(directory / name)
        elif isinstance(content, bytes):
            (directory / name).write_bytes(content)
        else:
            (directory / name).write_text(content)


def not_hdf5(path: Path) -> None:
    path.write_bytes(b"this is not HDF5\n" * 10)


def foreign_hdf5(path: Path) -> None:
    with h5py.File(path, "w") as f:
        f["x"] = np.arange(3)


def truncated_result(path: Path) -> None:
    """The first 3000 bytes of a real result.h5 (a copy cut short)."""
    from decrun.apps.base import Result
    from decrun.runner.results import write_result

    whole = path.with_name("whole.h5")
    write_result(whole, Result(fields={"omega": np.arange(5000.0)}), vertices=np.zeros((3, 3)),
                 simplices=np.array([[0, 1, 2]]))
    path.write_bytes(whole.read_bytes()[:3000])


# ----------------------------------------------------------------------------------
# in-process corpus: compose → validate → load → app, as `decrun` runs it
# ----------------------------------------------------------------------------------

VF = ["app=vector_field", "figures=false"]
PLANAR = ["mesh=planar", "app=hodge", "app.harmonic_dimension=false"]

CASES = {
    # NaN, inf and huge numbers anywhere in the options
    "nan-radius": (["mesh.radius=nan"], {}, ["mesh.radius", "nan"]),
    "huge-radius": (["mesh.radius=1e300"], {}, ["mesh.radius: 1e+300 is beyond ±1e+150"]),
    "nan-hole-ball": (["mesh.hole_balls=[[0,0,1,nan]]"], {}, ["mesh.hole_balls[0][3]: must be a finite number, got nan"]),
    "inf-hole-box": (["mesh.hole_boxes=[[0,0,0,inf,1,1]]"], {}, ["mesh.hole_boxes[0][3]: must be a finite number"]),
    "inf-noise": (["mesh.noise=inf"], {}, ["mesh.noise: must be a finite number, got inf"]),
    "inf-blowup": (["app.blowup_factor=inf"], {}, ["app.blowup_factor: must be a finite number, got inf"]),
    "nan-string-point": ([*VF, "app.sources=[{point:['nan',0,1]}]"], {}, ["app.sources[0].point[0]: must be a finite"]),
    "inf-vortex-point": ([*VF, "app.vortices=[{point:[0,0,inf]}]"], {}, ["app.vortices[0].point[2]: must be a finite"]),
    "nan-planar-outer": ([*PLANAR, "mesh.outer=[[0,0],[1,0],[nan,1]]"], {}, ["mesh.outer[2][0]: must be a finite"]),
    # points far from the surface are reported, not snapped
    "far-source": ([*VF, "app.sources=[{point:[1e6,1e6,1e6]}]"], {},
                   ["app.sources[0].point", "lies 1.73e+06 from the surface", "app.point_tolerance="]),
    "far-vortex": ([*VF, "app.vortices=[{point:[0,0,5]}]"], {}, ["app.vortices[0].point", "from the surface"]),
    "far-stroke": ([*VF, "app.stroke_magnitude=fixed", "app.strokes=[{points:[[0,0,1],[0,0,3]]}]"], {},
                   ["app.strokes[0].points[1]", "from the surface"]),
    "2d-point-on-sphere": ([*VF, "app.sources=[{point:[0,1]}]"], {}, ["app.sources[0].point: a point needs 3 coordinates"]),
    "negative-tolerance": ([*VF, "app.point_tolerance=-1"], {}, ["app.point_tolerance: must be >= 0"]),
    # huge and tiny coordinates
    "huge-file-coordinates": (["mesh=file", "mesh.path=huge.obj"], {"huge.obj": tetrahedron_obj(1e300)},
                              ["mesh.path='huge.obj'", "beyond ±1e+150"]),
    "big-file-mesh": (["mesh=file", "mesh.path=big.obj"], {"big.obj": tetrahedron_obj(1e100)},
                      ["mesh.path='big.obj'", "bounding-box diagonal 1.73e+100", "mesh.normalize=true"]),
    "tiny-file-mesh": (["mesh=file", "mesh.path=small.obj"], {"small.obj": tetrahedron_obj(1e-40)},
                       ["mesh.path='small.obj'", "bounding-box diagonal 1.73e-40", "mesh.normalize=true"]),
    "tiny-generated-mesh": (["mesh.radius=1e-35"], {}, ["mesh icosphere3", "outside decrun's range"]),
    # issue 34.6: no rescaling can fix a mesh without extent, so none is offered
    "coincident-file-mesh": (["mesh=file", "mesh.path=point.obj"], {"point.obj": "v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n"},
                             ["mesh.path='point.obj': all 3 vertices coincide"]),
    "negative-relative-index": (["mesh=file", "mesh.path=neg.obj"], {"neg.obj": "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n"},
                                ["mesh.path='neg.obj'", "line 4", "-4 (relative)"]),
    # planar domains that triangle would crash on or silently misread
    "bowtie": ([*PLANAR, "mesh.holes=[]", "mesh.outer=[[0,0],[2,2],[2,0],[0,1]]"], {},
               ["mesh.outer: segment 2", "crosses", "simple"]),
    "repeated-point": ([*PLANAR, "mesh.holes=[]", "mesh.outer=[[0,0],[1,0],[1,0],[1,1],[0,1]]"], {},
                       ["mesh.outer[2]: the point [1.0, 0.0] is given twice"]),
    "hole-outside": ([*PLANAR, "mesh.holes=[[[2,2],[3,2],[3,3]]]"], {}, ["mesh.holes[0]: the hole lies outside mesh.outer"]),
    "hole-crossing-outer": ([*PLANAR, "mesh.holes=[[[0.5,0.5],[1.5,0.5],[0.5,0.7]]]"], {},
                            ["mesh.holes[0]: segment 0", "mesh.outer segment 1", "must not touch"]),
    "nested-holes": ([*PLANAR, "mesh.holes=[[[0.2,0.2],[0.8,0.2],[0.8,0.8]],[[0.5,0.3],[0.7,0.3],[0.7,0.5]]]"], {},
                     ["mesh.holes[1]: the hole lies inside mesh.holes[0]"]),
    "planar-too-fine": ([*PLANAR, "mesh.max_area=1e-12"], {}, ["mesh.max_area", "triangles", "mesh.max_area="]),
    # post steps that would crash native code or exhaust memory
    "grid-too-fine": (["mesh=grid", "mesh.nx=100000", "mesh.ny=100000"], {}, ["mesh.nx: would make about 2e+10 triangles"]),
    "torus-too-fine": (["mesh=torus", "mesh.major_segments=100000", "mesh.minor_segments=1000"], {},
                       ["mesh.major_segments: would make about 2e+08 triangles"]),
    "refine-too-many": (["mesh=grid", "mesh.refine=loop", "mesh.refine_iterations=10"], {},
                        ["mesh.refine_iterations", "mesh.refine_iterations=6"]),
    "remesh-too-fine": (["mesh=file", "mesh.path=octa.obj", "mesh.refine=isotropic", "mesh.refine_target_edge=1e-5"],
                        {"octa.obj": OCTAHEDRON}, ["mesh.refine_target_edge", "mesh.refine_target_edge="]),
    "refine-tetrahedra": (["mesh=file", "mesh.path=tet.vtk", "mesh.refine=loop", "app=hodge"], {"tet.vtk": TETRA_VTK},
                          ["mesh.refine=loop: needs a triangle surface", "mesh.refine=none"]),
    "noise-tetrahedra": (["mesh=file", "mesh.path=tet.vtk", "mesh.noise=0.1", "app=hodge"], {"tet.vtk": TETRA_VTK},
                         ["mesh.noise: needs a triangle surface", "mesh.noise=0"]),
    "refine-non-manifold": (["mesh=file", "mesh.path=fin.obj", "mesh.refine=loop"], {"fin.obj": FIN},
                            ["mesh.refine=loop: pymeshlab refused the mesh", "manifold"]),
    # a previous run's result that is not one
    "hodge-not-hdf5": (["app=hodge", "app.input=result", "app.input_path=bad.h5"], {"bad.h5": not_hdf5},
                       ["app.input_path='bad.h5'", "file signature not found"]),
    "hodge-truncated": (["app=hodge", "app.input=result", "app.input_path=cut.h5"], {"cut.h5": truncated_result},
                        ["app.input_path='cut.h5'", "truncated file"]),
    "hodge-foreign-hdf5": (["app=hodge", "app.input=result", "app.input_path=other.h5"], {"other.h5": foreign_hdf5},
                           ["app.input_path='other.h5'", "not a decrun result.h5"]),
    # root keys
    "unknown-root-key": (["+foo=1"], {}, ["foo: unknown root key", "drop +foo=..."]),
    # an error raised by the core (which knows no config keys) is prefixed with the key
    "core-error-names-the-mesh": ([*PLANAR, "mesh.holes=[]", "mesh.max_area=0.5", "operator=circumcentric"], {},
                                  ["mesh planar0h: Hodge decomposition of 1-forms needs an invertible ⋆_1"]),
}


def run_in_process(overrides, directory):
    cwd = os.getcwd()
    os.chdir(directory)
    try:
        return run_experiment(compose_config(overrides))
    finally:
        os.chdir(cwd)


@pytest.mark.parametrize("overrides, files, words", CASES.values(), ids=CASES.keys())
def test_bad_input_is_one_clear_error(tmp_path, overrides, files, words):
    make_files(tmp_path, files)
    with pytest.raises(DecrunError) as info:
        run_in_process(overrides, tmp_path)
    message = str(info.value)
    assert "\n" not in message, message
    for word in words:
        assert word in message, message
    assert not list(tmp_path.rglob("result.h5*"))


def hint(message: str, key: str) -> str:
    """The value of the override ``key=<value>`` the message proposes (its last mention)."""
    return re.findall(rf"{re.escape(key)}=([^\s;),]+)", message)[-1]


def test_the_proposed_overrides_fix_it(tmp_path):
    """The override each message names is the fix: the far point is accepted with the
    proposed tolerance, the huge file with mesh.normalize=true, and the proposed mesh
    sizes fall just within decrun's triangle limit."""
    with pytest.raises(DecrunError) as info:
        run_in_process([*VF, "app.vortices=[{point:[0,0,1.5]}]"], tmp_path)
    tolerance = hint(str(info.value), "app.point_tolerance")
    result = run_in_process([*VF, "app.vortices=[{point:[0,0,1.5]}]", f"app.point_tolerance={tolerance}"], tmp_path).result
    assert result.metrics["vortices"] == 1
    (tmp_path / "big.obj").write_text(tetrahedron_obj(1e100))
    done = run_in_process(["mesh=file", "mesh.path=big.obj", "mesh.normalize=true", "app.rescale=none"], tmp_path)
    result, mesh = done.result, done.mesh
    # no overflow (no step blew up); unrescaled, the 4-vertex tetrahedron flows flat, which the
    # degeneration check reports (stable: false, unstable_reason: degenerate: ...)
    assert "diverged_at_step" not in result.metrics and np.isclose(np.linalg.norm(np.ptp(mesh.vertices, axis=0)), 1.0)
    # 15×15 grid: 450 triangles; 450·4^6 fits, 450·4^7 does not
    with pytest.raises(DecrunError) as info:
        run_in_process(["mesh=grid", "mesh.refine=loop", "mesh.refine_iterations=10"], tmp_path)
    k = int(hint(str(info.value), "mesh.refine_iterations"))
    assert 450 * 4**k <= MAX_TRIANGLES < 450 * 4 ** (k + 1)
    with pytest.raises(DecrunError) as info:
        run_in_process([*PLANAR, "mesh.holes=[]", "mesh.max_area=1e-12"], tmp_path)
    area = float(hint(str(info.value), "mesh.max_area"))
    assert 0.8 * MAX_TRIANGLES < 1.6 / area <= MAX_TRIANGLES  # unit square, 1.6 triangles per max_area


def test_max_area_in_scientific_notation_is_used_as_given(tmp_path):
    """triangle read ``a5e-05`` as area 5 then the switch ``e``: 2 triangles for a unit square."""
    from decrun.runner.job.plugins import option

    mesh = option("mesh", "planar", holes=[], max_area=5e-05).load()
    assert 1.4 / 5e-05 < len(mesh.simplices) < 1.8 / 5e-05
    assert mesh.meta["mean_edge_length"] < 0.02


def test_smoothing_a_regular_octahedron_has_the_exact_critical_step(tmp_path):
    """The ones vector is the kernel of S and, with uniform ⋆0, an eigenvector: ARPACK
    started from it stopped with "starting vector is zero". Regular octahedron (edge √2):
    cot weights 1/√3, graph Laplacian of K_{2,2,2} has λ_max = 6, ⋆0 = 2/√3, so
    λ_max(⋆0⁻¹S) = 3 and dt_crit = 2/3."""
    (tmp_path / "octa.obj").write_text(OCTAHEDRON)
    for operator in ("mixed_area", "whitney"):
        result = run_in_process(["mesh=file", "mesh.path=octa.obj", f"operator={operator}"], tmp_path).result
        assert result.metrics["stable"]
        if operator == "mixed_area":
            assert abs(result.metrics["dt_critical_explicit"] - 2 / 3) < 1e-12


def test_sparse_and_dense_largest_eigenvalues_agree():
    """The ARPACK path (seeded start vector) and the dense path give the same λ_max."""
    import decrun.methods.mean_curvature_flow as mcf
    from decrun.core.dec import DEC

    from meshes_for_tests import complex_of

    dec = DEC(complex_of("icosphere", subdiv=2), star="mixed_area")
    S, M = dec.laplacian_symmetric(0), dec.star_diagonal(0)
    sparse = mcf.largest_eigenvalue(S, M)
    import scipy.linalg as la

    dense = la.eigh(S.toarray(), np.diag(M), eigvals_only=True)[-1]
    assert S.shape[0] > mcf.DENSE_EIGEN_MAX and abs(sparse - dense) < 1e-8 * dense


def test_solvers_refuse_non_finite_matrices():
    from decrun.core.solvers import solver_factory

    A = sp.identity(4, format="csr") * 2.0
    A[1, 1] = np.nan
    for name in ("direct", "cg"):
        with pytest.raises(SolverError, match=r"4, 4\) matrix has 1 non-finite entries"):
            solver_factory(name)().factorize(A)


def test_an_os_error_message_names_the_path_and_the_override(tmp_path):
    from decrun.runner.job.failures import os_error_message

    forbidden = PermissionError(13, "Permission denied", str(tmp_path / "runs"))
    assert os_error_message(forbidden) == (f"cannot write {tmp_path / 'runs'}: Permission denied; choose another output "
                                           "directory with hydra.run.dir=DIR (hydra.sweep.dir=DIR with -m)")
    (tmp_path / "file").write_text("")
    in_the_way = NotADirectoryError(20, "Not a directory", str(tmp_path / "file" / "run"))
    assert os_error_message(in_the_way).startswith(f"cannot write {tmp_path / 'file'}: a file is in the way")


# ----------------------------------------------------------------------------------
# the real command line
# ----------------------------------------------------------------------------------


def decrun(*args, cwd, timeout=240):
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")}
    return subprocess.run([sys.executable, "-m", "decrun", *args, "figures=false"], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


def assert_one_clear_line(proc, *words, code=1):
    assert proc.returncode == code, proc.stderr[-3000:]
    text = proc.stdout + proc.stderr
    assert "Traceback" not in text and "Error executing job" not in text, text[-3000:]
    lines = [line for line in proc.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, proc.stderr
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


slow = pytest.mark.slow  # the same cause is checked in process above; here the CLI path once more

CLI_CASES = {
    "unknown-root-key": (["+foo=1"], {}, ["error: foo: unknown root key"]),
    "nan-override": pytest.param(["mesh.hole_balls=[[0,0,1,nan]]"], {},
                                 ["error: mesh.hole_balls[0][3]: must be a finite number"], marks=slow),
    "far-point": pytest.param(["app=vector_field", "app.sources=[{point:[1e6,1e6,1e6]}]"], {},
                              ["error: app.sources[0].point"], marks=slow),
    "corrupt-result": pytest.param(["app=hodge", "app.input=result", "app.input_path=bad.h5"], {"bad.h5": not_hdf5},
                                   ["error: app.input_path='bad.h5'"], marks=slow),
    "run-dir-is-a-file": (["hydra.run.dir=taken"], {"taken": ""}, ["error: cannot write taken: a file is in the way",
                                                                    "hydra.run.dir=DIR"]),
    "file-above-run-dir": pytest.param(["hydra.run.dir=taken/run"], {"taken": ""},
                                       ["error: cannot write taken: a file is in the way"], marks=slow),
    "sweep-dir-is-a-file": (["-m", "hydra.sweep.dir=taken", "app.steps=1,2"], {"taken": ""},
                            ["error: cannot write taken: a file is in the way"]),
}


@pytest.mark.parametrize("args, files, words", list(CLI_CASES.values()),
                         ids=CLI_CASES.keys())
def test_the_command_line_says_one_line(tmp_path, args, files, words):
    make_files(tmp_path, files)
    proc = decrun(*args, cwd=tmp_path)
    assert_one_clear_line(proc, *words)
    assert not list(tmp_path.rglob("result.h5*")) and not list(tmp_path.rglob("*.tmp-*"))
    for metrics in tmp_path.rglob("metrics.json"):  # where a run directory exists, it says so
        assert json.loads(metrics.read_text())["status"] == "failed"


@pytest.mark.slow
def test_a_regular_octahedron_smooths_through_the_command_line(tmp_path):
    (tmp_path / "octa.obj").write_text(OCTAHEDRON)
    proc = decrun("mesh=file", "mesh.path=octa.obj", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (metrics,) = tmp_path.rglob("metrics.json")
    assert json.loads(metrics.read_text())["dt_critical_explicit"] == pytest.approx(2 / 3, rel=1e-12)




def test_a_read_only_output_directory_is_one_line(tmp_path, tmpfs):
    read_only = tmpfs("1m", read_only=True)
    proc = decrun(f"hydra.run.dir={read_only}/run", cwd=tmp_path)
    assert_one_clear_line(proc, f"error: cannot write {read_only}/run: Read-only file system", "hydra.run.dir=DIR")
    proc = decrun("-m", f"hydra.sweep.dir={read_only}/sweep", "app.steps=1,2", cwd=tmp_path)
    assert_one_clear_line(proc, f"error: cannot write {read_only}/sweep: Read-only file system")


@pytest.mark.parametrize("size, words", [
    ("300k", ["result.h5.partial: No space left on device; no step was recorded"]),
    ("1500k", ["result.h5: No space left on device", "the 4 recorded steps are kept in"]),
], ids=["while-recording", "writing-result.h5"])
def test_a_full_disk_is_one_line_and_a_failed_status(tmp_path, tmpfs, size, words):
    disk = tmpfs(size)
    proc = decrun(f"hydra.run.dir={disk}/run", "mesh.subdiv=5", "app.steps=3", cwd=tmp_path)
    line = assert_one_clear_line(proc, "error: cannot write", *words)
    metrics = json.loads((disk / "run" / "metrics.json").read_text())
    assert metrics["status"] == "failed" and metrics["error"] == line.removeprefix("error: ")
    assert not list(disk.rglob(".*tmp-*")) and not (disk / "run" / "result.h5").exists()


def interrupt(tmp_path, signum, delay):
    """Start a long run, send ``signum`` after ``delay`` s; returns the finished process."""
    env = {k: v for k, v in os.environ.items() if k not in ("HYDRA_FULL_ERROR", "PYTEST_CURRENT_TEST")}
    proc = subprocess.Popen([sys.executable, "-m", "decrun", "figures=false", "app.steps=1000000", "app.dt=1e-7",
                             "app.rescale=none"], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    if delay is None:  # once the run records steps
        deadline = time.monotonic() + 120
        while not list(tmp_path.rglob("result.h5.partial")) and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(0.5)
    else:
        time.sleep(delay)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=120)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


@pytest.mark.parametrize("signum, code, cause", [(signal.SIGINT, 130, "Ctrl-C"), (signal.SIGTERM, 143, "SIGTERM")],
                         ids=["ctrl-c", "sigterm"])
def test_an_interrupted_run_says_so_and_keeps_its_steps(tmp_path, signum, code, cause):
    from decrun.runner.results import read_result

    proc = interrupt(tmp_path, signum, None)
    assert_one_clear_line(proc, f"decrun: interrupted ({cause}); what was recorded is in", code=code)
    (run,) = (tmp_path / "outputs" / "runs").iterdir()
    assert json.loads((run / "metrics.json").read_text()) == {"status": "interrupted", "error": f"interrupted ({cause})"}
    result = read_result(run / "result.h5")
    assert not result.complete and result.status == "interrupted" and result.steps_recorded > 0
    assert sorted(p.name for p in run.iterdir()) == [".hydra", "decrun.log", "metrics.json", "result.h5"]


@pytest.mark.slow
@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["ctrl-c", "sigterm"])
def test_an_interrupt_before_the_run_starts_is_one_line(tmp_path, signum, code):
    proc = interrupt(tmp_path, signum, 0.6)  # while Hydra and numpy are imported / the config composed
    if proc.returncode == code and "what was recorded" in proc.stderr:
        pytest.skip("this machine reached the run within 0.6 s")
    assert_one_clear_line(proc, "before the run started", code=code)


def test_a_post_step_that_breaks_the_mesh_is_named(monkeypatch):
    """A step that produced non-finite coordinates is reported by name, not as a strange
    error far away (e.g. "app.rescale=volume needs a closed surface")."""
    from decrun.errors import NonFiniteCoordinateError
    from decrun.runner.job.plugins import option
    from decrun.runner.mesh import Mesh
    from decrun.runner.mesh import post as post_steps

    def broken(mesh, cfg):
        vertices = mesh.vertices.copy()
        vertices[7] = np.nan
        return Mesh(vertices, mesh.simplices, dict(mesh.meta))

    monkeypatch.setattr(post_steps, "noise", broken)
    with pytest.raises(NonFiniteCoordinateError, match=r"^mesh icosphere1 after the mesh.post step 'noise': vertex 7 has a "
                                        r"non-finite coordinate \[nan, nan, nan\] \(1 such vertices\)$"):
        option("mesh", "icosphere", subdiv=1).load()
