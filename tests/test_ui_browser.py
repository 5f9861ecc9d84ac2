"""`workbench ui` in a real browser: the store a reproduction's tracking makes (a parent run and
its system runs in the shared metric schema), the real `workbench ui` (an `mlflow server` on
127.0.0.1), and headless Chromium (Debian's package; `make test` installs it) rendering the
address `workbench ui` prints. The checks read the rendered page: MLflow's model-training runs
view (not its GenAI overview) with the system runs and their per-target test MAE columns.

``WORKBENCH_SCREENSHOT=path.png`` keeps the screenshot, and ``WORKBENCH_UI_STORE=<tracking
URI>`` renders that store instead of the test's (the README's screenshot is this test on the
store of a fresh `make run`: ``WORKBENCH_UI_STORE=sqlite:///$PWD/mlruns/mlflow.db``)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from workbench.experiment.paper.runs import SYSTEM_TAG
from workbench.experiment.runs.run_fields import NOTE_TAG
from workbench.experiment.tracking.runs import Tracker
from workbench.experiment.tracking.views import metric_view

from services import (
    command_env,
    free_port,
    stop_process_group,
    wait_until_answering,
    workbench_cmd,
)

TARGETS = ["eeig1", "eeig2", "eeig3", "eeig4", "eeig5"]
SYSTEMS = {"control program": 1.341, "base boosting, paper settings": 1.074,
           "parameter-space model": 0.377}


def chromium() -> str:
    path = shutil.which("chromium") or shutil.which("chromium-browser")
    if path is None:
        pytest.fail("headless Chromium is missing: `make test` installs Debian's chromium "
                    "package (apt-get install chromium)")
    return path


def render(url: str, tmp: Path, *, screenshot: Path | None = None, budget_ms: int = 15000,
           timeout: float = 120) -> str:
    """The DOM Chromium renders at ``url`` after ``budget_ms`` of the page's virtual time
    (and, with ``screenshot``, a PNG of the page): one Chromium run does both (two runs
    rendered the page twice, each loading MLflow's whole UI)."""
    args = [chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
            "--disable-dev-shm-usage", f"--user-data-dir={tmp / 'profile'}",
            "--window-size=1800,900", f"--virtual-time-budget={budget_ms}"]
    if screenshot is not None:
        args.append(f"--screenshot={screenshot}")
    done = subprocess.run([*args, "--dump-dom", url], capture_output=True, text=True,
                          timeout=timeout, check=False)
    return done.stdout


def _store(root: Path, new_store) -> str:
    """A store shaped like a reproduction's (in a copy of an empty one): the parent run, its
    system runs (test MAE per target), the experiment's runs view."""
    uri = new_store(root / "mlruns" / "mlflow.db")
    tracker = Tracker(uri, "paper-reproduction")
    with tracker.run("paper reproduction", tags={NOTE_TAG: "the reproduction"}) as parent:
        for k, (name, avg) in enumerate(SYSTEMS.items()):
            run = tracker.start_run(name, parent_run_id=parent, tags={SYSTEM_TAG: f"s{k}"})
            tracker.log_metrics(run, {"test_mae_avg": avg, **{
                f"test_mae/{t}": avg + 0.1 * j for j, t in enumerate(TARGETS)}})
            tracker.end_run(run)
    tracker.share_view(metric_view(TARGETS, search_filter=f"tags.`{SYSTEM_TAG}` LIKE '%'"))
    return uri


@pytest.fixture(scope="module")
def ui(tmp_path_factory, new_store):
    """A store with a reproduction-like experiment, and `workbench ui` serving it; yields
    the addresses it printed."""
    root = tmp_path_factory.mktemp("ui")
    uri = os.environ.get("WORKBENCH_UI_STORE") or _store(root, new_store)
    port = free_port()
    log = root / "ui.log"
    with open(log, "w") as out:  # workbench ui's own server settings (one worker, no jobs)
        proc = subprocess.Popen(workbench_cmd("ui", "--tracking-uri", uri, "--port", str(port)),
                                cwd=root, stdout=out, stderr=subprocess.STDOUT,
                                env=command_env(), start_new_session=True)
    try:
        wait_until_answering(f"http://127.0.0.1:{port}/health", proc, log, timeout=180)
        yield log.read_text(), root
    finally:
        stop_process_group(proc, timeout=15)


def test_ui_prints_model_training_addresses(ui):
    printed, _ = ui
    assert re.search(r"MLflow UI for .* at http://127\.0\.0\.1:\d+/#/experiments\?"
                     r"workflowType=machine_learning", printed), printed
    assert re.search(r"paper-reproduction: http://127\.0\.0\.1:\d+/#/experiments/\d+/runs\?"
                     r"viewStateShareKey=workbench&workflowType=machine_learning", printed)


def test_browser_shows_the_systems_and_their_test_mae(ui, tmp_path):
    printed, _ = ui
    url = re.search(r"paper-reproduction: (\S+)", printed).group(1)
    screenshot = Path(os.environ.get("WORKBENCH_SCREENSHOT") or tmp_path / "ui.png")
    dom = ""
    for budget in (15000, 30000, 60000):  # a busy machine renders late: wait longer
        dom = render(url, tmp_path, screenshot=screenshot, budget_ms=budget)
        if all(name in dom for name in SYSTEMS) and "test_mae/eeig1" in dom:
            break
        time.sleep(1)
    for name in SYSTEMS:  # the system runs, listed flat by the view's filter
        assert name in dom, name
    assert "paper reproduction" not in dom  # the parent: not a system
    for t in TARGETS[:3]:  # the first per-target columns fit the window
        assert f"test_mae/{t}" in dom, t
    # the model-training runs view, not the GenAI overview
    assert "Detect Issues" not in dom and "Token Usage" not in dom
    assert ">Runs<" in dom
    assert screenshot.is_file() and screenshot.stat().st_size > 10_000
