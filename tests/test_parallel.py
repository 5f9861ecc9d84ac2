"""workbench.parallel: forked workers give exactly the single-process results; plans, errors,
warnings and worker pools behave."""

import os
import signal
import time
import warnings

import numpy as np
import pandas as pd
import pytest
from sklearn.exceptions import FitFailedWarning
from sklearn.model_selection import KFold

import workbench.parallel as par
from workbench import (
    BaseBoostCV,
    BaseBoostRegressor,
    MultiTargetBaseBoost,
    make_basis,
    make_transform,
)
from workbench.bases import paper_stacking
from workbench.curves import augmented_learning_curve
from workbench.experiment.process import signals
from workbench.parallel import (
    Task,
    effective_n_jobs,
    gather,
    in_worker,
    map_tasks,
    run_plans,
    start,
    worker_pool,
)
from workbench.selection import BasisChoiceCV


def _data(n=80, seed=0):
    rng = np.random.default_rng(seed)
    X = pd.DataFrame(rng.normal(size=(n, 5)), columns=[f"p{j}" for j in range(3)] + ["v0", "v1"])
    Y = pd.DataFrame({f"y{j}": X[f"p{j}"] + 0.4 * np.sin(2 * X["v0"]) + 0.1 * rng.normal(size=n)
                      for j in range(3)})
    return X, Y


def _multi(n_jobs, basis):
    booster = BaseBoostRegressor(basis=basis, n_stages=2, basis_features=["p0", "v0", "v1"],
                                 input_transform=make_transform("quantile_normal"))
    return MultiTargetBaseBoost(BaseBoostCV(booster, cv=KFold(4)), priors=["p0", "p1", "p2"],
                                n_jobs=n_jobs, random_state=3)


@pytest.mark.parametrize("basis", [
    make_basis("lightgbm", n_estimators=30, min_child_samples=5),
    make_basis("mlp", hidden_layer_sizes=4, max_iter=2000, alpha=1.0)])
def test_multitarget_two_processes_equal_one(basis):
    X, Y = _data()
    one = _multi(1, basis).fit(X, Y)
    two = _multi(2, basis).fit(X, Y)
    pd.testing.assert_frame_equal(one.predict(X), two.predict(X), check_exact=True)
    for a, b in zip(one.estimators_, two.estimators_):
        np.testing.assert_array_equal(a.cv_scores_boosted_, b.cv_scores_boosted_)
        np.testing.assert_array_equal(a.cv_predictions_prior_, b.cv_predictions_prior_)
        assert a.selected_ == b.selected_


def test_paper_stacking_basis_two_processes_equal_one():
    X, Y = _data(60)
    basis = paper_stacking(mlp_hidden=(3,), mlp_max_iter=300, lgbm_n_estimators=40,
                           final_hidden=(3,), final_max_iter=300)
    one = _multi(1, basis).fit(X, Y)
    two = _multi(-1, basis).fit(X, Y)
    pd.testing.assert_frame_equal(one.predict(X), two.predict(X), check_exact=True)


def test_basis_choice_and_curve_two_processes_equal_one():
    X, Y = _data()
    booster = BaseBoostRegressor(prior="p0", basis_features=["p0", "v0"])
    candidates = [("ridge", booster.set_params(basis=make_basis("ridge"))),
                  ("lgbm", BaseBoostRegressor(prior="p0", basis_features=["p0", "v0"],
                                              basis=make_basis("lightgbm", n_estimators=20)))]
    fits = [BasisChoiceCV(candidates, cv=3, random_state=0, n_jobs=n).fit(X, Y["y0"])
            for n in (1, 2)]
    assert fits[0].selected_candidate_ == fits[1].selected_candidate_
    np.testing.assert_array_equal(fits[0].predict(X), fits[1].predict(X))
    for name in fits[0].candidate_scores_:
        np.testing.assert_array_equal(fits[0].candidate_scores_[name],
                                      fits[1].candidate_scores_[name])
    curves = [augmented_learning_curve(candidates[1][1], X, Y["y0"], train_sizes=[20, 40],
                                       cv=3, random_state=0, n_jobs=n) for n in (1, 2)]
    for attr in ("train_error", "cv_error", "incumbent_error", "n_train_rows"):
        np.testing.assert_array_equal(getattr(curves[0], attr), getattr(curves[1], attr))


