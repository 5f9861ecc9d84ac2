"""``workbench init``: a first config for a CSV of your own, then ``workbench evaluate``."""

from __future__ import annotations

import contextlib
import io
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import tomllib
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.experiment.cli import main
from workbench.experiment.config import load_dataset
from workbench.experiment.config.toml_text import split_template, toml_string
from workbench.experiment.runs import init as init_module
from workbench.experiment.runs.init import csv_entry, template_text
from workbench.experiment.runs.prepare import load_config

ROOT = Path(__file__).resolve().parents[1]
PRIOR = ["model_E1", "model_E2"]
TARGETS = ["measured_E1", "measured_E2"]
FEATURES = ["v1", "v2", "v3"]
TARGET_ARGS = ["--prior", *PRIOR, "--target", *TARGETS]


def write_csv(path: Path, n: int = 120, seed: int = 0, **extra) -> Path:
    """2 targets, each with its prior column, 3 features, a known nonlinear correction (the
    prior misses it), a non-numeric column and a train/test column (every 4th row test)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, (n, 3))
    p1, p2 = rng.normal(5, 1, n), rng.normal(6, 1, n)
    frame = pd.DataFrame({
        "device": [f"chip{i % 3}" for i in range(n)],
        "v1": x[:, 0], "v2": x[:, 1], "v3": x[:, 2],
        "model_E1": p1, "model_E2": p2,
        "measured_E1": p1 + 0.8 * np.sin(3 * x[:, 0]) + 0.5 * x[:, 1] ** 2
        + rng.normal(0, 0.05, n),
        "measured_E2": p2 + 0.6 * x[:, 0] * x[:, 2] + 0.4 * np.cos(2 * x[:, 1])
        + rng.normal(0, 0.05, n),
        "split": np.where(np.arange(n) % 4 == 0, "test", "train"),
        **extra,
    })
    path.parent.mkdir(parents=True, exist_ok=True)
    frame.to_csv(path, index=False)
    return path


def run(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse's errors (one line, exit code 2)
            rc = exc.code
    return rc, out.getvalue(), err.getvalue()


def one_error_line(err: str) -> str:
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("workbench: error: "), err
    return lines[0]


@pytest.fixture
def data(tmp_path, monkeypatch):
    """A CSV in a folder with no experiments/ (the template comes from the package)."""
    monkeypatch.chdir(tmp_path)
    return write_csv(tmp_path / "data" / "device.csv")


# --- the two commands ---------------------------------------------------------------------

def test_init_then_evaluate_beats_the_prior(data, tmp_path):
    assert data == tmp_path / "data" / "device.csv"
    rc, out, err = run("init", "data/device.csv", *TARGET_ARGS, "--out", "configs/device.toml")
    assert rc == 0, err
    config = tmp_path / "configs" / "device.toml"
    assert "wrote configs/device.toml (84 training rows, 36 test rows)" in out
    assert "workbench evaluate configs/device.toml" in out and "workbench ui" in out
    text = config.read_text()
    assert text.startswith("# A first config for the data set 'device', written by "
                           "`workbench init` from data/device.csv")
    assert "#   workbench evaluate configs/device.toml\n#   workbench ui\n" in text
    cfg = load_config(config)  # the project's own parser
    assert cfg.name == "device" and cfg.random_state == 0
    assert cfg.data.csv == "../data/device.csv"  # relative to the config's folder
    assert (cfg.data.prior, cfg.data.targets, cfg.data.features) == (PRIOR, TARGETS, FEATURES)
    assert (cfg.data.test_fraction, cfg.data.split_seed, cfg.data.split_column) == (0.3, 0, None)

    rc, out, err = run("evaluate", config, "--no-track", "--no-intervals", "--json", "r.json")
    assert rc == 0, err
    result = json.loads((tmp_path / "r.json").read_text())
    assert result["n_train"] == 84 and result["n_test"] == 36
    assert result["model"]["test_mae_avg"] < 0.7 * result["prior"]["test_mae_avg"], result
    assert result["targets"] == TARGETS
    for model, prior in zip(result["model"]["test_mae"], result["prior"]["test_mae"]):
        assert model < prior


def test_the_template_comes_from_package_data(data, tmp_path):
    packaged = resources.files("workbench.experiment") / "templates" / "generic.toml"
    assert template_text() == packaged.read_text(encoding="utf-8")
    assert not (tmp_path / "experiments").exists()
    assert run("init", data, *TARGET_ARGS)[0] == 0
    text = (tmp_path / "device.toml").read_text()  # default --out: <name>.toml here
    assert text.endswith("\n\n" + template_text())  # copied as is, comments included
    template = tomllib.loads(template_text())
    raw = tomllib.loads(text)
    assert {k: v for k, v in raw.items() if k not in ("name", "random_state", "data")} \
        == template


def test_an_installed_package_carries_the_template(tmp_path):
    """setuptools' build (what a wheel holds) includes templates/generic.toml (package data
    in pyproject.toml), and the built package reads it with nothing else around."""
    src = tmp_path / "src"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(ROOT / name, src / name)
    shutil.copytree(ROOT / "workbench", src / "workbench",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    lib = tmp_path / "lib"
    subprocess.run([sys.executable, "-c", "from setuptools import setup; setup()", "-q",
                    "build_py", "--build-lib", str(lib)], cwd=src, check=True,
                   capture_output=True)
    built = lib / "workbench" / "experiment" / "templates" / "generic.toml"
    assert built.read_text() == template_text()
    code = ("import workbench.experiment.runs.init as m; print(m.__file__); "
            "print(len(m.template_text()))")
    env = {**os.environ, "PYTHONPATH": str(lib)}
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, check=True,
                         capture_output=True, text=True).stdout.split()
    assert Path(out[0]).is_relative_to(lib) and int(out[1]) == len(template_text())


# --- the options ----------------------------------------------------------------------------

def test_default_features_are_the_other_numeric_columns(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    n = 120
    gaps = np.arange(n, dtype=float)
    gaps[5] = np.nan
    csv = write_csv(tmp_path / "d.csv", n, flags=["yes"] * n, gappy=gaps,
                    row=np.arange(n))
    rc, out, err = run("init", csv, *TARGET_ARGS, "--split-column", "split")
    assert rc == 0, err
    cfg = load_config(tmp_path / "d.toml")
    assert cfg.data.features == [*FEATURES, "row"]  # file order; 'split' is the split
    assert ("features: v1, v2, v3, row (every other numeric column; not taken: 'device' (not "
            "numeric), 'flags' (not numeric), 'gappy' (missing or infinite values)") in out
    assert "'split'" not in out.splitlines()[0]

    # without a split column, the train/test column is just a non-numeric column
    rc, out, err = run("init", csv, *TARGET_ARGS, "--out", "random.toml")
    assert rc == 0, err
    assert "'split' (not numeric)" in out
    assert load_config(tmp_path / "random.toml").data.features == [*FEATURES, "row"]

    # explicit features: nothing chosen, nothing printed about them; --features alone: none
    rc, out, _ = run("init", csv, *TARGET_ARGS, "--features", "v2", "--out", "v2.toml")
    assert rc == 0 and "features:" not in out
    assert load_config(tmp_path / "v2.toml").data.features == ["v2"]
    assert run("init", csv, *TARGET_ARGS, "--features", "--out", "none.toml")[0] == 0
    assert load_config(tmp_path / "none.toml").data.features == []


def test_split_column(data, tmp_path):
    rc, out, err = run("init", data, *TARGET_ARGS, "--split-column", "split", "--name", "dev",
                       "--out", "s.toml")
    assert rc == 0, err
    assert "(90 training rows, 30 test rows)" in out
    raw = tomllib.loads((tmp_path / "s.toml").read_text())
    assert raw["name"] == "dev" and raw["data"]["split_column"] == "split"
    assert "test_fraction" not in raw["data"] and "split_seed" not in raw["data"]
    ds = load_dataset(load_config(tmp_path / "s.toml"))
    assert list(ds.test_index) == list(range(0, 120, 4))
    # --split-seed belongs to the random split
    rc, _, err = run("init", data, *TARGET_ARGS, "--split-column", "split", "--split-seed",
                     "1", "--out", "t.toml")
    assert rc == 2 and "--split-seed" in one_error_line(err)
    rc, _, err = run("init", data, *TARGET_ARGS, "--split-column", "split",
                     "--test-fraction", "0.2", "--out", "t.toml")
    assert rc == 2 and "not allowed with" in one_error_line(err)
    assert not (tmp_path / "t.toml").exists()


def test_group_column(data, tmp_path):
    """--group-column: written to [data], the dataset's groups (which CV folds keep whole)."""
    rc, out, err = run("init", data, *TARGET_ARGS, "--group-column", "device", "--out",
                       "g.toml")
    assert rc == 0, err
    raw = tomllib.loads((tmp_path / "g.toml").read_text())
    assert raw["data"]["group_column"] == "device" and "device" not in raw["data"]["features"]
    cfg = load_config(tmp_path / "g.toml")
    ds = load_dataset(cfg)
    assert set(ds.groups) == {"chip0", "chip1", "chip2"}
    rc, _, err = run("init", data, *TARGET_ARGS, "--group-column", "nope", "--out", "h.toml")
    assert rc == 2 and "nope" in one_error_line(err)
    assert not (tmp_path / "h.toml").exists()


