"""Which experiment next: greedy D-/I-optimal batches (workbench.design), the families'
uncertainty, ``workbench design`` and the closed loop with the simulator."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from workbench.design import ensemble_blocks, greedy_design, robust_sd
from workbench.experiment.cli import main
from workbench.param_regressor import HamiltonianParameterRegressor
from workbench.simulate import bias_columns, measure, simulate, write_simulation

EXPERIMENTS = Path(__file__).resolve().parents[1] / "experiments"
X = np.linspace(-1, 1, 21)


def _poly(degree: int, x=X) -> np.ndarray:
    """Blocks of polynomial regression: one output, coefficients 1, x, ..., x^degree."""
    return np.stack([x**k for k in range(degree + 1)], axis=1)[:, None, :]


# ---------------------------------------------------------------------- known optimal designs
def test_d_optimal_straight_line_takes_the_two_ends():
    batch = greedy_design(_poly(1), 1e-6 * np.eye(2), 2, criterion="d")
    assert sorted(X[batch.index]) == [-1.0, 1.0]


def test_d_optimal_parabola_is_minus_one_zero_one_in_equal_numbers():
    """The exact D-optimal design of quadratic regression on [-1, 1] puts equal numbers of
    points at -1, 0 and 1; after it, every support point's variance is 1 noise variance, so
    each further pick gains log 2 nats (the equivalence theorem)."""
    batch = greedy_design(_poly(2), 1e-6 * np.eye(3), 6, criterion="d", repeats=True)
    assert sorted(X[batch.index].round(12).tolist()) == [-1, -1, 0, 0, 1, 1]
    np.testing.assert_allclose(batch.gain[3:], np.log(2), rtol=1e-5)


def test_first_pick_is_the_brute_force_optimum_for_both_criteria():
    rng = np.random.default_rng(0)
    B = rng.normal(size=(40, 3, 6))
    measured = rng.normal(size=(12, 3, 6))
    F = np.einsum("nqd,nqe->de", measured, measured) + 0.1 * np.eye(6)
    M = np.einsum("nqd,nqe->de", B, B) / len(B)
    logdet = [np.linalg.slogdet(F + B[c].T @ B[c])[1] for c in range(len(B))]
    avg_var = [np.trace(np.linalg.solve(F + B[c].T @ B[c], M)) for c in range(len(B))]
    d = greedy_design(B, F, 1, criterion="d")
    i = greedy_design(B, F, 1, criterion="i")
    assert d.index[0] == int(np.argmax(logdet))
    assert i.index[0] == int(np.argmin(avg_var))
    np.testing.assert_allclose(d.gain[0], logdet[d.index[0]] - np.linalg.slogdet(F)[1])
    np.testing.assert_allclose(i.gain[0], np.trace(np.linalg.solve(F, M)) - min(avg_var))


def _naive(B, F, n, criterion):
    """The greedy batch recomputed from the inverse information at every pick."""
    M = np.einsum("nqd,nqe->de", B, B) / len(B)
    chosen = []
    for _ in range(n):
        G = np.linalg.inv(F)
        gains = []
        for c in range(len(B)):
            Fc = F + B[c].T @ B[c]
            gains.append(-np.inf if c in chosen else
                         np.linalg.slogdet(Fc)[1] - np.linalg.slogdet(F)[1] if criterion == "d"
                         else np.trace(G @ M) - np.trace(np.linalg.solve(Fc, M)))
        c = int(np.argmax(gains))
        chosen.append(c)
        F = F + B[c].T @ B[c]
    return chosen


@pytest.mark.parametrize("criterion", ["d", "i"])
def test_a_whole_batch_matches_recomputing_the_inverse_at_every_pick(criterion):
    rng = np.random.default_rng(3)
    B = rng.normal(size=(30, 2, 5))
    F = 0.5 * np.eye(5)
    assert greedy_design(B, F, 8, criterion=criterion).index.tolist() == _naive(B, F, 8,
                                                                               criterion)


def test_i_optimal_parabola_weights_the_middle_most():
    """I-optimal for a parabola over a uniform reference weights 0 about twice each end;
    the greedy batch after one point at each of -1, 0, 1 takes 0 first and most often."""
    B = _poly(2)
    F = np.einsum("nqd,nqe->de", B[[0, 10, 20]], B[[0, 10, 20]])
    batch = greedy_design(B, F, 5, criterion="i", repeats=True)
    picks = X[batch.index].round(12).tolist()
    assert picks[0] == 0 and picks.count(0) >= 2 and set(picks) <= {-1, 0, 1}


def test_a_batch_is_not_copies_of_one_setting():
    """Five copies of the best setting: after one, its information is known and the batch
    moves to the other end."""
    x = np.concatenate([np.ones(5), X])
    batch = greedy_design(_poly(1, x), np.diag([10.0, 0.1]), 2, criterion="d")
    assert sorted(x[batch.index]) == [-1.0, 1.0]
    assert len(set(batch.index.tolist())) == 2


def test_predictive_sd_and_informs():
    B = _poly(1)
    batch = greedy_design(B, np.eye(2), 1)
    np.testing.assert_allclose(batch.sd_before[:, 0] ** 2, 1 + X**2)  # G = I
    assert batch.sd[0, 0] == pytest.approx(np.sqrt(2))  # an end: var 1 + 1
    assert batch.informs[0] in (0, 1) and 0 < batch.informs_fraction[0] < 1


@pytest.mark.parametrize("kwargs, match", [
    (dict(blocks=np.zeros((3, 2))), "shape"),
    (dict(information=np.eye(3)), r"\(2, 2\)"),
    (dict(n=0), "n must be"),
    (dict(n=22), "n must be"),
    (dict(criterion="a"), "valid: d, i"),
    (dict(information=np.zeros((2, 2))), "not positive definite"),
    (dict(blocks=np.full((21, 1, 2), np.nan)), "NaN"),
])
def test_bad_design_inputs_name_the_problem(kwargs, match):
    args = dict(blocks=_poly(1), information=np.eye(2), n=2, criterion="d") | kwargs
    with pytest.raises(ValueError, match=match):
        greedy_design(args["blocks"], args["information"], args["n"],
                      criterion=args["criterion"])


def test_ensemble_blocks_give_the_ensembles_variance():
    rng = np.random.default_rng(1)
    P = rng.normal(size=(5, 30, 2))
    noise = np.array([0.5, 2.0])
    blocks, info = ensemble_blocks(P, noise)
    batch = greedy_design(blocks, info, 3)
    np.testing.assert_allclose((batch.sd_before * noise) ** 2, P.var(axis=0, ddof=1))
    with pytest.raises(ValueError, match="n_models >= 2"):
        ensemble_blocks(P[:1], noise)


def test_robust_sd_ignores_a_few_wild_residuals():
    r = np.random.default_rng(2).normal(0, 0.3, 2000)
    r[:20] = 50.0
    assert robust_sd(r) == pytest.approx(0.3, rel=0.1)


# ---------------------------------------------------------------------- the parameter-space model
def _regressor():
    d = simulate(4, 60, device_seed=1).data
    on, co = [f"model_f{k}" for k in range(1, 5)], [f"model_g{k}" for k in range(1, 4)]
    model = HamiltonianParameterRegressor(onsite=on, couplings=co, features=["v_q1", "v_c2"],
                                          alpha=0.5)
    return model.fit(d, d.filter(like="measured_E").to_numpy()), d


def test_coef_jacobian_is_the_derivative_of_predict():
    model, d = _regressor()
    rows = d.iloc[:6]
    A = model.coef_jacobian(rows)
    c0, eps = model._coef.copy(), 1e-6
    fd = np.empty_like(A)
    for j in range(len(c0)):
        model._coef = c0 + eps * np.eye(len(c0))[j]
        up = model.predict(rows)
        model._coef = c0 - eps * np.eye(len(c0))[j]
        fd[:, :, j] = (up - model.predict(rows)) / (2 * eps)
    model._coef = c0
    assert A.shape == (6, 4, len(c0))
    np.testing.assert_allclose(A, fd, atol=1e-5)


def test_information_is_gauss_newton_plus_the_ridge_penalty_off_the_intercepts():
    model, d = _regressor()
    A = model.coef_jacobian(d)
    F = model.information(d)
    extra = F - np.einsum("nkd,nke->de", A, A)
    intercepts = [s.start for s in model._slices]
    assert np.allclose(np.diag(extra)[intercepts], 0)
    assert np.allclose(np.delete(np.diag(extra), intercepts), 0.5)
    assert np.allclose(extra - np.diag(np.diag(extra)), 0)


# ---------------------------------------------------------------------- the command
LEAN = """name = "lean"
random_state = 0
n_jobs = 1
[data]
csv = "data.csv"
prior = {prior}
targets = {targets}
features = {features}
test_fraction = 0.25
split_seed = 0
[data.hamiltonian]
onsite = {onsite}
couplings = {couplings}
[model]
family = "{family}"
basis = "ridge"
n_stages = 1
[model.hamiltonian]
selection = "none"
candidates = "none"
boost_stage = false
[selection]
cv = 3
[intervals]
enabled = false
"""


def _names(prefix, n):
    return [f"{prefix}{k}" for k in range(1, n + 1)]


def _project(tmp_path: Path, family: str = "hamiltonian", rows: int = 40, n: int = 4) -> Path:
    """A CSV of ``rows`` simulated experiments and a lean config on it."""
    write_simulation(simulate(n, rows, device_seed=3), tmp_path / "data.csv")
    text = LEAN.format(prior=_names("model_E", n), targets=_names("measured_E", n),
                       features=_names("v_q", n) + _names("v_c", n - 1),
                       onsite=_names("model_f", n), couplings=_names("model_g", n - 1),
                       family=family).replace("'", '"')
    if family != "hamiltonian":
        text = text.replace(text[text.index("[model.hamiltonian]"):text.index("[selection]")],
                            "")
    (tmp_path / "lean.toml").write_text(text)
    return tmp_path / "lean.toml"


def _pool(tmp_path: Path, n: int = 4, rows: int = 80) -> Path:
    """Candidate settings of the same device (seed 3): random biases with the control
    model's parameters and prediction, no measurement."""
    settings = simulate(n, rows, device_seed=103).data[bias_columns(n, n - 1)]
    pool = measure(settings, device_seed=3).data
    pool = pool.drop(columns=[c for c in pool.columns if c.startswith("measured_")])
    path = tmp_path / "pool.csv"
    pool.to_csv(path, index=False)
    return path