def _pid_and_flag(x):
    return os.getpid(), in_worker(), x * x


def test_map_tasks_in_order_in_forked_workers_and_a_kept_pool():
    out = map_tasks([Task(_pid_and_flag, i) for i in range(6)], n_jobs=2)
    assert [o[2] for o in out] == [i * i for i in range(6)]
    assert all(o[1] for o in out) and os.getpid() not in {o[0] for o in out}
    assert map_tasks([Task(_pid_and_flag, 3)], n_jobs=1)[0][:2] == (os.getpid(), False)
    with worker_pool(2):  # tasks of 0.2 s, so both workers take some in each call
        first = {o[0] for o in map_tasks([Task(_slow_pid, i) for i in range(4)], 2)}
        again = {o[0] for o in map_tasks([Task(_slow_pid, i) for i in range(4)], 2)}
    assert len(first) == 2 and first == again  # the same workers served both calls


def test_start_workers_forks_the_pool_from_the_calling_thread():
    """start_workers forks every worker of the enclosing pool at once (so a thread started
    afterwards never forks), and a thread's plans then run on those workers."""
    import threading

    import workbench.parallel as par

    with worker_pool(2):
        pool = par._AMBIENT[-1]
        assert pool._executor is None  # forked on first use
        par.start_workers(2)
        pids = set(pool._executor._processes)
        assert len(pids) == 2
        out = []
        thread = threading.Thread(target=lambda: out.extend(
            map_tasks([Task(_slow_pid, i) for i in range(4)], 2)))
        thread.start()
        thread.join()
        assert {o[0] for o in out} <= pids and [o[2] for o in out] == [0, 1, 4, 9]
    par.start_workers(2)  # no pool: nothing to do


_INIT_WORKER = par.init_worker


def _init_once_a_sigterm_waits(parent):
    """A worker's initializer that first waits until a SIGTERM sent to it is pending, then
    runs :func:`~workbench.parallel.init_worker`, whose default disposition ends it."""
    deadline = time.monotonic() + 30
    while signal.SIGTERM not in signal.sigpending() and time.monotonic() < deadline:
        time.sleep(0.01)
    _INIT_WORKER(parent)
    os._exit(3)  # not reached


def test_a_sigterm_reaching_a_worker_before_its_initializer_waits_for_it(monkeypatch):
    """A worker starts with SIGINT and SIGTERM blocked: one sent before its initializer ran
    never runs the command's handler it was forked with (seen on a fresh clone: a config
    error ended the pool at once, a child raised the command's interrupt just after fork()
    and, unwinding into the parent's stack, ran the rest of the pytest worker's tests a
    second time). It waits for the worker's own disposition and ends it."""
    monkeypatch.setattr(par, "init_worker", _init_once_a_sigterm_waits)
    with signals.handle_signals():  # the command's handler, as the fork inherits it
        pool = par._Pool(1)
        [proc] = pool.executor._processes.values()
        os.kill(proc.pid, signal.SIGTERM)
        proc.join(60)
        pool.close(kill=True)
    assert proc.exitcode == -signal.SIGTERM


def _slow_pid(i):
    time.sleep(0.2)
    return _pid_and_flag(i)


def _nested(n):
    return effective_n_jobs(-1), map_tasks([Task(_pid_and_flag, i) for i in range(n)], 2)


def test_no_nested_processes_inside_a_worker():
    [(jobs, inner)] = map_tasks([Task(_nested, 3)], n_jobs=2)
    assert jobs == 1 and len({pid for pid, _, _ in inner}) == 1