def test_a_column_that_repeats_names_is_proposed_as_the_group_column(data, tmp_path):
    """Without --group-column, a text column whose values repeat (the device) is proposed,
    not forced: the config is written without it and the note says how to keep groups whole;
    the split column (two values) is not proposed, nor a column of unique names."""
    from workbench.experiment.splits.columns import group_columns

    assert group_columns(data, ["split"]) == {"device": 3}
    rc, out, err = run("init", data, *TARGET_ARGS, "--split-column", "split", "--out", "n.toml")
    assert rc == 0, err
    assert "note: column 'device' repeats 3 values" in out and "--group-column device" in out
    assert "group_column" not in tomllib.loads((tmp_path / "n.toml").read_text())["data"]
    rc, out, _ = run("init", data, *TARGET_ARGS, "--group-column", "device", "--out", "m.toml")
    assert rc == 0 and "note:" not in out
    unique = write_csv(tmp_path / "u.csv", run_id=[f"r{i}" for i in range(120)])
    assert "run_id" not in group_columns(unique, ["split"])


def test_test_fraction_and_seed(data, tmp_path):
    rc, out, err = run("init", data, *TARGET_ARGS, "--test-fraction", "0.25", "--split-seed",
                       "7", "--out", "f.toml")
    assert rc == 0, err
    cfg = load_config(tmp_path / "f.toml")
    assert (cfg.data.test_fraction, cfg.data.split_seed) == (0.25, 7)
    assert "(90 training rows, 30 test rows)" in out
    for bad in ("0", "1", "abc", "nan"):
        rc, _, err = run("init", data, *TARGET_ARGS, "--test-fraction", bad, "--out", "g.toml")
        assert rc == 2 and "--test-fraction" in one_error_line(err)
    rc, _, err = run("init", data, *TARGET_ARGS, "--split-seed", "-1", "--out", "g.toml")
    assert rc == 2 and "--split-seed" in one_error_line(err)
    assert not (tmp_path / "g.toml").exists()


