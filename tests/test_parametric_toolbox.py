"""experiments/parametric_transmon.toml: a user's model that calls scqubits (the optional
extra ``toolbox``, which the dev extra includes), through family = "parametric"."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("scqubits", reason="the optional extra toolbox (pip install "
                    "'workbench[toolbox]') is not installed: the transmon example needs scqubits")

from workbench.experiment.cli import main  # noqa: E402
from workbench.parametric import ParametricModel, load_model  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "experiments" / "parametric_transmon.toml"
MODEL = ROOT / "experiments" / "models" / "transmon_scqubits.py"
DATA = ROOT / "experiments" / "datasets" / "transmon_flux.csv"


def test_the_jacobian_is_the_spectrum_s_derivative():
    """The file's Hellmann-Feynman jacobian agrees with central finite differences of its
    own predict, at parameters off the start values."""
    model = load_model(MODEL)
    data = pd.read_csv(DATA).iloc[:12]
    theta = model.start(data) + np.array([0.7, -0.01, 0.03, 0.04])
    by_differences = ParametricModel.from_functions(model.parameters, model.predict_fn)
    np.testing.assert_allclose(model.jacobian(theta, data, 2),
                               by_differences.jacobian(theta, data, 2), rtol=1e-5, atol=1e-5)


def test_the_committed_data_are_what_the_script_makes():
    import importlib.util

    spec = importlib.util.spec_from_file_location("transmon_flux", DATA.with_suffix(".py"))
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    pd.testing.assert_frame_equal(script.simulate(), pd.read_csv(DATA), atol=1e-4)


def test_the_transmon_config_learns_the_drift(tmp_path, monkeypatch):
    """Reduced (half the rows, one selection step from two candidates, 3 folds, no stage;
    the shipped config otherwise): the drift the data were made with (the junctions age:
    EJmax falls with the day) is found, and the corrected model is near the 2 MHz noise
    while the design values are far off. ``--out`` writes the family's tables (its
    learning curve and SHAP summaries left out: three quarters of this test's CPU, the
    family's code checked on its decay model by test_parametric_family.py's tracked run)."""
    from workbench.experiment.families import Artifacts
    from workbench.experiment.families.parametric import ParametricFamily

    monkeypatch.setattr(ParametricFamily, "begin_artifacts",
                        lambda *args, **kwargs: lambda emit=None: Artifacts())
    pd.read_csv(DATA).iloc[:45].to_csv(tmp_path / "transmon.csv", index=False)  # half: cost
    config = tmp_path / "transmon.toml"
    config.write_text(CONFIG.read_text()
                      .replace('"datasets/transmon_flux.csv"', '"transmon.csv"')
                      .replace('"models/transmon_scqubits.py"', repr(str(MODEL))))
    out = tmp_path / "result.json"
    assert main(["evaluate", str(config), "--no-track", "--no-intervals", "--jobs", "1",
                 "--json", str(out), "--out", str(tmp_path / "tables"),
                 "--set", "model.parametric.max_steps=1",
                 "--set", "model.parametric.selection_cv=3",
                 "--set", "model.parametric.boost_stage=false",
                 "--set", "model.parametric.prior_cv=2",
                 "--set", 'model.parametric.candidates={EJmax = ["day"], d = ["day"]}',
                 "--set", 'model.parametric.start={flux_offset = ["day"]}']) == 0
    result = json.loads(out.read_text())
    info = result["parametric"]
    assert info["choice"] == "drift"
    assert [(s["parameter"], s["covariate"]) for s in info["selection"]["path"][1:]] == [
        ("EJmax", "day")]
    coef = {(c["parameter"], c["covariate"]): c["coef"] for c in info["coefficients"]}
    assert coef[("EJmax", "day")] < 0 < coef[("flux_offset", "day")]
    assert max(result["model"]["test_mae"]) < 0.005 < min(result["prior"]["test_mae"])
    assert (tmp_path / "tables" / "corrected_parameters.csv").exists()