@pytest.mark.parametrize("family, criterion", [("hamiltonian", "i"), ("hamiltonian", "d"),
                                               ("eigenvalue", "i")])
def test_design_command_writes_the_chosen_rows_and_why(tmp_path, capsys, family, criterion):
    config, pool = _project(tmp_path, family), _pool(tmp_path)
    out = tmp_path / "next.csv"
    assert main(["design", str(config), "--candidates", str(pool), "--n", "6", "--out",
                 str(out), "--criterion", criterion]) == 0
    line = capsys.readouterr().out
    assert f"6 of 80 candidates ({criterion.upper()}-optimal" in line
    assert "30 training rows" in line
    chosen = pd.read_csv(out)
    candidates = pd.read_csv(pool)
    assert list(chosen["design_rank"]) == [1, 2, 3, 4, 5, 6]
    assert list(chosen.columns[:len(candidates.columns)]) == list(candidates.columns)
    # distinct candidate rows, copied unchanged
    merged = chosen.merge(candidates, on=list(candidates.columns))
    assert len(merged) == 6 and not chosen.duplicated(list(candidates.columns)).any()
    assert (chosen[[f"measured_E{k}_sd" for k in range(1, 5)]] >= 0).all().all()
    what = "correction coefficients" if family == "hamiltonian" else "fold models"
    assert chosen["design_reason"].str.contains(what).all()
    assert chosen["design_reason"].str.startswith(f"{criterion.upper()}-optimal pick").all()
    if criterion == "d":
        assert (np.diff(chosen["design_gain"]) <= 1e-9).all()  # greedy: gains fall


