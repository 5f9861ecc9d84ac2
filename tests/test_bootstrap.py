"""Bootstrap intervals of the test errors: per target, the average over targets, and the
paired difference model - prior (experiment layer, bootstrap.py)."""

import json

import numpy as np
import pytest

from workbench.experiment.scoring.bootstrap import (
    BOOTSTRAP_EXACT_ROWS,
    ErrorInterval,
    _intervals,
    bootstrap_error_interval,
    bootstrap_method,
    bootstrap_test_scores,
)
from workbench.experiment.scoring.results import Result
from workbench.experiment.scoring.scores import ModelScores, Scores, mae, mse


def _errors(n, targets=3, seed=0, scale=1.0):
    rng = np.random.default_rng(seed)
    return scale * rng.standard_t(4, size=(n, targets))


def test_the_interval_contains_the_point_estimate_per_target_and_on_average():
    err = _errors(41)
    ci = bootstrap_error_interval(err, random_state=3)
    assert isinstance(ci, ErrorInterval)
    point = np.mean(np.abs(err), axis=0)
    assert len(ci.per_target) == 3
    for (low, high), p in zip(ci.per_target, point, strict=True):
        assert low < p < high
    low, high = ci.average
    assert low < point.mean() < high
    # the average's interval is no wider than the widest target's (averaging cancels noise)
    widths = [h - lo for lo, h in ci.per_target]
    assert high - low <= max(widths)


def test_squared_errors_give_the_mse_interval():
    err = _errors(41)
    ci = bootstrap_error_interval(err, squared=True)
    for (low, high), p in zip(ci.per_target, np.mean(err ** 2, axis=0), strict=True):
        assert low < p < high


def test_more_rows_give_a_narrower_interval():
    small = bootstrap_error_interval(_errors(40, seed=1), random_state=0)
    large = bootstrap_error_interval(_errors(1000, seed=1), random_state=0)
    width = lambda bounds: bounds[1] - bounds[0]  # noqa: E731
    assert width(large.average) < 0.5 * width(small.average)  # ~ 1 / sqrt(25) of it
    for s, lg in zip(small.per_target, large.per_target, strict=True):
        assert width(lg) < width(s)


def test_same_seed_same_numbers_other_seed_other_numbers():
    err = _errors(41)
    a = bootstrap_error_interval(err, random_state=7)
    b = bootstrap_error_interval(err, random_state=7)
    c = bootstrap_error_interval(err, random_state=8)
    assert a == b
    assert a != c
    # the Monte Carlo error of 10,000 resamples is small against the interval's width
    assert abs(a.average[0] - c.average[0]) < 0.05 * (a.average[1] - a.average[0])


def test_rows_are_resampled_jointly_over_targets():
    """Two identical targets: every resample gives them the same mean, so the average's
    interval equals each target's (an independent resampling per target would narrow it)."""
    col = _errors(41, targets=1)[:, 0]
    ci = bootstrap_error_interval(np.column_stack([col, col]))
    assert ci.per_target[0] == ci.per_target[1]
    assert ci.average == pytest.approx(ci.per_target[0], rel=1e-12)


def test_paired_difference():
    """The paired interval of model - prior: a model uniformly better by 0.3 on every row has a
    difference of exactly -0.3 on every resample; a one-dimensional input is one target."""
    prior = np.abs(_errors(41, targets=1)[:, 0]) + 0.5
    model = prior - 0.3
    ci = bootstrap_error_interval(model, baseline=prior)
    assert ci.per_target[0] == pytest.approx([-0.3, -0.3])
    assert ci.average == pytest.approx([-0.3, -0.3])
    # pairing: the difference's interval is much narrower than either system's, and it is
    # the difference of the same resamples (same seed)
    noisy = model + 0.05 * np.random.default_rng(5).normal(size=41)
    paired = bootstrap_error_interval(noisy, baseline=prior)
    own = bootstrap_error_interval(noisy)
    assert paired.average[1] - paired.average[0] < 0.3 * (own.average[1] - own.average[0])
    assert paired.average[1] < 0


