"""Failures end in one short line and leak nothing (issue 20, "Plumbing you can trust").

Each case of the table runs ``workbench.experiment.cli.main`` in-process on a small simulated
device in ``tmp_path`` (the working directory, with no ``$MLFLOW_TRACKING_URI``: the default
store would be ``tmp_path/mlruns``) and checks: exit code 2, standard error one line
``workbench: error: ...`` under 300 characters holding the key words and none of the file's
content or secrets, nothing on standard output, and no file written (no ``mlruns/``, no
``--json`` output). Then: a zero-row request to the served model, the config logged with
its credentials redacted, and :func:`~workbench.experiment.process.errors.redact` itself."""

from __future__ import annotations

import asyncio
import contextlib
import io
import json
from pathlib import Path

import pandas as pd
import pytest

from workbench._text import clip
from workbench.experiment.cli import main
from workbench.experiment.process.errors import listing, redact, redact_config
from workbench.simulate import simulate

SECRET = "s3cret"

CONFIG = """\
name = "msg"
random_state = 0
n_jobs = 1
{top}
[data]
csv = "{csv}"
prior = ["model_E1"]
targets = ["measured_E1"]
features = ["v_q1", "v_q2", "v_c1"]
test_fraction = 0.3
{data}
[model]
basis = "ridge"
input_transform = "standard"
{model}
{extra}
"""

HAMILTONIAN = """\
[data.hamiltonian]
onsite = ["model_f1", "model_f2"]
couplings = ["model_g1"]
"""


def device_frame(rows: int = 60) -> pd.DataFrame:
    return simulate(2, rows, device_seed=0).data


def write_config(tmp_path: Path, csv: str = "sim.csv", *, top: str = "", data: str = "",
                 model: str = "", extra: str = "") -> Path:
    path = tmp_path / "msg.toml"
    path.write_text(CONFIG.format(csv=csv, top=top, data=data, model=model, extra=extra))
    return path


def with_data(tmp_path: Path, **config) -> Path:
    device_frame().to_csv(tmp_path / "sim.csv", index=False)
    return write_config(tmp_path, **config)


# --------------------------------------------------------------------------- the cases
# Each builds its files in tmp_path and returns (argv, needles, secrets).

def shadow_file(tmp_path):
    (tmp_path / "shadow").write_text(f"root:$6${SECRET}salt$Zx81kQhash:19000:0:99999:7:::\n"
                                     "daemon:*:19000:0:99999:7:::\n")
    return (["evaluate", write_config(tmp_path, csv="shadow")],
            ["shadow", "does not look like a CSV file"], [SECRET, "$6$", "19000", "daemon"])


def key_file_with_commas(tmp_path):
    (tmp_path / "key.pem").write_text("-----BEGIN PRIVATE KEY-----,MIIEvQIBADAN:Bgkq\n"
                                      f"{SECRET}AAAA,BBBB\n")
    return (["evaluate", write_config(tmp_path, csv="key.pem")],
            ["missing column(s) ['v_q1'", "does not look like a CSV header"],
            [SECRET, "BEGIN", "MIIEv"])


def semicolons(tmp_path):
    device_frame().to_csv(tmp_path / "sim.csv", index=False, sep=";", decimal=",")
    return (["evaluate", write_config(tmp_path)],
            ["sim.csv has one column named 'v_q1;v_q2;v_c1;...'", "wrong delimiter",
             "comma-separated"], ["model_E1;", "measured"])


def huge_target(tmp_path):
    frame = device_frame()
    frame.loc[5, "measured_E1"] = 1e308
    frame.to_csv(tmp_path / "sim.csv", index=False)
    return (["evaluate", write_config(tmp_path)],
            ["column(s) ['measured_E1']", "line 7", "1e+150"], ["1e+308", "1e308"])


