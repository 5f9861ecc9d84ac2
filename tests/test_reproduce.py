"""workbench reproduce --quick --all: every manifest entry, the report, numbers that agree
everywhere; and what ``make run`` (no ``--all``) leaves out."""

import contextlib
import csv
import dataclasses
import importlib
import io
import json
import re
import warnings

import matplotlib.image
import pytest

from workbench.datasets import SOURCES, register_source
from workbench.experiment.cli import main
from workbench.experiment.paper.gates import GATE_SYSTEMS
from workbench.experiment.paper.systems import SYSTEMS

# the module (the package's name ``reproduce`` is the function)
reproduce_module = importlib.import_module("workbench.experiment.paper.reproduce")
#: The fixture's calls of the report and the systems' catalogue: name -> [(args, kwargs)].
CALLS: dict[str, list] = {}

FIGURE_IDS = ["fig2_mae_bars", "fig3_correlation", "fig4_learning_curve_Y3", "fig5_shap_Y1",
              "figS2_voltage_boxplots", "figS3_prior_target_boxplots", "figS4_mse_bars",
              "figS5_learning_curves", "figS6_tabula_rasa_mae", "figS7_tabula_rasa_mse",
              "figS8_shap", "figH1_hamiltonian_mae_bars", "figH2_parameter_corrections",
              "figH3_selection_path", "figR1_systems_mae", "figR2_shap_correction",
              "figR3_shap_prediction", "figG1_gates_mae"]


def _counted(load, log):
    """``load``, writing the source's name to the file ``log`` at each call (worker processes
    count too)."""
    def counted(options, base, name):
        dataset = load(options, base, name)
        with open(log, "a") as fh:
            fh.write(f"{dataset.name}\n")
        return dataset

    return counted


def _recorded(func, calls):
    """``func``, appending each call's ``(args, kwargs)`` to ``calls``."""
    def recorded(*args, **kwargs):
        calls.append((args, kwargs))
        return func(*args, **kwargs)

    return recorded


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory, google_5q_dir, ibm_gates_dir):
    """One ``reproduce --quick --all``: every system, the search and the IBM benchmark too."""
    root = tmp_path_factory.mktemp("reproduce")
    uri = f"sqlite:///{root / 'store' / 'mlflow.db'}"
    output = io.StringIO()
    with pytest.MonkeyPatch.context() as mp, contextlib.redirect_stdout(output), \
            contextlib.redirect_stderr(output), warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")  # what a user's terminal would show, recorded:
        for hidden in (DeprecationWarning, PendingDeprecationWarning, ImportWarning,
                       ResourceWarning):  # Python's default filters hide these
            warnings.simplefilter("ignore", hidden)
        mp.setenv("WORKBENCH_DATA_DIR", str(google_5q_dir))
        mp.chdir(root)  # the search's journal lands here
        for name in ("google_5q", "ibm_gates"):
            mp.setitem(SOURCES, name, SOURCES[name])  # restored after the run
            register_source(name, _counted(SOURCES[name].load, root / "loads.txt"))
        for name in ("report", "paper_systems"):  # what they were given, for the tests
            mp.setattr(reproduce_module, name,
                       _recorded(getattr(reproduce_module, name), CALLS.setdefault(name, [])))
        assert main(["reproduce", "--quick", "--all", "--out", str(root / "reports"),
                     "--tracking-uri", uri]) == 0
    shown = "".join(f"{w.category.__name__}: {w.message}\n" for w in caught)
    (root / "output.txt").write_text(output.getvalue() + shown)  # what the user saw
    return root / "reports", uri


def test_every_figure_is_written(quick_run):
    out, _ = quick_run
    manifest = json.loads((out / "manifest.json").read_text())
    assert sorted(manifest) == sorted(FIGURE_IDS)
    for files in manifest.values():
        files = [files] if isinstance(files, str) else files
        for f in files:
            assert matplotlib.image.imread(out / f).size > 0, f
    assert len(manifest["figS5_learning_curves"]) == len(manifest["figS8_shap"]) == 5


def test_each_dataset_is_loaded_once(quick_run):
    """The Google benchmark's systems (paper, improved, search, hamiltonian) share one load;
    the IBM gates, one more."""
    out, _ = quick_run
    loads = (out.parent / "loads.txt").read_text().split("\n")[:-1]
    assert len(loads) == 2 and len(set(loads)) == 2, loads