@pytest.mark.parametrize("edit, match", [
    (lambda p: p.write_text(""), "--candidates: .* is empty"),
    (lambda p: pd.read_csv(p).drop(columns="model_f2").to_csv(p, index=False),
     r"candidates: missing column\(s\) .*model_f2"),
    (lambda p: pd.read_csv(p).assign(v_q1=np.nan).to_csv(p, index=False),
     "candidates: .*v_q1"),
    (lambda p: pd.read_csv(p).assign(design_rank=1).to_csv(p, index=False),
     "names design writes"),
])
def test_design_command_bad_candidates_are_one_line_and_write_nothing(tmp_path, capsys, edit,
                                                                      match):
    config, pool = _project(tmp_path), _pool(tmp_path)
    edit(pool)
    out = tmp_path / "next.csv"
    assert main(["design", str(config), "--candidates", str(pool), "--n", "3", "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("workbench: error:")
    assert re.search(match, err), err
    assert not out.exists()


def test_design_command_more_than_the_candidates_or_out_a_directory(tmp_path, capsys):
    config, pool = _project(tmp_path), _pool(tmp_path, rows=5)
    assert main(["design", str(config), "--candidates", str(pool), "--n", "6", "--out",
                 str(tmp_path / "n.csv")]) == 2
    assert "--n 6: choose between 1 and the 5 candidates" in capsys.readouterr().err
    assert main(["design", str(config), "--candidates", str(pool), "--n", "2", "--out",
                 str(tmp_path)]) == 2
    assert "is a directory" in capsys.readouterr().err


def test_closed_loop_design_then_simulate_the_chosen_settings(tmp_path, capsys):
    """The README's loop: design chooses settings, the simulator measures them on the same
    seeded device, the new rows join the data."""
    config, pool = _project(tmp_path), _pool(tmp_path)
    next_csv, measured = tmp_path / "next.csv", tmp_path / "measured.csv"
    assert main(["design", str(config), "--candidates", str(pool), "--n", "5", "--out",
                 str(next_csv)]) == 0
    assert main(["simulate", "--sites", "4", "--device-seed", "3", "--settings", str(next_csv),
                 "--out", str(measured)]) == 0
    assert "measured 5 settings" in capsys.readouterr().out
    chosen, new = pd.read_csv(next_csv), pd.read_csv(measured)
    np.testing.assert_allclose(new[_names("model_E", 4)], chosen[_names("model_E", 4)])
    data = pd.read_csv(tmp_path / "data.csv")
    pd.concat([data, new[data.columns]]).to_csv(tmp_path / "data.csv", index=False)
    assert main(["design", str(config), "--candidates", str(pool), "--n", "5", "--out",
                 str(next_csv)]) == 0
    assert "34 training rows" in capsys.readouterr().out


def test_acquisition_loop_arms_share_their_start_and_stay_in_the_pool(tmp_path):
    from workbench.experiment.config import load_dataset
    from workbench.experiment.runs.design import acquisition_loop
    from workbench.experiment.runs.prepare import load_config

    cfg = load_config(_project(tmp_path, rows=70))
    ds = load_dataset(cfg)
    pool, test = list(ds.train_index), list(ds.test_index)
    runs = {arm: acquisition_loop(cfg, ds, pool, test, arm=arm, seed=4, start=10, batch=5,
                                  stop=20)
            for arm in ("design", "random")}
    for run in runs.values():
        assert run.n_measured == [10, 15, 20] and len(run.test_mae) == 3
        assert len(set(run.chosen)) == 20 and set(run.chosen) <= set(pool)
    assert runs["design"].chosen[:10] == runs["random"].chosen[:10]
    assert runs["design"].test_mae[0] == runs["random"].test_mae[0]
    again = acquisition_loop(cfg, ds, pool, test, arm="design", seed=4, start=10, batch=5,
                             stop=20)
    assert again.chosen == runs["design"].chosen and again.test_mae == runs["design"].test_mae
    with pytest.raises(ValueError, match="valid: design, random"):
        acquisition_loop(cfg, ds, pool, test, arm="best")


def test_design_loop_config_parses():
    from workbench.experiment.runs.prepare import load_config

    cfg = load_config(EXPERIMENTS / "design_loop.toml")
    assert cfg.family.name == "hamiltonian" and not cfg.intervals.enabled