@pytest.mark.parametrize("kwargs, match", [
    ({"errors": np.zeros((0, 2))}, "at least one row"),
    ({"errors": [1.0, np.nan]}, "non-finite"),
    ({"errors": np.zeros((3, 2)), "baseline": np.zeros((3, 1))}, "shape of errors"),
    ({"errors": [1.0], "level": 1.0}, "level"),
    ({"errors": [1.0], "n_resamples": 0}, "n_resamples"),
])
def test_bad_arguments_are_refused(kwargs, match):
    with pytest.raises(ValueError, match=match):
        bootstrap_error_interval(**kwargs)


def _scores(n=41, targets=2, seed=0):
    rng = np.random.default_rng(seed)
    y = rng.normal(size=(n, targets))
    prior_pred = y + rng.normal(scale=1.0, size=y.shape)
    pred = y + rng.normal(scale=0.5, size=y.shape)
    prior = Scores(test_mae=mae(y, prior_pred), test_mse=mse(y, prior_pred), cv_mae=[1.0] * 2,
                   cv_mse=[1.0] * 2)
    model = ModelScores(test_mae=mae(y, pred), test_mse=mse(y, pred), cv_mae=[1.0] * 2,
                        cv_mse=[1.0] * 2, selected=["boosted", "prior"])
    return y, prior_pred, pred, prior, model


def test_bootstrap_test_scores_fills_both_systems_and_the_json_only_adds_keys():
    y, prior_pred, pred, prior, model = _scores()
    before = (prior.to_json(), model.to_json())
    assert prior.ci("test_mae") is None  # not computed: no interval, no key
    assert not any(k.endswith("_ci") for part in before for k in part)
    settings = bootstrap_test_scores(prior, model, y, prior_pred, pred, random_state=4)
    assert settings == {"method": "percentile", "level": 0.95, "n_resamples": 10_000,
                        "random_state": 4, "n_rows": 41}
    for scores in (prior, model):
        for key in ("test_mae", "test_mse"):
            rows = scores.ci(key)
            point = [*getattr(scores, key), scores.avg(key)]
            assert len(rows) == 3  # two targets and the average
            for (low, high), p in zip(rows, point, strict=True):
                assert low < p < high
    diff = model.ci("test_mae_diff")
    gain = np.subtract(model.test_mae, prior.test_mae)
    for (low, high), d in zip(diff, [*gain, gain.mean()], strict=True):
        assert low < d < high
    assert diff[-1][1] < 0  # the model (noise 0.5) beats the prior (noise 1) on 41 rows
    # the same numbers as the function on the errors, with the same seed
    direct = bootstrap_error_interval(y - pred, baseline=y - prior_pred, random_state=4)
    assert model.test_mae_diff_ci == direct.per_target
    assert model.test_mae_diff_avg_ci == direct.average

    after = (prior.to_json(), model.to_json())
    for old, new in zip(before, after, strict=True):
        assert {k: new[k] for k in old} == old  # every key kept, with its value
    assert set(after[0]) - set(before[0]) == {"test_mae_ci", "test_mae_avg_ci", "test_mse_ci",
                                               "test_mse_avg_ci"}
    assert set(after[1]) - set(before[1]) == {"test_mae_ci", "test_mae_avg_ci", "test_mse_ci",
                                               "test_mse_avg_ci", "test_mae_diff_ci",
                                               "test_mae_diff_avg_ci"}
    result = Result(name="r", config=None, family="eigenvalue", targets=["a", "b"],
                    n_train=10, n_test=41, prior=prior, model=model, bootstrap=settings)
    out = json.loads(json.dumps(result.to_json()))
    assert out["bootstrap"] == settings
    assert out["model"]["test_mae_diff_avg_ci"] == model.test_mae_diff_avg_ci


def test_bootstrap_test_scores_takes_a_single_target_as_a_column():
    y, prior_pred, pred, prior, model = _scores(targets=1)
    bootstrap_test_scores(prior, model, y, prior_pred[:, 0], pred[:, 0])
    assert len(model.test_mae_ci) == 1 and len(model.test_mae_diff_ci) == 1


