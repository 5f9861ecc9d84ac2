"""Load a config's dataset and check it against the config.

The data come through the data-source registry (:func:`workbench.datasets.load_source`), then
are checked against the config's folds and prediction intervals.
"""

from __future__ import annotations

import json
from pathlib import Path

from ...conformal import min_calibration_rows
from ...datasets import Dataset, DatasetError, load_source
from ...selection import ordered_splits
from .experiment import ExperimentConfig

__all__ = ["check_ordered_rows", "check_training_rows", "data_key", "load_dataset"]


def load_dataset(cfg: ExperimentConfig) -> Dataset:
    """Load the dataset named by the config's ``[data]`` section (paths relative to the config).

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config.

    Returns
    -------
    Dataset
        The data, loaded by the ``[data] source``'s loader
        (:func:`workbench.datasets.load_source`).

    Raises
    ------
    DatasetError
        For unusable data, including a training split too small for the configured CV
        folds or prediction intervals.
    """
    ds = load_source(cfg.data.source, cfg.data.model_dump(), _base(cfg), cfg.name)
    if cfg.family is not None:  # e.g. the prior a family computes itself
        ds = cfg.family.complete_data(cfg, ds)
    check_training_rows(cfg, len(ds.train_index))
    check_ordered_rows(cfg, ds)
    return ds


def _base(cfg: ExperimentConfig) -> Path:
    """Return the folder the config's relative data paths start from."""
    return cfg.path.parent if cfg.path is not None else Path.cwd()


def data_key(cfg: ExperimentConfig) -> str:
    """Say which data a config loads: its ``[data]`` table and the folder paths start from.

    Configs with equal keys load equal datasets (up to a name the source takes from the
    config, e.g. a CSV's), so a command that runs several of them can load the data once.

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config.

    Returns
    -------
    str
        The key.
    """
    return json.dumps([cfg.data.model_dump(mode="json"), str(_base(cfg).resolve())],
                      sort_keys=True)


def check_training_rows(cfg: ExperimentConfig, n_train: int) -> None:
    """Check that ``n_train`` training rows are enough for the config.

    Enough means enough for ``[selection]``'s folds and ``[intervals]``' calibration.

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config.
    n_train : int
        The dataset's training rows.

    Raises
    ------
    DatasetError
        Naming the section, its values and the rows they need.
    """
    folds = cfg.selection.cv
    if n_train < 2 * folds:
        raise DatasetError(f"the training split has {n_train} rows, too few for "
                           f"[selection] cv = {folds} (each fold needs at least 2 rows: "
                           f"at least {2 * folds} training rows)")
    iv = cfg.intervals
    if not iv.enabled:
        return
    # CV+ calibrates on every training row (each fold needs 2); split on its held-out
    # share (rounded up, as train_test_split does)
    need = min_calibration_rows(iv.alpha)
    if iv.method == "oof":  # every training row is held out once by the model's CV
        least, how = need, "the model's own folds"
    elif iv.method != "split":
        least, how = max(2 * iv.cv, need), f"cv = {iv.cv}"
    else:
        least = int((need - 1) / iv.calibration_fraction) + 1  # ceil(frac n) >= need
        how = f"calibration_fraction = {iv.calibration_fraction}"
    if n_train < least:
        raise DatasetError(f"the training split has {n_train} rows, too few "
                           f"for [intervals] method = {iv.method!r} with {how} and alpha "
                           f"= {iv.alpha} (at least {least}); set a larger alpha or "
                           f"[intervals] enabled = false")


def check_ordered_rows(cfg: ExperimentConfig, ds: Dataset) -> None:
    """Check that the training rows' order values make the config's ordered folds.

    Parameters
    ----------
    cfg : ExperimentConfig
        The checked config (``[selection] cv``).
    ds : Dataset
        Its data (their ``order``, if any).

    Raises
    ------
    DatasetError
        Naming the column, its distinct values and the folds.
    """
    if ds.order is None:
        return
    order, folds = ds.order.loc[ds.train_index], cfg.selection.cv
    try:
        splits = ordered_splits(order.to_numpy(), folds)
    except ValueError:
        raise DatasetError(
            f"order column {order.name!r}: the {len(order)} training rows hold "
            f"{order.nunique()} distinct value(s), too few for [selection] cv = {folds} "
            f"forward-chaining folds (each needs earlier rows to train on and later ones to "
            f"hold out); set fewer folds") from None
    iv, held = cfg.intervals, sum(len(test) for _, test in splits)
    if iv.enabled and iv.method == "oof" and held < min_calibration_rows(iv.alpha):
        raise DatasetError(f"[intervals] method = 'oof': the forward-chaining folds hold out "
                           f"{held} of the {len(order)} training rows, too few to calibrate "
                           f"alpha = {iv.alpha} (at least {min_calibration_rows(iv.alpha)}); "
                           f"set a larger alpha or [intervals] enabled = false")