def _boom(x):
    if x == 2:
        raise ValueError("task two failed")
    return x


def _plan_catching():
    try:
        yield [Task(_boom, 1), Task(_boom, 2)]
    except ValueError as exc:
        caught = str(exc)
    second = yield [Task(_boom, 5)]
    return caught, second


@pytest.mark.parametrize("n_jobs", [1, 2])
def test_a_task_error_is_raised_in_its_plan(n_jobs):
    assert run_plans([_plan_catching()], n_jobs) == [("task two failed", [5])]
    with pytest.raises(ValueError, match="task two failed"):
        map_tasks([Task(_boom, 2), Task(_boom, 1)], n_jobs)


def _ident(x):
    return x


def _stages(name, n):
    a = yield [Task(_ident, i) for i in range(n)]
    b = yield [Task(_ident, sum(a))]
    return name, a, b


@pytest.mark.parametrize("n_jobs", [1, 2])
def test_plans_and_gathered_plans(n_jobs):
    out = run_plans([_stages("a", 3), _stages("b", 1), gather([_stages("c", 2),
                                                              _stages("d", 4)])], n_jobs)
    assert out == [("a", [0, 1, 2], [3]), ("b", [0], [0]),
                   [("c", [0, 1], [1]), ("d", [0, 1, 2, 3], [6])]]


def _warns(x):
    # no stacklevel (B028), deliberately: the warning's location is this worker-side line
    warnings.warn(f"careful with {x}", FitFailedWarning)  # noqa: B028
    return x


def test_warnings_of_workers_are_issued_in_the_parent():
    with pytest.warns(FitFailedWarning, match="careful with 1"):
        assert map_tasks([Task(_warns, 1)], n_jobs=2) == [1]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.simplefilter("ignore", FitFailedWarning)  # the parent's filters apply
        assert map_tasks([Task(_warns, 2)], n_jobs=2) == [2]


def test_a_started_task_runs_on_a_worker_beside_the_plans():
    """start: the task runs on a worker of the pool while this process runs plans on the
    other; its value, error and warnings come with result(). Without a pool (or n_jobs=1)
    it runs here, at result()."""
    with worker_pool(2, eager=True):
        started = start(Task(_slow_pid, 7))
        plans = map_tasks([Task(_pid_and_flag, i) for i in range(4)], 2)
        pid, in_a_worker, value = started.result()
        assert in_a_worker and pid != os.getpid() and value == 49
        assert [o[2] for o in plans] == [0, 1, 4, 9]
        with pytest.raises(ValueError, match="task two failed"):
            start(Task(_boom, 2)).result()
        with pytest.warns(FitFailedWarning, match="careful with 3"):
            assert start(Task(_warns, 3)).result() == 3
    for n_jobs in (1, -1):  # no pool, or one process: here, when the result is taken
        assert start(Task(_pid_and_flag, 2), n_jobs).result() == (os.getpid(), False, 4)


def test_effective_n_jobs():
    assert effective_n_jobs(None) == 1 and effective_n_jobs(3) == 3
    assert effective_n_jobs(-1) >= 1
    with pytest.raises(ValueError, match="n_jobs == 0"):
        effective_n_jobs(0)
    with pytest.raises(TypeError, match="non-empty list of Task"):
        run_plans([(x for x in [[1]])], 1)


def test_lean_lightgbm_predicts_like_lightgbm_and_pickles():
    import pickle

    from lightgbm import LGBMRegressor
    from sklearn.base import clone

    from workbench.bases import LeanLGBMRegressor

    X, Y = _data(120)
    params = dict(n_estimators=80, num_leaves=8, min_child_samples=5, objective="mae",
                  data_sample_strategy="goss", random_state=0, n_jobs=1, verbose=-1)
    plain = LGBMRegressor(**params).fit(X, Y["y0"])
    lean = clone(LeanLGBMRegressor(**params)).fit(X, Y["y0"])
    np.testing.assert_array_equal(plain.predict(X), lean.predict(X))
    back = pickle.loads(pickle.dumps(lean))
    assert not hasattr(back, "_train_set")
    np.testing.assert_array_equal(back.predict(X), lean.predict(X))
    plain.fit(X, Y["y1"])  # LightGBM's own class outside a lean fit: unchanged behaviour
    assert plain.booster_.current_iteration() == 80