def test_an_existing_config_is_kept_without_force(data, tmp_path):
    config = tmp_path / "device.toml"
    config.write_text("# mine\n")
    rc, out, err = run("init", data, *TARGET_ARGS)
    assert rc == 2 and out == ""
    assert one_error_line(err) == ("workbench: error: device.toml exists: nothing written "
                                   "(--force overwrites it)")
    assert config.read_text() == "# mine\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["data", "device.toml"]
    rc, out, err = run("init", data, *TARGET_ARGS, "--force")
    assert rc == 0, err
    assert load_config(config).data.targets == TARGETS
    rc, _, err = run("init", data, *TARGET_ARGS, "--out", "data")  # a folder
    assert rc == 2 and "is a directory" in one_error_line(err)
    rc, _, err = run("init", data, *TARGET_ARGS, "--out", "data/device.csv/x.toml")
    assert rc == 2 and "is a file, not a directory" in one_error_line(err)


# --- bad data: the loader's one line, nothing written -----------------------------------------

def _nan_cell(path: Path) -> Path:
    frame = pd.read_csv(path)
    frame.loc[10, "measured_E2"] = np.nan
    frame.to_csv(path, index=False)
    return path


@pytest.mark.parametrize("case", ["missing column", "NaN cell", "count mismatch",
                                  "missing file", "non-numeric feature"])
def test_bad_data_is_one_line_and_nothing_written(data, tmp_path, case):
    args = {"missing column": [data, "--prior", "model_E1", "model_EX", "--target", *TARGETS],
            "NaN cell": [_nan_cell(data), *TARGET_ARGS],
            "count mismatch": [data, "--prior", "model_E1", "--target", *TARGETS],
            "missing file": [tmp_path / "nope.csv", *TARGET_ARGS],
            "non-numeric feature": [data, *TARGET_ARGS, "--features", "v1", "device"]}[case]
    before = sorted(p.name for p in tmp_path.rglob("*"))
    rc, out, err = run("init", *args, "--out", "bad.toml")
    line = one_error_line(err)
    assert rc == 2 and out == ""
    assert sorted(p.name for p in tmp_path.rglob("*")) == before  # no file, no temporary
    expected = {"missing column": ["missing column(s) ['model_EX']", "the file has columns",
                                   "'device', 'v1'"],
                "NaN cell": ["NaN", "'measured_E2'", "line 12"],
                "count mismatch": ["1 prior column(s)", "2 target(s)"],
                "missing file": ["CSV file not found", "nope.csv"],
                "non-numeric feature": ["'device' has non-numeric values"]}[case]
    for needle in expected:
        assert needle in line, (needle, line)


