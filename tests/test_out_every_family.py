"""``evaluate --out DIR`` writes every figure, table and data file the run logs, for every
family: the MAE/MSE bars, the intervals' figure and table, the family's own tables and
figures and its run figures (the eigenvalue family's learning curves and SHAP summaries),
also for the eigenvalue family without intervals (issue 44)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.experiment.cli import main
from workbench.experiment.runs.evaluate import evaluate
from workbench.experiment.runs.prepare import load_config
from workbench.experiment.runs.run_outputs import computed_outputs
from workbench.simulate import simulate, write_simulation

DECAY = """import numpy as np

PARAMETERS = {"amplitude": 2.0, "tau": 1.0, "offset": 0.0}


def predict(params, data):
    t = data["t"].to_numpy()
    return params["amplitude"] * np.exp(-t / params["tau"]) + params["offset"]
"""


def _eigenvalue(folder: Path) -> str:
    """48 rows, 2 targets, one ridge stage."""
    rng = np.random.default_rng(0)
    n = 48
    f = rng.normal(size=(n, 2))
    prior = rng.normal(size=(n, 2)) * 3
    y = prior + 0.5 * f[:, [0]] - 0.3 * f[:, [1]] ** 2 + rng.normal(scale=0.1, size=(n, 2))
    pd.DataFrame({"f1": f[:, 0], "f2": f[:, 1], "p1": prior[:, 0], "p2": prior[:, 1],
                  "y1": y[:, 0], "y2": y[:, 1]}).to_csv(folder / "data.csv", index=False)
    return ('[data]\ncsv = "data.csv"\nprior = ["p1", "p2"]\ntargets = ["y1", "y2"]\n'
            'features = ["f1", "f2"]\ntest_fraction = 0.25\n[model]\nbasis = "ridge"\n')


def _hamiltonian(folder: Path) -> str:
    """A simulated 3-site chain, 60 experiments; a short selection."""
    write_simulation(simulate(3, 60, device_seed=1), folder / "device.csv")
    return ('[data]\ncsv = "device.csv"\n'
            'prior = ["model_E1", "model_E2", "model_E3"]\n'
            'targets = ["measured_E1", "measured_E2", "measured_E3"]\n'
            'features = ["v_q1", "v_q2", "v_q3", "v_c1", "v_c2"]\ntest_fraction = 0.3\n'
            '[data.hamiltonian]\nonsite = ["model_f1", "model_f2", "model_f3"]\n'
            'couplings = ["model_g1", "model_g2"]\nsign = -1\n'
            'qubit_features = ["v_q1", "v_q2", "v_q3"]\ncoupler_features = ["v_c1", "v_c2"]\n'
            '[model]\nfamily = "hamiltonian"\nbasis = "ridge"\n'
            'basis_inputs = "prior+features"\ninput_transform = "standard"\n'
            '[model.hamiltonian]\ncandidates = "local"\nmax_steps = 2\nselection_cv = 3\n'
            '[selection]\ncv = 3\n')


def _parametric(folder: Path) -> str:
    """A decay whose lifetime drifts with temperature; the model file is the prior."""
    rng = np.random.default_rng(0)
    n = 70
    t, temp = rng.uniform(0, 3, n), rng.normal(size=n)
    y = 2.5 * np.exp(-t / (1.5 + 0.3 * temp)) + 0.1 + rng.normal(0, 0.01, n)
    pd.DataFrame({"t": t, "temp": temp, "y": y}).to_csv(folder / "decay.csv", index=False)
    (folder / "decay.py").write_text(DECAY)
    return ('[data]\ncsv = "decay.csv"\ntargets = ["y"]\nfeatures = ["t", "temp"]\n'
            'test_fraction = 0.3\n[model]\nfamily = "parametric"\n'
            '[model.parametric]\nmodel = "decay.py"\nmax_steps = 1\nproducts = false\n'
            'boost_stage = false\n')


FAMILIES = {"eigenvalue": _eigenvalue, "hamiltonian": _hamiltonian,
            "parametric": _parametric}


def test_every_family_of_the_workbench_is_here():
    """A new family of the workbench's own gets its ``--out`` check (plug-ins not counted)."""
    from workbench.experiment.families import FAMILIES as REGISTRY
    from workbench.experiment.families import discover_families

    discover_families()
    own = {name for name, family in REGISTRY.items()
           if type(family).__module__.startswith("workbench.experiment.families.")}
    assert own == set(FAMILIES)


def _config(folder: Path, family: str, intervals: bool) -> Path:
    path = folder / f"{family}.toml"
    path.write_text(f'name = "{family}"\nrandom_state = 0\nn_jobs = 1\n'
                    + FAMILIES[family](folder)
                    + ("" if intervals else "[intervals]\nenabled = false\n"))
    return path


@pytest.mark.parametrize("family", sorted(FAMILIES))
def test_out_writes_what_the_run_logs(family, tmp_path):
    """Every figure, table and data file a tracked run logs is a file in ``--out``."""
    cfg = load_config(_config(tmp_path, family, intervals=True))
    run = evaluate(cfg, return_model=True)
    with computed_outputs(cfg, run.result, run.model, run.dataset, setting="s",
                          out=tmp_path / "out") as computed:
        written = {p.name for p in (tmp_path / "out").iterdir()}
        logged = ({Path(a).name for a in computed.figures}
                  | {Path(a).name for a in computed.tables}
                  | set(computed.data))
        assert logged and logged <= written, sorted(logged - written)
        for name in computed.figures:  # the run logs the file --out wrote
            assert computed.files[name] == tmp_path / "out" / Path(name).name, name
    assert {"mae_bars.png", "mse_bars.png", "intervals.png", "test_intervals.csv"} <= written
    for name in written - {n for n in written if n.endswith((".png", ".csv"))}:
        json.loads((tmp_path / "out" / name).read_text())  # data files are JSON


def test_eigenvalue_out_without_intervals(tmp_path, capsys):
    """The eigenvalue family without intervals: ``--out`` is not refused; it writes the bars,
    the learning curves and the SHAP summaries, without tracking."""
    path = _config(tmp_path, "eigenvalue", intervals=False)
    out = tmp_path / "out"
    assert main(["evaluate", str(path), "--no-track", "--out", str(out),
                 "--json", str(tmp_path / "r.json")]) == 0
    written = sorted(p.name for p in out.iterdir())
    assert {"mae_bars.png", "mse_bars.png"} <= set(written)
    for target in ("y1", "y2"):
        assert any(target in n and "curve" in n for n in written), written
        assert any(n.startswith("shap") and target in n for n in written), written
    assert not any(n.startswith("intervals") for n in written)
    result = json.loads((tmp_path / "r.json").read_text())
    assert sorted(Path(p).name for p in result["outputs"].values()) == written
    assert "wrote " in capsys.readouterr().out