def test_selection_learning_curve_reuses_the_selection_folds():
    from sklearn.base import clone
    from sklearn.metrics import mean_absolute_error

    from workbench.curves import selection_learning_curve

    X, Y = _data(80)
    booster = BaseBoostRegressor(prior="p0", basis=make_basis("lightgbm", n_estimators=25,
                                                              min_child_samples=5),
                                 basis_features=["p0", "v0"])
    model = BaseBoostCV(booster, cv=KFold(4), random_state=2,
                        return_train_score=True).fit(X, Y["y0"])
    curves = [selection_learning_curve(model, X, Y["y0"], train_sizes=[20, 40, 60],
                                       random_state=1, n_jobs=n) for n in (1, 2)]
    for attr in ("train_error", "cv_error", "incumbent_error", "n_train_rows"):
        np.testing.assert_array_equal(getattr(curves[0], attr), getattr(curves[1], attr))
    curve = curves[0]
    y = Y["y0"].to_numpy()
    for j, (tr, va) in enumerate(KFold(4).split(X)):  # the whole fold: the selection's fit
        fitted = clone(model._candidate()).fit(X.iloc[tr], y[tr])
        assert curve.cv_error[2, j] == mean_absolute_error(y[va], fitted.predict(X.iloc[va]))
        assert curve.train_error[2, j] == mean_absolute_error(y[tr], fitted.predict(X.iloc[tr]))
        assert curve.incumbent_error[2, j] == mean_absolute_error(y[va], X["p0"].iloc[va])
    assert np.isfinite(curve.cv_error).all() and curve.n_train_rows[0].tolist() == [20] * 4


@pytest.mark.parametrize("params", [
    dict(objective="mae", data_sample_strategy="goss", num_leaves=32, max_depth=20,
         learning_rate=0.2, reg_alpha=0.3, reg_lambda=0.3, max_bin=512, n_estimators=300),
    dict(objective="huber", num_leaves=15, n_estimators=60, min_child_samples=3),
    dict(objective="regression", n_estimators=40, num_leaves=7)])
def test_lean_lightgbm_numpy_prediction_is_lightgbm_s(params):
    from lightgbm import LGBMRegressor

    from workbench.bases import NUMPY_PREDICT_ROWS, LeanLGBMRegressor

    X, Y = _data(90)
    lean = LeanLGBMRegressor(**params, random_state=0, verbose=-1, n_jobs=1).fit(X, Y["y0"])
    plain = LGBMRegressor(**params, random_state=0, verbose=-1, n_jobs=1).fit(X, Y["y0"])
    rng = np.random.default_rng(1)
    rows = np.vstack([X.to_numpy()[rng.integers(0, len(X), NUMPY_PREDICT_ROWS)],
                      rng.normal(size=(500, 5)) * 3])
    trees = lean._numpy_trees()
    assert trees is not None
    thresholds = []  # inputs exactly at the split thresholds: the `<=` boundary

    def walk(node):
        if not isinstance(node, float):
            thresholds.append(node[:2])
            walk(node[2]), walk(node[3])
    for tree in trees:
        walk(tree)
    for k, (feature, threshold) in enumerate(thresholds[:500]):
        rows[k, feature] = threshold
    rows[500:505] = [[1e-36], [-1e-36], [1e-35], [-1e-35], [0.0]]  # LightGBM reads as zero
    expected = plain.booster_.predict(rows)
    np.testing.assert_array_equal(lean.predict(rows), expected)  # numpy trees
    np.testing.assert_array_equal(lean.predict(pd.DataFrame(rows, columns=X.columns)), expected)
    np.testing.assert_array_equal(lean.predict(rows[:10]), expected[:10])  # LightGBM's own
    rows[3, 2] = np.nan  # missing values: LightGBM's own handling
    np.testing.assert_array_equal(lean.predict(rows), plain.booster_.predict(rows))


