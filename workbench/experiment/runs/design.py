"""``workbench design``: which settings to measure next.

``workbench design CONFIG --candidates CANDIDATES.csv --n N --out NEXT.csv``.

The config's model is fitted on its training rows (the measurements so far; the test rows
stay unseen), then ``N`` of the candidate settings (rows with the model's inputs: features,
the control model's prediction and, for the parameter-space family, its Hamiltonian
parameters; no measurement) are chosen greedily by how much measuring them would teach the
model (:func:`workbench.design.greedy_design`): the family says what the model is unsure of
(:meth:`~workbench.experiment.families.base.ModelFamily.design_problem`: for the
parameter-space model the Fisher information of its correction coefficients through the
Hellmann-Feynman Jacobian; for the others the spread of fold models). Criterion "i" (the
default) lowers the model's average predictive variance over the candidates, "d" maximises
the information about the coefficients (log det).

The output holds the chosen candidates' rows as given (every column, text unchanged), in the
order chosen, then ``design_rank``, ``design_gain``, the model's prediction and predictive sd
of each target (``<target>_predicted``, ``<target>_sd``: at the time of the pick, given the
measured rows and the earlier picks), and ``design_reason``, a sentence on why the row was
chosen.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from sklearn.metrics import mean_absolute_error

from ...datasets import Dataset
from ...datasets.csv import DatasetError, _read
from ...design import CRITERIA, Batch, DesignProblem, greedy_design
from ..config import ExperimentConfig, load_dataset
from ..families.fitting import quiet_fit
from ..process.errors import UsageError
from ..process.outputs import check_file, write_file
from ..tracking.serving import InputError, check_inputs

__all__ = ["ARMS", "Acquisition", "Design", "acquisition_loop", "choose", "design",
           "design_columns", "design_csv"]

log = logging.getLogger("workbench")

@dataclass
class Design:
    """A chosen batch of candidates.

    Parameters
    ----------
    chosen : DataFrame
        The design columns of the picks (rank order, indexed like the candidates).
    batch : Batch
        The greedy batch.
    problem : DesignProblem
        What the model was unsure of.
    n_rows : int
        The rows the model was fitted on.
    n_candidates : int
        The candidates it chose among.
    seconds : float
        The wall time of the choice.
    """

    chosen: pd.DataFrame
    batch: Batch
    problem: DesignProblem
    n_rows: int
    n_candidates: int
    seconds: float = 0.0


def _check_n(n: int, m: int) -> None:
    if not 1 <= n <= m:
        raise UsageError(f"--n {n}: choose between 1 and the {m} candidates")


def _reasons(batch: Batch, problem: DesignProblem, targets: list[str]) -> list[str]:
    out = []
    for r, (gain, sd, k, frac) in enumerate(zip(batch.gain, batch.sd, batch.informs,
                                               batch.informs_fraction), start=1):
        if batch.criterion == "d":
            why = f"D-optimal pick {r}: {gain:.3g} nats of information about {problem.what}"
        else:
            why = (f"I-optimal pick {r}: lowers the average predictive variance over the "
                   f"candidates by {gain:.3g} noise variances ({problem.what})")
        sd_units = sd * problem.noise_sd
        t = int(np.argmax(sd_units))
        after = ("the measured rows" if r == 1 else "the measured rows and pick 1" if r == 2
                 else f"the measured rows and picks 1-{r - 1}")
        informs = problem.informs.format(name=problem.coefficients[k], fraction=frac)
        out.append(f"{why}; predicted sd {sd_units[t]:.3g} for {targets[t]} given {after}; "
                   f"{informs}")
    return out


def choose(cfg: ExperimentConfig, model: Any, X: pd.DataFrame, Y: pd.DataFrame,
           candidates: pd.DataFrame, n: int, criterion: str = "i") -> Design:
    """Choose ``n`` of the ``candidates`` for the config's ``model`` fitted on ``X``, ``Y``.

    No file is read or written.

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config (its family says what the model is unsure of).
    model : estimator
        The config's model, fitted on ``X``, ``Y``.
    X, Y : DataFrame
        The rows measured so far: the family's inputs and the targets.
    candidates : DataFrame
        The candidate settings: a frame of the family's input columns.
    n : int
        How many to choose (1 to the number of candidates).
    criterion : {"i", "d"}, default="i"
        "i" lowers the average predictive variance over the candidates, "d" maximises the
        information about the coefficients.

    Returns
    -------
    Design
        The picks, in the order chosen.

    Raises
    ------
    UsageError
        For an unknown criterion or an ``n`` out of range.
    """
    start = time.perf_counter()
    if criterion not in CRITERIA:
        raise UsageError(f"unknown design criterion {criterion!r}; valid: {', '.join(CRITERIA)}")
    _check_n(n, len(candidates))
    problem = cfg.family.design_problem(model, X, Y, candidates, cfg.random_state)
    batch = greedy_design(problem.blocks, problem.information, n, criterion=criterion)
    rows = candidates.iloc[batch.index]
    targets = [str(t) for t in Y.columns]
    pred = np.asarray(model.predict(rows), dtype=float).reshape(len(rows), len(targets))
    sd = batch.sd * problem.noise_sd
    columns: dict[str, object] = {"design_rank": np.arange(1, n + 1),
                                  "design_gain": batch.gain}
    for j, t in enumerate(targets):
        columns[f"{t}_predicted"] = pred[:, j]
        columns[f"{t}_sd"] = sd[:, j]
    columns["design_reason"] = _reasons(batch, problem, targets)
    chosen = pd.DataFrame(columns, index=rows.index)
    return Design(chosen=chosen, batch=batch, problem=problem, n_rows=len(X),
                  n_candidates=len(candidates), seconds=time.perf_counter() - start)


def _checked(cfg: ExperimentConfig,
             candidates: pd.DataFrame) -> tuple[Dataset, pd.DataFrame, pd.DataFrame]:
    ds = load_dataset(cfg)
    X_all = cfg.family.inputs(cfg, ds)
    try:
        C = check_inputs(candidates, list(X_all.columns), where="candidates")
    except InputError as exc:
        raise UsageError(str(exc)) from None
    return ds, X_all, C


def _design(cfg: ExperimentConfig, ds: Dataset, X_all: pd.DataFrame, C: pd.DataFrame, n: int,
            criterion: str) -> Design:
    X, Y = X_all.loc[ds.train_index], ds.targets.loc[ds.train_index]
    log.info("[%s] fitting on %d training rows, then choosing %d of %d candidates", cfg.name,
             len(X), n, len(C))
    model = quiet_fit(cfg.family.build(cfg, ds), X, Y)
    return choose(cfg, model, X, Y, C, n, criterion)


def design(cfg: ExperimentConfig, candidates: pd.DataFrame, n: int,
           criterion: str = "i") -> Design:
    """Fit the config's model on its training rows and choose ``n`` of the ``candidates``.

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config.
    candidates : DataFrame
        Any frame holding the family's input columns by name (checked like a served model's
        input).
    n : int
        How many to choose.
    criterion : {"i", "d"}, default="i"
        The design criterion (:func:`choose`).

    Returns
    -------
    Design
        The picks, in the order chosen.

    Raises
    ------
    UsageError
        For candidates without the model's inputs, an unknown criterion or an ``n`` out of
        range.
    """
    ds, X_all, C = _checked(cfg, candidates)
    return _design(cfg, ds, X_all, C, n, criterion)


def design_columns(targets: list[str]) -> list[str]:
    """List the columns ``workbench design`` adds to the chosen rows.

    Parameters
    ----------
    targets : list of str
        The dataset's targets.

    Returns
    -------
    list of str
        ``design_rank``, ``design_gain``, ``<target>_predicted`` and ``<target>_sd`` per
        target, ``design_reason``.
    """
    return ["design_rank", "design_gain", *(f"{t}_{s}" for t in targets
                                            for s in ("predicted", "sd")), "design_reason"]


def design_csv(cfg: ExperimentConfig, candidates: str | Path, n: int, out: str | Path,
               criterion: str = "i") -> Design:
    """Run :func:`design` on a candidates CSV and write the chosen rows to ``out``.

    The file (see the module docstring) is written atomically; every input is checked before
    the model is fitted.

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config.
    candidates : str or Path
        The candidates CSV.
    n : int
        How many to choose.
    out : str or Path
        Where the chosen rows go.
    criterion : {"i", "d"}, default="i"
        The design criterion (:func:`choose`).

    Returns
    -------
    Design
        The picks, in the order chosen.

    Raises
    ------
    UsageError
        For an unreadable candidates file, columns design would overwrite, or any
        :func:`design` error.
    """
    check_file(out, "--out")
    try:
        text = _read(Path(candidates))
    except DatasetError as exc:
        raise UsageError(f"--candidates: {exc}") from None
    ds, X_all, C = _checked(cfg, text)
    clash = [c for c in design_columns(ds.target_names) if c in text.columns]
    if clash:
        raise UsageError(f"--candidates: column(s) {clash} are names design writes; rename "
                         "them")
    _check_n(n, len(C))  # before the fit
    done = _design(cfg, ds, X_all, C, n, criterion)
    table = pd.concat([text.loc[done.chosen.index], done.chosen], axis=1)
    write_file(out, table.to_csv(index=False), "--out")
    return done


ARMS = ("design", "random")


@dataclass
class Acquisition:
    """One closed loop: the test MAE (average over targets) after each batch.

    Parameters
    ----------
    arm : {"design", "random"}
        How each batch was chosen.
    seed : int
        The loop's seed.
    n_measured, test_mae : list
        After each batch, the rows measured and the test MAE of the model fitted on them.
    chosen : list, default=[]
        The index labels chosen, in order.
    seconds : float, default=0.0
        The loop's wall time.
    """

    arm: str
    seed: int
    n_measured: list[int]
    test_mae: list[float]
    chosen: list[Any] = field(default_factory=list)
    seconds: float = 0.0


def acquisition_loop(cfg: ExperimentConfig, ds: Dataset, pool: Any, test: Any, *,
                     arm: str = "design", seed: int = 0, start: int = 20, batch: int = 10,
                     stop: int = 200, criterion: str = "i",
                     progress: Callable[[Acquisition], None] | None = None) -> Acquisition:
    """Run one closed calibration loop, from ``start`` random rows of ``pool`` to ``stop``.

    Each batch of ``batch`` rows is chosen by :func:`choose` (``arm="design"``) or at random
    (``"random"``); after each batch the config's model is refitted on the chosen rows and
    scored on the ``test`` rows. The starting rows depend on ``seed`` only, so both arms of a
    seed start alike.

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config.
    ds : Dataset
        The dataset.
    pool : iterable
        Index labels of ``ds`` whose targets are revealed only when chosen.
    test : list-like
        Index labels of the rows scored after each batch.
    arm : {"design", "random"}, default="design"
        How each batch is chosen.
    seed : int, default=0
        Seeds the starting rows and the random picks.
    start, batch, stop : int
        The starting rows, the rows per batch and the rows at which the loop stops.
    criterion : {"i", "d"}, default="i"
        The design criterion (:func:`choose`).
    progress : callable, optional
        Called with the :class:`Acquisition` so far after each batch.

    Returns
    -------
    Acquisition
        The test MAE after each batch.

    Raises
    ------
    ValueError
        For an unknown ``arm``.
    """
    if arm not in ARMS:
        raise ValueError(f"unknown arm {arm!r}; valid: {', '.join(ARMS)}")
    t0 = time.perf_counter()
    family = cfg.family
    X_all, Y_all = family.inputs(cfg, ds), ds.targets
    pool = list(pool)
    rng = np.random.default_rng(seed)
    chosen = [pool[i] for i in rng.choice(len(pool), min(start, len(pool)), replace=False)]
    X_test, y_test = X_all.loc[test], Y_all.loc[test].to_numpy(dtype=float)
    out = Acquisition(arm=arm, seed=seed, n_measured=[], test_mae=[])
    while True:
        X, Y = X_all.loc[chosen], Y_all.loc[chosen]
        model = quiet_fit(family.build(cfg, ds), X, Y)
        pred = np.asarray(model.predict(X_test), dtype=float).reshape(y_test.shape)
        out.n_measured.append(len(chosen))
        out.test_mae.append(mean_absolute_error(y_test, pred))
        if progress is not None:
            progress(out)
        taken = set(chosen)
        rest = [i for i in pool if i not in taken]
        k = min(batch, stop - len(chosen), len(rest))
        if k <= 0:
            break
        if arm == "random":
            picks = [rest[i] for i in rng.choice(len(rest), k, replace=False)]
        else:
            picks = [rest[i] for i in choose(cfg, model, X, Y, X_all.loc[rest], k,
                                             criterion).batch.index]
        chosen += picks
    out.chosen = chosen
    out.seconds = time.perf_counter() - t0
    return out