def huge_prior(tmp_path):
    frame = device_frame()
    frame.loc[0, "model_E1"] = -3e200
    frame.to_csv(tmp_path / "sim.csv", index=False)
    return (["evaluate", write_config(tmp_path)], ["'model_E1'", "line 2"], ["3e+200"])


def hamiltonian_key(key):
    def case(tmp_path):
        cfg = with_data(tmp_path, data=HAMILTONIAN, model='family = "hamiltonian"',
                        extra=f"[model.hamiltonian]\n{key} = 1\n")
        return (["evaluate", cfg], ["[model.hamiltonian]", key[:20], "valid keys are",
                                    "'alpha'"], [])
    return case


def estimator_range(section, line, needles):
    """A value outside the range of the estimator whose parameter the key is: the line names
    the file, ``section.key``, the value and the estimator's constraint."""
    def case(tmp_path):
        kwargs = ({"model": line} if section == "model" else
                  {"data": HAMILTONIAN, "model": 'family = "hamiltonian"',
                   "extra": f"[{section}]\n{line}\n"} if section == "model.hamiltonian" else
                  {"extra": f"[{section}]\n{line}\n"})
        return ["evaluate", with_data(tmp_path, **kwargs)], ["msg.toml: ", *needles], []
    return case


def unknown_key(section):
    """``bogus_key = 1`` in ``section`` (``""``: the top level)."""
    def case(tmp_path):
        kwargs = {"": {"top": "bogus_key = 1"}, "data": {"data": "bogus_key = 1"},
                  "model": {"model": "bogus_key = 1"},
                  "data.hamiltonian": {"data": HAMILTONIAN + "bogus_key = 1\n"}}.get(
            section, {"extra": f"[{section}]\nbogus_key = 1\n"})
        return ["evaluate", with_data(tmp_path, **kwargs)], ["bogus_key", "valid keys"], []
    return case


def huge_basis_name(tmp_path):
    cfg = with_data(tmp_path, extra=f'[model.targets.measured_E1]\nbasis = "{"x" * 5000}"\n')
    return ["evaluate", cfg], ["unknown basis", "5002 chars"], ["x" * 100]


def tracking_server_with_password(tmp_path):
    cfg = with_data(tmp_path, extra=f'[tracking]\ntracking_uri = "http://u:{SECRET}@127.0.0.1:1"\n')
    return ["evaluate", cfg], ["cannot reach", "http://u:***@127.0.0.1:1"], [SECRET]


CASES = {
    "shadow file": shadow_file,
    "key file with commas": key_file_with_commas,
    "semicolon-delimited csv": semicolons,
    "1e308 target": huge_target,
    "-3e200 prior": huge_prior,
    "model.hamiltonian unknown key": hamiltonian_key("bogus_key"),
    "model.hamiltonian near miss": hamiltonian_key("max_iters"),
    "model.hamiltonian 400-char key": hamiltonian_key("k" * 400),
    **{f"unknown key in [{s or 'top'}]": unknown_key(s) for s in (
        "", "data", "data.hamiltonian", "model", "model.targets.measured_E1", "selection",
        "evaluation", "intervals", "search", "cv", "study", "tracking")},
    "model.n_stages below BaseBoostRegressor's range": estimator_range(
        "model", "n_stages = 0", ["model.n_stages = 0: The 'n_stages' parameter of "
                                  "BaseBoostRegressor must be an int in the range [1, inf)"]),
    "intervals.alpha outside ConformalRegressor's range": estimator_range(
        "intervals", "alpha = 1.5", ["intervals.alpha = 1.5: The 'alpha' parameter of "
                                     "ConformalRegressor", "(0.0, 1.0)"]),
    "model.hamiltonian.selection_cv below HamiltonianSelectionCV's": estimator_range(
        "model.hamiltonian", "selection_cv = 1",
        ["model.hamiltonian.selection_cv = 1: The 'cv' parameter of HamiltonianSelectionCV",
         "[2, inf)"]),
    "5000-char basis name": huge_basis_name,
    "tracking server with a password": tracking_server_with_password,
}


