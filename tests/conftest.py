"""Shared fixtures. ``tests/`` is on ``sys.path`` (this file's folder), so test modules in
the sub-folders (which mirror decrun's layers: core/, methods/, apps/, runner/) import the
mesh helpers with ``from meshes_for_tests import ...``."""

from __future__ import annotations

import os
import sys

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")
# as the decrun command does (decrun/__main__.py): bound GNU OpenMP's and OpenBLAS's spinning before they load
from decrun.core.threads import bound_blas_spin, bound_openmp_spin  # noqa: E402

bound_openmp_spin()
bound_blas_spin()
# the mesh cache (decrun.runner.mesh.cache) of this session, shared by its xdist workers and the
# decrun commands they start (they inherit the variable), removed at the end; never the user's
if "DECRUN_MESH_CACHE" not in os.environ:
    import atexit
    import shutil
    import tempfile

    os.environ["DECRUN_MESH_CACHE"] = tempfile.mkdtemp(prefix="decrun-mesh-cache-")
    atexit.register(shutil.rmtree, os.environ["DECRUN_MESH_CACHE"], True)


def pytest_configure(config):
    config.addinivalue_line("markers", "ray: starts or joins a Ray cluster (serialized across xdist workers, "
                                       "with a Ray temp dir of its own: the ray_private fixture)")


@pytest.fixture(autouse=True)
def ray_private(request, tmp_path_factory, monkeypatch):
    """For a test marked ``ray``: the Ray clusters of the run one at a time, each unseen by the others.

    Two xdist workers that both start Ray collide: a ``ray.cluster_utils.Cluster`` writes its
    address into ``<ray temp dir>/ray_current_cluster`` and a ``ray.init()`` without an address
    (the ray launcher's default) elsewhere joins that cluster instead of starting its own; and
    two clusters at once do not fit two cores. So the test holds an exclusive lock on a file
    shared by the session's workers for its whole length, and ``RAY_TMPDIR`` points to a short
    directory of its own (Ray's socket paths must stay under 108 bytes), inherited by the
    processes it starts; ``RAY_ADDRESS`` is unset.

    A test without the mark gets a ``RAY_TMPDIR`` of its own too, a sentinel: Ray writes its
    session there the moment it starts (in this process or in a child, which inherits the
    variable), so a test that starts Ray without the mark fails, naming the mark it needs,
    instead of racing the marked ones for the cores and the cluster address."""
    import shutil
    import tempfile
    from pathlib import Path

    if request.node.get_closest_marker("ray") is None:
        sentinel = Path(tempfile.mkdtemp(prefix="decrun-noray-"))
        monkeypatch.setenv("RAY_TMPDIR", str(sentinel))
        try:
            yield None
        finally:
            started = sorted(p.name for p in sentinel.iterdir())
            shutil.rmtree(sentinel, ignore_errors=True)
        if started:
            pytest.fail(f"{request.node.nodeid} started Ray (it wrote {started} into RAY_TMPDIR) without the ray mark: "
                        "add @pytest.mark.ray, which serializes the Ray tests and gives each its own temp dir",
                        pytrace=False)
        return
    import fcntl

    base = tmp_path_factory.getbasetemp()
    shared = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base  # the session's workers share it
    with open(shared / "decrun-ray.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        private = Path(tempfile.mkdtemp(prefix="decrun-ray-"))
        monkeypatch.setenv("RAY_TMPDIR", str(private))
        monkeypatch.delenv("RAY_ADDRESS", raising=False)
        try:
            yield private
        finally:
            if "ray" in sys.modules and sys.modules["ray"].is_initialized():  # a launcher run in this process
                sys.modules["ray"].shutdown()
            shutil.rmtree(private, ignore_errors=True)
            fcntl.flock(lock, fcntl.LOCK_UN)


@pytest.fixture
def new_solver():
    """A factory of fresh direct solvers (what ``ctx.new_solver`` is in a default run)."""
    from decrun.core.solvers import solver_factory

    return solver_factory("direct")


@pytest.fixture
def run_app():
    """``run_app(app, K, star=..., boundary=..., solver=...)`` → (Result, Context): an app run
    outside the runner, with the in-memory context (recorded series in ``ctx.series``)."""
    from decrun.apps.base import Context
    from decrun.core.dec import DEC

    def run(app, K, star="circumcentric", boundary="none", solver="direct", meta=None):
        app.check_pieces(K)
        dec = DEC(K, star=star, boundary=boundary)
        app.check_operators(dec)
        app.check(K, dec)
        ctx = Context(app, K, dec, new_solver=solver, meta=meta)
        return app.run(ctx), ctx

    return run


@pytest.fixture
def decrun_cli(tmp_path):
    """Run the real ``decrun`` command (``python -m decrun``) in a temporary directory."""
    import subprocess

    def run(*args, cwd=None, env=None, timeout=300):
        environment = dict(os.environ, MPLBACKEND="Agg", **(env or {}))
        return subprocess.run([sys.executable, "-m", "decrun", *args], cwd=cwd or tmp_path, capture_output=True,
                              text=True, timeout=timeout, env=environment)

    return run


@pytest.fixture
def tmpfs(tmp_path):
    """``tmpfs(size, read_only=False)`` → a freshly mounted tmpfs under ``tmp_path`` (a full or
    read-only disk for the tests that need one; root and mount(8) only, skipped elsewhere),
    unmounted after the test."""
    import subprocess
    from pathlib import Path

    mounted: list[Path] = []

    def mount(size: str, read_only: bool = False) -> Path:
        point = tmp_path / f"fs{len(mounted)}"
        point.mkdir()
        options = f"size={size}" + (",ro" if read_only else "")
        if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(point)],
                                               capture_output=True).returncode != 0:
            pytest.skip("cannot mount a tmpfs (needs root)")
        mounted.append(point)
        return point

    yield mount
    for point in mounted:
        subprocess.run(["umount", str(point)], check=True)


@pytest.fixture
def tiny_disk(tmpfs):
    """A 1 MiB tmpfs (:func:`tmpfs`)."""
    return tmpfs("1m")