def test_normal_quantile_transform_is_scikit_learn_s():
    from sklearn.preprocessing import QuantileTransformer

    from workbench.bases import NormalQuantileTransformer

    rng = np.random.default_rng(0)
    X = np.column_stack([rng.normal(size=300), rng.integers(0, 5, 300).astype(float),
                         rng.exponential(size=300)])
    for n_rows, new in ((300, rng.normal(size=(400, 3)) * 3), (40, X[:500])):
        ours = NormalQuantileTransformer(random_state=0).fit(X[:n_rows])
        theirs = QuantileTransformer(n_quantiles=min(1000, n_rows), output_distribution="normal",
                                     random_state=0).fit(X[:n_rows])
        new = np.vstack([new, X[:n_rows], [[np.nan, 0.0, -1.0]]])
        np.testing.assert_array_equal(ours.transform(new), theirs.transform(new))
        np.testing.assert_array_equal(ours.transformer_.inverse_transform(ours.transform(new)),
                                      theirs.inverse_transform(theirs.transform(new)))


def test_kernel_ridge_basis_is_exact_up_to_a_row_count_then_nystroem():
    from sklearn.kernel_ridge import KernelRidge

    from workbench.bases import make_basis, quadratic_basis_warning

    rng = np.random.default_rng(0)
    X = rng.normal(size=(400, 3))
    y = np.sin(X[:, 0]) + X[:, 1] ** 2 + 0.05 * rng.normal(size=400)
    exact = make_basis("kernel_ridge", alpha=0.1, gamma=0.5).fit(X, y)
    assert not exact.approximate_
    np.testing.assert_array_equal(exact.predict(X), KernelRidge(alpha=0.1, kernel="rbf",
                                                               gamma=0.5).fit(X, y).predict(X))
    approx = make_basis("kernel_ridge", alpha=0.1, gamma=0.5, exact_max_rows=100,
                        n_components=150, random_state=0).fit(X, y)
    assert approx.approximate_
    # rank-150 Nystroem features of a smooth kernel: close to the exact fit
    assert np.mean(np.abs(approx.predict(X) - exact.predict(X))) < 0.05 * np.std(y)
    with pytest.raises(ValueError, match="alpha"):
        make_basis("kernel_ridge", alpha=-1.0).fit(X, y)
    assert "cubic" in quadratic_basis_warning("gaussian_process", 50_000)
    assert quadratic_basis_warning("gaussian_process", 500) is None
    assert quadratic_basis_warning("kernel_ridge", 10 ** 6) is None


def test_lean_lightgbm_predicts_large_trees_with_lightgbm(monkeypatch):
    """numpy's all-rows-through-every-node evaluation only for small trees; larger ones go
    through LightGBM's traversal (the same numbers either way)."""
    from workbench import bases
    from workbench.bases import LeanLGBMRegressor

    X, Y = _data(90)
    small = LeanLGBMRegressor(n_estimators=20, verbose=-1, n_jobs=1).fit(X, Y["y0"])
    large = LeanLGBMRegressor(n_estimators=20, num_leaves=15, min_child_samples=3,
                              verbose=-1, n_jobs=1).fit(X, Y["y0"])
    assert small._small_trees() and not large._small_trees()  # 90 // 20 = 4 leaves at most
    rows = np.random.default_rng(0).normal(size=(bases.NUMPY_PREDICT_ROWS, 5))
    summed = []
    monkeypatch.setattr(bases, "_sum_trees", lambda *a: summed.append(1) or np.zeros(len(rows)))
    large.predict(rows)
    assert not summed
    small.predict(rows)
    assert summed