def test_one_pass_gives_the_numbers_of_separate_intervals():
    """bootstrap_test_scores computes every statistic from one set of resamples: each of its
    intervals is the one bootstrap_error_interval gives alone with the same seed."""
    y, prior_pred, pred, prior, model = _scores(n=60, targets=3, seed=2)
    bootstrap_test_scores(prior, model, y, prior_pred, pred, random_state=9)
    for scores, p, squared, key in ((prior, prior_pred, False, "test_mae"),
                                    (prior, prior_pred, True, "test_mse"),
                                    (model, pred, False, "test_mae"),
                                    (model, pred, True, "test_mse")):
        alone = bootstrap_error_interval(y - p, squared=squared, random_state=9)
        np.testing.assert_allclose(getattr(scores, f"{key}_ci"), alone.per_target, rtol=1e-12)
        np.testing.assert_allclose(getattr(scores, f"{key}_avg_ci"), alone.average,
                                   rtol=1e-12)


def test_many_rows_use_cornish_fisher_close_to_the_percentile_bootstrap():
    """Above BOOTSTRAP_EXACT_ROWS rows of near-normal means nothing is resampled; the
    Cornish-Fisher ends agree with the percentile bootstrap's within its Monte Carlo error
    (two seeds of 10,000 resamples differ by a few percent of the half-width)."""
    n = BOOTSTRAP_EXACT_ROWS + 1000
    rng = np.random.default_rng(0)
    y = rng.normal(size=(n, 2))
    prior_pred = y + rng.gamma(2.0, size=y.shape)  # skewed errors
    pred = y + 0.5 * rng.normal(size=y.shape)
    prior = Scores(test_mae=mae(y, prior_pred), test_mse=mse(y, prior_pred), cv_mae=[],
                   cv_mse=[])
    model = ModelScores(test_mae=mae(y, pred), test_mse=mse(y, pred), cv_mae=[], cv_mse=[])
    settings = bootstrap_test_scores(prior, model, y, prior_pred, pred, random_state=1)
    assert settings == {"method": "cornish_fisher", "level": 0.95, "random_state": 1,
                        "n_rows": n}
    stat = np.abs(y - prior_pred)
    assert bootstrap_method(stat) == "cornish_fisher"
    cf = np.array(bootstrap_error_interval(stat).per_target)
    pct, method = _intervals(stat, 0.95, 10_000, 0, method="percentile")
    assert method == "percentile"
    half = (pct[:, 1] - pct[:, 0]) / 2
    assert np.all(np.abs(cf - pct) < 0.06 * half[:, None])
    # skewed errors: the interval is not symmetric about the mean, as the bootstrap's is not
    mean = stat.mean(axis=0)
    assert np.all((cf[:, 1] - mean) > (mean - cf[:, 0]))
    assert np.allclose(prior.test_mae_ci, cf, rtol=1e-12)


def test_heavy_tails_are_resampled_even_with_many_rows():
    """Squared Student-t(3) errors have no variance: their resampled mean stays far from
    normal however many rows, where the expansion is off; those rows are resampled."""
    n = BOOTSTRAP_EXACT_ROWS + 1000
    err = np.random.default_rng(3).standard_t(3, size=(n, 2))
    assert bootstrap_method(np.abs(err)) == "cornish_fisher"
    assert bootstrap_method(err ** 2) == "percentile"
    y = np.zeros((n, 2))
    prior = Scores(test_mae=mae(y, err), test_mse=mse(y, err), cv_mae=[], cv_mse=[])
    model = ModelScores(test_mae=mae(y, err / 2), test_mse=mse(y, err / 2), cv_mae=[],
                        cv_mse=[])
    settings = bootstrap_test_scores(prior, model, y, err, err / 2)
    assert settings["method"] == "percentile" and settings["n_resamples"] == 10_000
    alone = bootstrap_error_interval(err, squared=True)
    np.testing.assert_allclose(prior.test_mse_ci, alone.per_target, rtol=1e-12)