@pytest.mark.parametrize("case", ["missing column", "NaN cell"])
def test_the_same_message_as_evaluate(data, tmp_path, case):
    """init's error line is the one evaluate gives for the config init would have written."""
    prior = ["model_E1", "model_EX"] if case == "missing column" else PRIOR
    if case == "NaN cell":
        _nan_cell(data)
    rc, _, init_err = run("init", data, "--prior", *prior, "--target", *TARGETS,
                          "--features", *FEATURES, "--out", "c.toml")
    assert rc == 2 and not (tmp_path / "c.toml").exists()
    (tmp_path / "c.toml").write_text(
        f'name = "device"\n[data]\ncsv = "data/device.csv"\nprior = {json.dumps(prior)}\n'
        f'targets = {json.dumps(TARGETS)}\nfeatures = {json.dumps(FEATURES)}\n'
        f'test_fraction = 0.3\n[model]\nbasis = "ridge"\n')
    rc, _, evaluate_err = run("evaluate", "c.toml", "--no-track")
    assert rc == 2 and one_error_line(init_err) == one_error_line(evaluate_err)


def test_too_few_training_rows_for_the_folds(tmp_path, monkeypatch):
    """evaluate's own data checks (the template's CV folds) run before writing."""
    monkeypatch.chdir(tmp_path)
    csv = write_csv(tmp_path / "small.csv", n=12)
    rc, _, err = run("init", csv, *TARGET_ARGS)
    assert rc == 2 and "too few for [selection] cv" in one_error_line(err)
    assert not (tmp_path / "small.toml").exists()


# --- paths, names and the template's layout -------------------------------------------------

def test_the_csv_path_is_relative_to_the_config_or_absolute(tmp_path, monkeypatch):
    csv = tmp_path / "a" / "b.csv"
    assert csv_entry(csv, tmp_path / "c" / "d" / "x.toml") == "../../a/b.csv"
    assert csv_entry(csv, tmp_path / "a" / "x.toml") == "b.csv"

    def other_drive(path, start=os.curdir):
        raise ValueError("path is on mount 'D:', start on mount 'C:'")

    monkeypatch.setattr(init_module.os.path, "relpath", other_drive)
    assert csv_entry(csv, tmp_path / "x.toml") == csv.resolve().as_posix()
    monkeypatch.chdir(tmp_path)
    write_csv(csv)
    assert run("init", csv, *TARGET_ARGS, "--out", "x.toml")[0] == 0
    cfg = load_config(tmp_path / "x.toml")
    assert cfg.data.csv == csv.resolve().as_posix()
    assert len(load_dataset(cfg).targets) == 120


