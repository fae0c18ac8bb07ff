"""The MLflow UI shows a tracked sweep: a 3-job sweep with ``tracker=mlflow`` into a sqlite
store, ``mlflow server`` on 127.0.0.1 over it (the command docs/tracking.md gives), and the
experiment's runs page opened in headless Chromium through selenium — every job's run is
listed, and the metric column ``dirichlet_energy`` added with *Columns* shows each job's value
from metrics.csv.

Needs the ``mlflow`` and ``view`` extras and Debian's ``chromium`` + ``chromium-driver``
(.ci/run installs them); skipped, saying which is missing, elsewhere."""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request

import pandas as pd
import pytest
from cli_processes import decrun, env

pytest.importorskip("mlflow", reason="the MLflow UI test needs the mlflow extra: pip install 'decrun[mlflow]'")
pytest.importorskip("selenium", reason="the MLflow UI test needs the view extra: pip install 'decrun[view]'")
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
DRIVER = shutil.which("chromedriver")
pytestmark = pytest.mark.skipif(CHROMIUM is None or DRIVER is None,
                                reason="no headless browser: apt-get install chromium chromium-driver (.ci/run does)")

#: Chromium as root in a container: no sandbox, no GPU, nothing fetched from the network
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                  "--disable-component-update", "--disable-sync", "--no-first-run", "--window-size=1600,1000")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_for(url: str, seconds: float, server: subprocess.Popen) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if server.poll() is not None:
            raise AssertionError(f"mlflow server exited with {server.returncode}: {server.stderr.read()[-2000:]}")
        try:
            with urllib.request.urlopen(url, timeout=5) as response:
                if response.status == 200:
                    return
        except OSError:
            time.sleep(1)
    raise AssertionError(f"mlflow server did not answer {url} within {seconds} s")


def _browser():
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    options.add_argument(f"--user-data-dir={tempfile.mkdtemp(prefix='chromium-')}")
    options.binary_location = CHROMIUM
    return webdriver.Chrome(service=Service(DRIVER), options=options)


def _page_text(driver, wanted: list[str], seconds: float) -> str:
    """The page's text once every string of ``wanted`` is on it (the UI loads its runs after
    the page); the last text seen when that does not happen within ``seconds``."""
    deadline, text = time.monotonic() + seconds, ""
    while time.monotonic() < deadline:
        text = driver.find_element("tag name", "body").text
        if all(w in text for w in wanted):
            break
        time.sleep(0.5)
    return text


def test_the_mlflow_ui_shows_the_sweeps_runs_and_a_metric_column(tmp_path):
    from selenium.webdriver.common.by import By
    from selenium.webdriver.common.keys import Keys

    proc = decrun("-m", "app=heat", "mesh.subdiv=1", "app.t_end=0.004", "operator=mixed_area",
                  "figures=false", "app.dt=1e-3,2e-3,4e-3", "tracker=mlflow", "tracker.uri=sqlite:///mlflow.db",
                  "hydra.sweep.dir=sweep", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    table = pd.read_csv(tmp_path / "sweep" / "metrics.csv")
    assert len(table) == 3 and set(table["status"]) == {"ok"}
    from mlflow.tracking import MlflowClient

    experiment = MlflowClient(f"sqlite:///{tmp_path / 'mlflow.db'}").get_experiment_by_name("decrun").experiment_id
    port = _free_port()
    mlflow = [os.path.join(os.path.dirname(sys.executable), "mlflow")]
    server = subprocess.Popen([*mlflow, "server", "--backend-store-uri", "sqlite:///mlflow.db", "--host", "127.0.0.1",
                               "--port", str(port), "--workers", "1"], cwd=tmp_path, env=env(),
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    driver = None
    try:
        base = f"http://127.0.0.1:{port}"
        _wait_for(f"{base}/health", 180, server)
        driver = _browser()
        # the jobs (nested under the sweep's run, which the page shows folded) through the UI's own filter
        driver.get(f"{base}/#/experiments/{experiment}/runs?searchFilter=attributes.run_name%20LIKE%20%27job%25%27"
                   "&orderByKey=metrics.%60dirichlet_energy%60&orderByAsc=true")
        jobs = [f"job {job}" for job in table["job"]]
        text = _page_text(driver, [*jobs, "3 matching runs"], 120)
        assert all(job in text for job in jobs) and "3 matching runs" in text, text[-1500:]
        driver.find_element(By.XPATH, "//button[contains(., 'Columns')]").click()
        [choice] = [e for e in driver.find_elements(By.XPATH, "//*[normalize-space(text())='dirichlet_energy']")
                    if e.is_displayed()]
        choice.click()
        driver.find_element("tag name", "body").send_keys(Keys.ESCAPE)
        values = [repr(float(v)) for v in table["dirichlet_energy"]]  # as the UI prints a metric: every digit
        cells = _page_text(driver, values, 60)
        assert all(v in cells for v in values), (values, cells[-1500:])
    finally:
        if driver is not None:
            driver.quit()
        os.killpg(server.pid, signal.SIGTERM)  # the server and its uvicorn worker (its own session)
        try:
            server.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, signal.SIGKILL)