def test_progress_and_the_final_count(quick_run):
    """Every phase shows progress (a line per trial of the search), no library warning leaks,
    and the last line counts the figure files written."""
    out, _ = quick_run
    text = (out.parent / "output.txt").read_text()
    assert "[paper_search" in text and " trial " in text  # the search's per-trial lines
    assert "Warning" not in text, [line for line in text.splitlines() if "Warning" in line]
    written = len(list((out / "figures").glob("*.png")))
    assert f"and {written} figures (of {len(FIGURE_IDS)} numbered figures)" in text


def test_report_and_numbers(quick_run):
    out, uri = quick_run
    res = json.loads((out / "results.json").read_text())
    paper = res["settings"]["paper"]
    assert paper["model"]["test_mae_avg"] <= 1.10
    assert all(m < p for m, p in zip(paper["model"]["test_mae"], paper["prior"]["test_mae"]))
    text = (out / "README.md").read_text()
    assert f"**{paper['model']['test_mae_avg']:.3f}**" in text
    assert res["random_state"] == 0 and "(random_state 0)" in text  # one name per seed
    manifest = json.loads((out / "manifest.json").read_text())
    for fig_id, files in manifest.items():  # shown in the report, or named there (a panel)
        for f in [files] if isinstance(files, str) else files:
            assert f in text, (fig_id, f)
    # Fig. 4 and Fig. 5 are panels of S5 and S8, drawn once
    assert manifest["fig4_learning_curve_Y3"] == "figures/figS5_learning_curve_Y3.png"
    assert manifest["fig5_shap_Y1"] == "figures/figS8_shap_Y1.png"
    tabula = res["tabula_rasa"]
    assert len(tabula["seeds"]) == len(tabula["test_mae_avg_per_seed"]) == 3  # --quick
    assert tabula["test_mae_avg_min"] <= tabula["test_mae_avg"] <= tabula["test_mae_avg_max"]
    assert 5 < tabula["test_mae_avg"] < 16  # the reference measured about 11
    assert f"{tabula['test_mae_avg']:.1f} MHz average test MAE, the mean of 3" in text
    # 95% intervals in the table: the paper settings' average, and its gain over the prior
    m = paper["model"]
    low, high = m["test_mae_avg_ci"]
    assert low < m["test_mae_avg"] < high
    assert f"**{m['test_mae_avg']:.3f}** ({low:.2f}-{high:.2f})" in text
    gain = m["test_mae_diff_avg_ci"]
    assert gain[1] < 0 and f"{gain[0]:+.2f} to {gain[1]:+.2f}" in text
    assert "What base boosting learned: SHAP of the correction" in text
    ham = res["settings"]["hamiltonian"]
    assert ham["family"] == "hamiltonian"
    assert ham["model"]["test_mae_avg"] < ham["prior"]["test_mae_avg"]
    assert f"**{ham['model']['test_mae_avg']:.3f}**" in text  # the report's table row
    assert "Repeated CV of the chosen model" in text
    assert "`workbench evaluate experiments/hamiltonian.toml` computes it" in text
    for name, path in res["hamiltonian_tables"].items():
        assert (out / path).is_file() and f"[{name}]({path})" in text
    # learning-curve sizes are rows actually used, never more than 5-fold CV can train on
    lc = res["learning_curves"]
    assert max(lc["train_sizes"]) <= 76
    for curve in lc["curves"].values():
        assert curve["n_train_rows"] == [[s] * lc["folds"] for s in lc["train_sizes"]]


def test_readme_results_are_the_reproduction_s(quick_run):
    """README.md's results are benchmarks/tables.py's rendering of results.json: the rows
    ``--quick`` computes as ``make run`` does are this run's, the others have their place."""
    import importlib.util
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    out, _ = quick_run
    res = json.loads((out / "results.json").read_text())
    spec = importlib.util.spec_from_file_location("bench_tables", root / "benchmarks" /
                                                  "tables.py")
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    text = (root / "README.md").read_text()
    block = text[text.index("<!-- results -->"):text.index("<!-- /results -->")]

    def rows(text):
        return {cells[0]: cells[1:] for line in text.splitlines() if line.startswith("| ")
                for cells in [[c.strip() for c in line.strip("|").split("|")]]}

    made, shown = rows(tables.readme_results(res)), rows(block)
    assert made.keys() == shown.keys()
    for row in tables.QUICK_ROWS:
        assert shown[row] == made[row], row
    # the report says no machine timing (results.json keeps wall_s)
    report = (out / "README.md").read_text()
    assert not re.search(r"\d+(\.\d+)? ?(s|seconds|minutes)\b", report), "a timing in the report"


