"""Real services for tests: a PostgreSQL server (the ``pgserver`` wheel ships PostgreSQL; as
root it runs the server as a system user ``pgserver`` that it creates) and an ``mlflow
server`` with a PostgreSQL backend store and a local artifacts directory on 127.0.0.1.
No mocks: the tests talk to these servers over their real protocols."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_until_answering(url: str, proc: subprocess.Popen, log: Path, timeout: float,
                         poll_s: float = 0.3) -> float:
    """Poll ``url`` until it answers 200; returns the seconds it took. Raises (with the end
    of ``log``) if ``proc`` exits first or ``timeout`` seconds pass."""
    start = time.monotonic()
    while time.monotonic() - start < timeout:
        if proc.poll() is not None:
            raise RuntimeError(f"{proc.args[:4]} exited with {proc.returncode}: "
                               f"{log.read_text()[-2000:]}")
        try:
            with urllib.request.urlopen(url, timeout=2) as r:
                if r.status == 200:
                    return time.monotonic() - start
        except OSError:
            time.sleep(poll_s)
    raise RuntimeError(f"{url} did not answer in {timeout} s: {log.read_text()[-2000:]}")


def stop_process_group(proc: subprocess.Popen, timeout: float = 10) -> None:
    """SIGTERM the process group of ``proc`` (started with ``start_new_session=True``: a
    server and its workers), SIGKILL it if it is still there after ``timeout`` seconds."""
    import signal

    try:
        os.killpg(proc.pid, signal.SIGTERM)
        proc.wait(timeout=timeout)
    except ProcessLookupError:
        return
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


class Postgres:
    """A PostgreSQL server in ``root`` (started in about a second); :meth:`database` creates
    a database and returns its SQLAlchemy URL (Unix socket; trust authentication, so any
    password in the URL is accepted: the tests use one to check it is never printed)."""

    def __init__(self, root: Path):
        import pgserver

        root.mkdir(parents=True, exist_ok=True)
        self.server = pgserver.get_server(root, cleanup_mode="stop")
        info = self.server.get_postmaster_info()
        self.socket_dir = str(info.socket_dir)

    def database(self, name: str, user: str = "postgres", password: str | None = None) -> str:
        self.server.psql(f"CREATE DATABASE {name};")
        auth = user if password is None else f"{user}:{password}"
        return f"postgresql+psycopg2://{auth}@/{name}?host={self.socket_dir}"

    def stop(self) -> None:
        self.server.cleanup()


#: The environment of an ``mlflow server`` a test starts: no job execution (MLflow's GenAI
#: jobs: a job runner and seven huey consumer processes, each importing MLflow; workbench
#: starts no server job) and one worker process (MLflow's default: four, each importing the
#: server; one serves a test's requests). The tracking server itself is unchanged; on 2 cores
#: it answers after 8 s instead of 23 s, with 9 s of CPU instead of 30 s.
TEST_SERVER_ENV = {"MLFLOW_SERVER_ENABLE_JOB_EXECUTION": "false", "MLFLOW_WORKERS": "1"}


class MlflowServer:
    """``mlflow server`` on 127.0.0.1 at a free port (or ``port``), on ``backend_uri`` with
    artifacts in ``artifacts``; :attr:`uri` is its http URL. :meth:`kill` and :meth:`start`
    take it away (SIGKILL) and bring it back on the same port."""

    def __init__(self, backend_uri: str, artifacts: Path, log: Path, timeout: float = 180,
                 port: int | None = None):
        self.port = port or free_port()
        self.uri = f"http://127.0.0.1:{self.port}"
        artifacts.mkdir(parents=True, exist_ok=True)
        self._args = [sys.executable, "-m", "mlflow", "server", "--backend-store-uri",
                      backend_uri, "--artifacts-destination", artifacts.resolve().as_uri(),
                      "--host", "127.0.0.1", "--port", str(self.port), "--workers", "1"]
        self._log_path = log
        self._log = open(log, "w")
        self.start(timeout)

    def start(self, timeout: float = 180) -> float:
        """Start the server and wait until it answers; returns the seconds it took."""
        env = dict(os.environ, MLFLOW_DISABLE_TELEMETRY="true", **TEST_SERVER_ENV)
        self.proc = subprocess.Popen(self._args, stdout=self._log, stderr=subprocess.STDOUT,
                                     env=env, start_new_session=True)
        try:
            return wait_until_answering(f"{self.uri}/health", self.proc, self._log_path,
                                        timeout, poll_s=0.5)
        except RuntimeError:
            self.stop()
            raise

    def kill(self) -> None:
        """SIGKILL the server and its workers (a crashed host), and wait until they are gone
        and the port refuses connections."""
        import signal

        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.proc.wait()
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:  # a worker may outlive its parent for a moment
            try:
                os.killpg(self.proc.pid, 0)
            except ProcessLookupError:
                return
            time.sleep(0.05)

    def stop(self) -> None:
        import signal

        try:
            os.killpg(self.proc.pid, signal.SIGTERM)  # the server and its uvicorn workers
            self.proc.wait(timeout=3)  # a test server: no need to drain requests
        except (ProcessLookupError, subprocess.TimeoutExpired):
            try:
                os.killpg(self.proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self._log.close()


TINY = """\
name = "tiny"
random_state = 0

[data]
csv = "sim.csv"
prior = ["model_E1"]
targets = ["measured_E1"]
features = ["v_q1", "v_q2", "v_c1"]
test_fraction = 0.3

[model]
basis = "ridge"
n_stages = 1
basis_inputs = "prior+features"
input_transform = "standard"

[search]
n_stages = {{ low = 1, high = 3 }}
line_search_penalty = {{ low = 0.0, high = 0.5 }}

[search.basis_params.ridge]
alpha = {{ low = 0.001, high = 100.0, log = true }}

[cv]
outer_folds = 2
inner_folds = 3
sweep_seed = 0

[study]
trials = {trials}
pruner = "none"
storage = "optuna.journal"
stale_after_s = {stale_after_s}

[tracking]
experiment = "tiny"
"""


def tiny_sweep(directory: Path, trials: int = 6, stale_after_s: float = 600) -> Path:
    """A small sweep config (one target of a simulated 2-qubit device, 3 studies: 2 outer
    folds and the final one) and its data in ``directory``; returns the config path."""
    from workbench.simulate import Mismatch, simulate

    directory.mkdir(parents=True, exist_ok=True)
    simulate(2, 120, device_seed=0, mismatch=Mismatch.default()).data.to_csv(directory / "sim.csv",
                                                                      index=False)
    path = directory / "tiny.toml"
    path.write_text(TINY.format(trials=trials, stale_after_s=stale_after_s))
    return path


def workbench_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "workbench.experiment.cli", *map(str, args)]


def command_env(**extra: str) -> dict[str, str]:
    """The environment of a ``workbench`` process in tests: the worktree importable, one
    BLAS thread, no telemetry, and runs' heartbeats every 2 s."""
    root = str(Path(__file__).resolve().parents[1])
    path = os.environ.get("PYTHONPATH")
    env = dict(os.environ, OMP_NUM_THREADS="1", MLFLOW_DISABLE_TELEMETRY="true",
               WORKBENCH_RUN_HEARTBEAT_S="2",
               PYTHONPATH=root if not path else f"{root}{os.pathsep}{path}")
    env.update(extra)
    return env