def _files(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("MLFLOW_TRACKING_URI", raising=False)  # the default: ./mlruns
    return tmp_path


@pytest.mark.parametrize("case", list(CASES.values()), ids=list(CASES))
def test_failure_is_one_short_line_and_writes_nothing(workdir, case):
    argv, needles, secrets = case(workdir)
    before = _files(workdir)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main([str(a) for a in argv] + ["--json", str(workdir / "out.json")])
    lines = err.getvalue().splitlines()
    assert rc == 2, err.getvalue()
    assert len(lines) == 1 and lines[0].startswith("workbench: error: "), err.getvalue()
    line = lines[0]
    assert len(line) < 300, (len(line), line)
    for needle in needles:
        assert needle in line, (needle, line)
    for secret in secrets:
        assert secret not in line, (secret, line)
    assert out.getvalue() == ""
    assert _files(workdir) == before  # no mlruns/, no out.json, nothing else


# --------------------------------------------------------------------------- the served model


def _asgi_post(app, path: str, body: bytes) -> tuple[int, bytes]:
    """One POST through the ASGI app (what uvicorn does for ``mlflow models serve``)."""
    incoming = [{"type": "http.request", "body": body, "more_body": False}]
    sent: list[dict] = []

    async def receive():
        return incoming.pop(0) if incoming else {"type": "http.disconnect"}

    async def send(message):
        sent.append(message)

    scope = {"type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1",
             "method": "POST", "scheme": "http", "path": path, "raw_path": path.encode(),
             "query_string": b"", "root_path": "", "client": ("127.0.0.1", 1),
             "server": ("127.0.0.1", 80),
             "headers": [(b"content-type", b"application/json"),
                         (b"content-length", str(len(body)).encode())]}
    asyncio.run(app(scope, receive, send))
    status = next(m["status"] for m in sent if m["type"] == "http.response.start")
    return status, b"".join(m.get("body", b"") for m in sent if m["type"] == "http.response.body")


def test_served_model_answers_a_zero_row_request_in_one_short_message(tmp_path, monkeypatch):
    import mlflow.pyfunc
    from mlflow.environment_variables import _MLFLOW_IS_IN_SERVING_ENVIRONMENT
    from mlflow.pyfunc import scoring_server
    from sklearn.linear_model import LinearRegression

    from workbench.experiment.tracking.serving import WorkbenchModel, model_signature

    monkeypatch.setenv(_MLFLOW_IS_IN_SERVING_ENVIRONMENT.name, "false")  # init sets it
    X = pd.DataFrame({"a": [0.0, 1.0, 2.0], "b": [1.0, 0.0, 1.0]})
    wrapped = WorkbenchModel(LinearRegression().fit(X, X["a"] + X["b"]), ["a", "b"], ["y"])
    mlflow.pyfunc.save_model(str(tmp_path / "model"), python_model=wrapped, input_example=X,
                             signature=model_signature(wrapped.columns, wrapped.outputs))
    app = scoring_server.init(mlflow.pyfunc.load_model(str(tmp_path / "model")))

    def post(rows):
        return _asgi_post(app, "/invocations", json.dumps(
            {"dataframe_split": {"columns": ["a", "b"], "data": rows}}).encode())

    status, body = post([[1.0, 2.0]])
    assert status == 200 and json.loads(body)["predictions"][0]["y"] == pytest.approx(3.0)
    status, body = post([])
    assert status == 400, body
    assert len(body) < 300, (len(body), body)
    reply = json.loads(body)
    assert "no rows to predict" in reply["message"] and "stack_trace" not in reply


# --------------------------------------------------------------------------- secrets


def test_logged_config_and_model_config_have_no_password(workdir, monkeypatch, new_store):
    """``evaluate`` logs the config file as a run artifact and as the model's
    ``config.toml``: both with the passwords of ``[study] storage`` and ``[tracking]
    tracking_uri`` (and of a URL in a comment) replaced by ``***``; no file of the store
    holds the password."""
    from mlflow import MlflowClient

    from workbench.experiment.families import Artifacts
    from workbench.experiment.families.eigenvalue import EigenvalueFamily

    monkeypatch.setattr(EigenvalueFamily, "begin_artifacts",
                        lambda *args, **kwargs: lambda emit=None: Artifacts())
    cfg = with_data(workdir, top=f"# moved from postgresql://old:{SECRET}-x@db.example/old\n",
                    extra=f'[study]\nstorage = "postgresql://u:{SECRET}@127.0.0.1:1/db"\n'
                          f"[tracking]\ntracking_uri = 'http://u:{SECRET}@127.0.0.1:1'\n")
    uri = new_store(workdir / "store" / "mlflow.db")
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(["evaluate", str(cfg), "--tracking-uri", uri, "--no-intervals",
                   "--json", str(workdir / "out.json")])
    assert rc == 0, err.getvalue()
    result = json.loads((workdir / "out.json").read_text())["mlflow"]
    client = MlflowClient(uri)
    logged = Path(client.download_artifacts(result["run_id"], "msg.toml",
                                            str(workdir / "download"))).read_text()
    model_dir = client.get_logged_model(result["model_uri"].removeprefix("models:/"))
    in_model = (Path(model_dir.artifact_location.removeprefix("file://")) /
                "config.toml").read_text()
    expected = cfg.read_text().replace(f"old:{SECRET}-x@", "old:***@").replace(
        f"u:{SECRET}@", "u:***@")
    assert logged == in_model == expected
    for path in (workdir / "store").rglob("*"):
        if path.is_file():
            assert SECRET.encode() not in path.read_bytes(), path
    assert SECRET not in out.getvalue() + err.getvalue()


@pytest.mark.parametrize("url, shown", [
    ("postgresql://u:pw@h:5432/db", "postgresql://u:***@h:5432/db"),
    ("postgresql+psycopg2://u:p@ss/w?rd#x@h/db?host=/tmp", "postgresql+psycopg2://u:***@h/db?host=/tmp"),
    ("mysql://u:p%40ss@h/db", "mysql://u:***@h/db"),
    ("http://u:pw@h:5000", "http://u:***@h:5000"),
    ("https://h/api?token=abc&x=1", "https://h/api?token=***&x=1"),
    ("postgresql://h/db?user=u&password=pw", "postgresql://h/db?user=u&password=***"),
    ("postgresql://u@h/db", "postgresql://u@h/db"),
    ("sqlite:////tmp/mlruns/mlflow.db", "sqlite:////tmp/mlruns/mlflow.db"),
    ("mlruns/optuna.journal", "mlruns/optuna.journal"),
])
def test_redact(url, shown):
    assert redact(url) == shown


def test_redact_config_keeps_the_file_but_the_passwords():
    text = ('# was "postgresql://a:old-pw@h/db"\n[study]\nstorage = "postgresql://u:p\\"w@h/db"\n'
            "[tracking]\ntracking_uri = 'http://u:pw@h:5000'\n")
    assert redact_config(text) == ('# was "postgresql://a:***@h/db"\n[study]\n'
                                   'storage = "postgresql://u:***@h/db"\n'
                                   "[tracking]\ntracking_uri = 'http://u:***@h:5000'\n")
    odd = '[study]\nstorage = "postgresql://u:\\u0070w@h/db"\n'  # an escape not undone here
    assert "pw" not in redact_config(odd) and "\\u0070" not in redact_config(odd)


def test_clip_cuts_to_the_limit_with_an_ellipsis():
    assert clip("abc", 3) == "abc"
    assert clip("abcd", 3) == "..."
    assert clip("x" * 500, 200) == "x" * 197 + "..."
    assert listing(["a" * 40, "b"]) == f"'{'a' * 27}...', 'b'"