def test_without_all_the_report_says_how_to_get_the_search_and_ibm(quick_run):
    """``make run`` (no ``--all``): no search row, no IBM section or JSON, the report names
    ``reproduce --all``; README.md's IBM paragraph keeps its last ``--all`` values."""
    import importlib.util
    from pathlib import Path

    from workbench.experiment.paper import report

    [((rep,), _)] = CALLS["report"]
    assert rep.all_systems and "search" in rep.settings and rep.gates is not None
    default = dataclasses.replace(
        rep, all_systems=False, gates=None,
        settings={k: v for k, v in rep.settings.items() if k != "search"})
    text = report(default)
    assert "Generated by `workbench reproduce` (quick" in text
    assert "`workbench reproduce --all` adds them" in text
    assert "nested-CV search (this run)" not in text
    assert "## A second benchmark" not in text and "figG1" not in text
    assert "nested-CV search (this run)" in report(rep)  # the --all run's own report
    res = default.to_json()
    assert res["all"] is False and "ibm_gates" not in res and "search" not in res["settings"]
    # the catalogue without the search: its other systems, in order
    [(args, kwargs)] = CALLS["paper_systems"]
    systems = reproduce_module.paper_systems(*args[:3], None, *args[4:], **kwargs)
    assert [s.key for s in systems] == [k for k in SYSTEMS if k != "search"]
    root = Path(__file__).resolve().parents[1]
    spec = importlib.util.spec_from_file_location("bench_tables", root / "benchmarks" /
                                                  "tables.py")
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    readme = (root / "README.md").read_text()
    block = readme[readme.index("<!-- results -->"):readme.index("<!-- /results -->")]
    kept = block[block.index(tables.GATES_PARAGRAPH):].strip()
    assert "`workbench reproduce --all`" in kept
    assert tables.readme_results(res, block).endswith(kept)
    made = tables.readme_results(rep.to_json(), block)  # --all: remade from its own JSON
    assert tables.readme_gates(rep.to_json()["ibm_gates"]) in made