def test_odd_column_names_are_written_as_toml_strings(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    csv = write_csv(tmp_path / "odd name.csv")
    frame = pd.read_csv(csv).rename(columns={"v1": 'v "1"', "v2": "v\\2", "v3": "λ 3"})
    frame.to_csv(csv, index=False)
    rc, out, err = run("init", csv, *TARGET_ARGS)
    assert rc == 0, err
    assert "workbench evaluate 'odd name.toml'" in out
    cfg = load_config(tmp_path / "odd name.toml")
    assert cfg.data.features == ['v "1"', "v\\2", "λ 3"]
    strings = ['a "b" \\ c', "tab\there", "line\nbreak", "\x00\x1f\x7f", "λ", ""]
    assert tomllib.loads("\n".join(f"k{i} = {toml_string(s)}"
                                   for i, s in enumerate(strings))) \
        == {f"k{i}": s for i, s in enumerate(strings)}


def test_template_keys_outside_tables_stay_top_level(data, tmp_path, monkeypatch):
    template = ('# the template\nn_jobs = 1   # one process\n\n# the model\n[model]\n'
                'basis = "ridge"\n[selection]\ncv = 3\n')
    top, rest = split_template(template)
    assert top == "# the template\nn_jobs = 1   # one process\n\n"
    assert rest == '# the model\n[model]\nbasis = "ridge"\n[selection]\ncv = 3\n'
    assert split_template(template_text()) == ("", template_text())
    tricky = 'description = """\n[not a table]\n"""\n[model]\nbasis = "ridge"\n'
    assert split_template(tricky)[1] == '[model]\nbasis = "ridge"\n'
    monkeypatch.setattr(init_module, "template_text", lambda: template)
    assert run("init", data, *TARGET_ARGS)[0] == 0
    cfg = load_config(tmp_path / "device.toml")
    assert cfg.n_jobs == 1 and cfg.selection.cv == 3 and cfg.data.features == FEATURES
    # a template setting what init writes is refused (a bug of the template: one line)
    monkeypatch.setattr(init_module, "template_text", lambda: '[data]\ncsv = "x.csv"\n')
    rc, _, err = run("init", data, *TARGET_ARGS, "--out", "bad.toml")
    assert rc == 2 and "template generic.toml sets ['data']" in one_error_line(err)
    assert not (tmp_path / "bad.toml").exists()


def test_init_help_loads_no_heavy_library():
    code = ("import sys\nfrom workbench.experiment.cli import main\ntry:\n"
            "    main(['init', '--help'])\nexcept SystemExit:\n    pass\n"
            "print(sorted({m.split('.')[0] for m in sys.modules} & "
            "{'mlflow', 'optuna', 'shap', 'sklearn', 'lightgbm', 'pandas'}))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert "--split-column" in out and out.strip().endswith("[]")


def test_the_user_guide_s_two_commands(tmp_path, monkeypatch):
    """The user guide's "Your own data" page opens with init and evaluate; init, as written
    there, writes the config the evaluate line names."""
    page = (ROOT / "docs" / "user_guide" / "own_data.md").read_text()
    section = page.split("# Your own data: a CSV and a config", 1)[1]
    block = re.search(r"```sh\n(.*?)```", section, flags=re.S)
    assert block and block.start() < section.index("```toml")  # the commands come first
    init_line, evaluate_line = block.group(1).strip().splitlines()
    init_argv, evaluate_argv = shlex.split(init_line), shlex.split(evaluate_line)
    assert init_argv[:2] == ["workbench", "init"] and evaluate_argv[:2] == ["workbench",
                                                                              "evaluate"]
    monkeypatch.chdir(tmp_path)
    write_csv(tmp_path / init_argv[2])
    rc, out, err = run(*init_argv[1:])
    assert rc == 0, err
    assert f"next: workbench evaluate {evaluate_argv[2]}" in out
    load_dataset(load_config(tmp_path / evaluate_argv[2]))


@pytest.mark.parametrize("options", [
    [],                                               # features, order and groups found
    ["--group-column", "device"],                     # groups given
    ["--split-column", "split", "--features", *FEATURES],
    ["--order-column", "date", "--split-seed", "3"],  # an order column, a random split
])
def test_init_reads_the_csv_once(tmp_path, monkeypatch, options):
    """One read of the CSV per ``init``, however many steps look at it (the loader's checks,
    the features, the order and group columns, the config's own load); the dataset it
    reports is the one ``evaluate`` loads."""
    monkeypatch.chdir(tmp_path)
    dates = pd.date_range("2024-01-01", periods=120, freq="D").strftime("%Y-%m-%d")
    path = write_csv(tmp_path / "d.csv", date=list(dates))
    real, reads = pd.read_csv, []

    def counted(source, *args, **kwargs):
        reads.append(Path(source).resolve())
        return real(source, *args, **kwargs)

    monkeypatch.setattr(pd, "read_csv", counted)
    done = init_module.init_config(path, prior=PRIOR, targets=TARGETS, out="c.toml",
                                   **_init_options(options))
    assert reads == [path.resolve()]
    ds = load_dataset(load_config(tmp_path / "c.toml"))  # outside init: a read of its own
    assert len(reads) == 2
    assert (done.n_train, done.n_test) == (len(ds.train_index), len(ds.test_index))


def _init_options(argv: list[str]) -> dict:
    """``init``'s command-line options as :func:`init_config`'s keywords."""
    out, key = {}, None
    for item in argv:
        if item.startswith("--"):
            key = item[2:].replace("-", "_")
            out[key] = [] if key == "features" else None
        elif key == "features":
            out[key].append(item)
        else:
            out[key] = int(item) if key == "split_seed" else item
    return out


def test_read_once_reuses_a_file_only_inside_its_block(tmp_path, monkeypatch):
    from workbench.datasets import read_csv_cells, read_once

    path = write_csv(tmp_path / "d.csv")
    real, reads = pd.read_csv, []
    monkeypatch.setattr(pd, "read_csv", lambda *a, **k: reads.append(1) or real(*a, **k))
    with read_once():
        first = read_csv_cells(path)
        assert read_csv_cells(path) is first and len(reads) == 1
    read_csv_cells(path)
    assert len(reads) == 2
