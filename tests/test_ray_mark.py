"""A test that starts Ray must carry the ``ray`` mark (tests/conftest.py's ``ray_private``: the
session lock and a Ray temp dir of its own); one without it that starts Ray — in the test's
process or in a child — fails, naming the mark. Shown on a pytest session of its own, run here
with this suite's conftest."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent

#: what Ray does first when it starts: its session directory under $RAY_TMPDIR/ray
STARTS = "Path(os.environ['RAY_TMPDIR'], 'ray', 'session_latest').mkdir(parents=True)"

INNER = f'''
import os, subprocess, sys
from pathlib import Path
import pytest

def test_unmarked_start_in_process():
    {STARTS}

def test_unmarked_start_in_a_child():
    subprocess.run([sys.executable, "-c", "import os; from pathlib import Path; {STARTS}"], check=True)

@pytest.mark.ray
def test_marked_start():
    {STARTS}

def test_unmarked_without_ray():
    assert Path(os.environ["RAY_TMPDIR"]).is_dir()
'''

REAL = '''
import ray

def test_unmarked_real_ray():
    ray.init(num_cpus=1, include_dashboard=False, object_store_memory=78643200)
    ray.shutdown()
'''


def _session(tmp_path: Path, source: str) -> subprocess.CompletedProcess:
    """``pytest`` on ``source`` as a test file beside a copy of this suite's conftest."""
    shutil.copy(HERE / "conftest.py", tmp_path / "conftest.py")
    (tmp_path / "test_inner.py").write_text(source)
    env = {k: v for k, v in os.environ.items() if k not in ("PYTEST_XDIST_WORKER", "PYTEST_CURRENT_TEST", "RAY_TMPDIR")}
    return subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:randomly", "-p", "no:xdist", "-p",
                           "no:cacheprovider", "-rE", str(tmp_path / "test_inner.py")], cwd=tmp_path, env=env,
                          capture_output=True, text=True, timeout=300)


def test_a_test_that_starts_ray_without_the_mark_fails(tmp_path):
    done = _session(tmp_path, INNER)
    assert done.returncode == 1, done.stdout[-3000:]
    assert "4 passed, 2 errors" in done.stdout, done.stdout[-3000:]  # the errors: at the unmarked ones' teardown
    for name in ("test_unmarked_start_in_process", "test_unmarked_start_in_a_child"):
        assert f"test_inner.py::{name} started Ray (it wrote ['ray'] into RAY_TMPDIR) without the ray mark: " \
               "add @pytest.mark.ray" in done.stdout, done.stdout[-3000:]
    assert "test_marked_start started Ray" not in done.stdout


@pytest.mark.ray  # its inner session starts a real Ray (in a process of its own)
@pytest.mark.slow
def test_a_real_ray_start_without_the_mark_fails(tmp_path):
    pytest.importorskip("ray")
    done = _session(tmp_path, REAL)
    assert done.returncode == 1 and "1 passed, 1 error" in done.stdout, done.stdout[-3000:]
    assert "test_unmarked_real_ray started Ray" in done.stdout and "without the ray mark" in done.stdout