def test_figures_show_the_json_numbers_and_mlflow_has_them(quick_run, tmp_path):
    from mlflow import MlflowClient

    from workbench.experiment.figures import mae_bars, save_figure

    out, uri = quick_run
    res = json.loads((out / "results.json").read_text())
    paper = res["settings"]["paper"]
    redrawn = save_figure(mae_bars(res["short"], paper["prior"]["test_mae"],
                                   paper["model"]["test_mae"],
                                   prior_ci=[*paper["prior"]["test_mae_ci"],
                                             paper["prior"]["test_mae_avg_ci"]],
                                   model_ci=[*paper["model"]["test_mae_ci"],
                                             paper["model"]["test_mae_avg_ci"]],
                                   unit=res["unit"], title="Test MAE per eigenenergy (Fig. 2)",
                                   labels=("control program", "base boosting"),
                                   setting="paper settings"), tmp_path / "fig2.png")
    assert redrawn.read_bytes() == (out / "figures" / "fig2_mae_bars.png").read_bytes()
    client = MlflowClient(uri)
    run = client.get_run(res["mlflow"]["run_id"])
    assert run.data.metrics["wall_s"] == pytest.approx(res["wall_s"])
    assert client.get_experiment(run.info.experiment_id).name == "paper-reproduction"
    children = {c.info.run_name: c for c in client.search_runs(
        [run.info.experiment_id], f"tags.mlflow.parentRunId = '{run.info.run_id}'")}
    assert set(children) == {name for name, _ in SYSTEMS.values()} | {"IBM two-qubit gates"}
    targets = res["targets"]
    rows = {row["system"]: row
            for row in csv.DictReader((out / "systems.csv").read_text().splitlines())}
    for key, (name, _) in SYSTEMS.items():
        child = children[name]
        assert child.data.tags["workbench.system"] == key
        assert res["mlflow"][f"run_id.{key}"] == child.info.run_id
        # one metric schema: the dataset's target names, the keys of `workbench evaluate`
        maes = [child.data.metrics[f"test_mae/{t}"] for t in targets]
        assert child.data.metrics["test_mae_avg"] == pytest.approx(sum(maes) / len(maes))
        assert float(rows[name]["average"]) == pytest.approx(
            child.data.metrics["test_mae_avg"], abs=1e-4)
        assert {d.dataset.name for d in child.inputs.dataset_inputs} == {"google_5q"}
        # its true duration, inside the parent's
        assert run.info.start_time <= child.info.start_time <= child.info.end_time \
            <= run.info.end_time
    paper_run = children[SYSTEMS["paper"][0]]
    assert [paper_run.data.metrics[f"test_mae/{t}"] for t in targets] == pytest.approx(
        paper["model"]["test_mae"])
    assert [children[SYSTEMS["prior"][0]].data.metrics[f"test_mae/{t}"]
            for t in targets] == pytest.approx(paper["prior"]["test_mae"])
    assert paper_run.info.end_time - paper_run.info.start_time > 1000  # fits, curves: seconds
    assert paper_run.data.metrics["test_mae_avg_ci_low"] == pytest.approx(
        paper["model"]["test_mae_avg_ci"][0])
    assert "figures/figR2_shap_correction_Y1.png" in {
        a.path for a in client.list_artifacts(paper_run.info.run_id, "figures")}
    ham = res["settings"]["hamiltonian"]
    assert children[SYSTEMS["hamiltonian"][0]].data.metrics["test_mae_avg"] == pytest.approx(
        ham["model"]["test_mae_avg"])
    tabula = children[SYSTEMS["tabula_rasa"][0]]
    assert tabula.data.metrics["test_mae_avg"] == pytest.approx(res["tabula_rasa"]["test_mae_avg"])
    artifacts = {a.path for a in client.list_artifacts(paper_run.info.run_id, "figures")}
    assert "figures/fig2_mae_bars.png" in artifacts
    assert "paper_main_body.toml" in {a.path for a in client.list_artifacts(paper_run.info.run_id)}
    search = children[SYSTEMS["search"][0]]
    folds = client.search_runs([run.info.experiment_id],
                               f"tags.mlflow.parentRunId = '{search.info.run_id}'")
    assert folds and all(f.data.tags["workbench.kind"] == "outer_fold" for f in folds)
    # the second benchmark: its systems under their own parent, the same metric schema
    second = children["IBM two-qubit gates"]
    gate_runs = {c.info.run_name: c for c in client.search_runs(
        [run.info.experiment_id], f"tags.mlflow.parentRunId = '{second.info.run_id}'")}
    assert set(gate_runs) == {name for name, _ in GATE_SYSTEMS.values()}
    gates = res["ibm_gates"]
    gate_rows = {row["system"]: row for row in csv.DictReader(
        (out / "systems_ibm_gates.csv").read_text().splitlines())}
    expected = {"gates_prior": gates["generic"]["prior"]["test_mae_avg"],
                "gates_peer": gates["peer"]["model"]["test_mae_avg"],
                "gates_generic": gates["generic"]["model"]["test_mae_avg"]}
    for key, (name, _) in GATE_SYSTEMS.items():
        child = gate_runs[name]
        assert child.data.tags["workbench.system"] == key
        assert child.data.metrics["test_mae/gate_error"] == pytest.approx(expected[key])
        assert float(gate_rows[name]["average"]) == pytest.approx(expected[key], abs=1e-4)
        assert {d.dataset.name for d in child.inputs.dataset_inputs} == {"ibm_gates"}


def test_second_benchmark_in_the_report(quick_run):
    """The IBM gates: prior, peer and generic config with intervals, in the report."""
    out, _ = quick_run
    res = json.loads((out / "results.json").read_text())
    gates = res["ibm_gates"]
    text = (out / "README.md").read_text()
    assert "## A second benchmark: IBM two-qubit gates" in text
    # each benchmark's errors in its data's unit
    assert res["unit"] == "MHz" and "## Test mean absolute error (MHz)" in text
    assert gates["generic"]["unit"] == gates["peer"]["unit"] == "%"
    generic, peer = gates["generic"], gates["peer"]
    assert generic["n_train"] == 1935 and generic["n_test"] == 4713
    assert generic["prior"]["test_mae_avg"] == pytest.approx(0.5779, abs=1e-4)
    assert peer["prior"]["test_mae_avg"] == pytest.approx(generic["prior"]["test_mae_avg"])
    for scores in (generic["prior"], peer["model"], generic["model"]):
        low, high = scores["test_mae_avg_ci"]
        assert low < scores["test_mae_avg"] < high
        assert f"**{scores['test_mae_avg']:.3f}** ({low:.2f}-{high:.2f})" in text
    low, high = gates["generic_minus_peer_test_mae_avg_ci"]
    assert f"{low:+.3f} to {high:+.3f}" in text
    assert len(gates["peer_params"]) == 1 and "n_estimators" in gates["peer_params"][0]
    assert gates["generic_chosen"] and gates["generic_chosen"][0] in text


@pytest.mark.slow  # a second whole reproduction; determinism is also unit-tested (figures,
# configs, the parameter-space model) in the default suite
def test_same_seed_same_numbers_and_figures(quick_run, tmp_path, google_5q_dir, monkeypatch):
    out, _ = quick_run
    monkeypatch.setenv("WORKBENCH_DATA_DIR", str(google_5q_dir))
    monkeypatch.chdir(tmp_path)  # a fresh search storage: the search is redone, not resumed
    assert main(["reproduce", "--quick", "--out", str(tmp_path / "again"), "--no-track"]) == 0
    first = json.loads((out / "results.json").read_text())
    second = json.loads((tmp_path / "again" / "results.json").read_text())
    for key in ("settings", "tabula_rasa", "correlation", "learning_curves"):
        a, b = json.dumps(first[key], sort_keys=True), json.dumps(second[key], sort_keys=True)
        if key == "settings":  # wall times differ, numbers must not
            a, b = (json.dumps(_without_wall(json.loads(x)), sort_keys=True) for x in (a, b))
        assert a == b, key
    for files in first["figures"].values():
        for f in files:
            assert (out / f).read_bytes() == (tmp_path / "again" / f).read_bytes(), f


def _without_wall(obj):
    if isinstance(obj, dict):
        return {k: _without_wall(v) for k, v in obj.items()
                if k not in ("wall_s", "config", "seconds")}
    if isinstance(obj, list):
        return [_without_wall(v) for v in obj]
    return obj


def test_quick_studies_are_not_the_full_runs(quick_run):
    """--quick searches other folds with another budget: its studies have names of their
    own, so a later full run (same seed, same storage) does not resume them."""
    out, _ = quick_run
    import optuna

    from workbench.experiment.storage import open_storage

    root = out.parent
    names = optuna.get_all_study_names(open_storage("mlruns/optuna.journal", root))
    assert names and all("-seed0-quick" in n for n in names)


def test_reproduce_without_its_configs_is_one_line(tmp_path, capsys, monkeypatch):
    """An installed wheel carries no experiments/: the configs' folder is named, not a
    traceback, and nothing is written."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "cfg").mkdir()
    (tmp_path / "cfg" / "paper_main_body.toml").write_text("")
    assert main(["reproduce", "--experiments", "cfg", "--out", "r", "--no-track"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and len(err) < 300, err
    assert "cfg/" in err and "paper_improved.toml" in err and "--experiments" in err, err
    assert "paper_main_body.toml" not in err  # present: not listed as missing
    assert not (tmp_path / "r").exists()


def test_compare_two_reproduction_runs(quick_run, capsys):
    """``workbench compare`` on the reproduction's paper-settings and control-program runs:
    their test MAEs as results.json has them, and a paired interval per target."""
    out, uri = quick_run
    res = json.loads((out / "results.json").read_text())
    ids = res["mlflow"]
    assert main(["compare", ids["run_id.paper"], ids["run_id.prior"], "--tracking-uri",
                 uri]) == 0
    text = capsys.readouterr().out
    lines = {line.split()[0]: line.split() for line in text.splitlines()[2:]}
    paper = res["settings"]["paper"]
    for i, target in enumerate(res["targets"]):
        a, b = float(lines[target][1]), float(lines[target][2])
        assert a == pytest.approx(paper["model"]["test_mae"][i], abs=5e-4)
        assert b == pytest.approx(paper["prior"]["test_mae"][i], abs=5e-4)
    assert "paired bootstrap interval of a - b" in text and "average" in lines
