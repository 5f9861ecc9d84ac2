"""Handlers of the commands around a model run: ``init``, ``predict`` and ``simulate``.

``init`` writes a first config for a CSV, ``predict`` applies a logged model to new rows and
``simulate`` writes a simulated device's CSV.
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path
from typing import Any

from ..process.errors import UsageError

__all__ = ["init", "predict", "simulate"]


def init(args: argparse.Namespace) -> int:
    """``workbench init``: write a first config for a CSV of one's own.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments.

    Returns
    -------
    int
        The exit code (0).
    """
    from ..runs.init import init_config

    done = init_config(args.data, prior=args.prior, targets=args.target, features=args.features,
                       split_column=args.split_column, test_fraction=args.test_fraction,
                       split_seed=args.split_seed, name=args.name, out=args.out,
                       force=args.force, group_column=args.group_column,
                       order_column=None if args.order_column == "none" else args.order_column,
                       model=args.model)
    if done.defaulted:
        left = "; not taken: " + ", ".join(f"{c!r} ({why})" for c, why in done.skipped.items())
        print(f"features: {', '.join(done.features) or '(none)'} (every other numeric column"
              f"{left if done.skipped else ''}; --features chooses)")
    print(f"wrote {done.path} ({done.n_train} training rows, {done.n_test} test rows)")
    _order_lines(args, done)
    for column, n in done.group_hints.items():
        print(f"note: column {column!r} repeats {n} values over the rows; if rows that share "
              f"one are alike (a device, a date), --group-column {shlex.quote(column)} keeps "
              f"each whole in one CV fold (plain folds reward what only repeats within it)")
    print(f"next: workbench evaluate {shlex.quote(str(done.path))}\n      workbench ui")
    return 0


def _order_lines(args: argparse.Namespace, done: Any) -> None:
    """Say which order column ``init`` found or was given, and what it made of it."""
    order = done.order
    if order is not None:
        test = (f"; the test rows are the latest {done.n_test} (split = \"time\")"
                if done.time_split else "")
        how = "found" if args.order_column == "auto" else "given"
        print(f"order: {how} {order.describe()}: the CV folds chain forward, each training on "
              f"the rows before the ones it holds out ([data] order_column){test}; "
              f"--order-column none: plain folds")
    elif args.order_column == "auto" and args.group_column is None:
        print("order: no column of dates or run numbers found: a random test split and "
              "shuffled folds (--order-column COL names one)")


def predict(args: argparse.Namespace) -> int:
    """``workbench predict``: a logged or registered model on the rows of a CSV.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments.

    Returns
    -------
    int
        The exit code (0).
    """
    from ..tracking.predict import predict_csv
    from ..tracking.uris import resolve_tracking_uri

    uri = resolve_tracking_uri(args.tracking_uri, None, Path.cwd())
    done = predict_csv(args.model, args.data, args.out, tracking_uri=uri)
    print(f"wrote {done.path} ({done.rows} rows: {', '.join(done.targets)}"
          f"{' with intervals' if done.intervals else ''})")
    return 0


def compare(args: argparse.Namespace) -> int:
    """``workbench compare``: two runs' per-target test MAE and their paired interval.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments.

    Returns
    -------
    int
        The exit code (0).
    """
    from ..tracking.compare import compare_runs, format_comparison
    from ..tracking.uris import check_store_uri, resolve_tracking_uri

    uri = resolve_tracking_uri(args.tracking_uri, None, Path.cwd())
    check_store_uri(uri)
    print(format_comparison(compare_runs(uri, args.run_a, args.run_b)))
    return 0


def _mismatch(names: list[str] | None) -> Any:
    """Return the simulation's mismatch mechanisms ``--mismatch`` names."""
    from ...simulate import Mismatch

    if names is None:
        return Mismatch.default()
    if names == ["none"]:
        return Mismatch.none()
    return Mismatch.only(*names)


def _shape(text: str | None) -> tuple[int, int] | None:
    """``--shape RxC`` as ``(rows, cols)``."""
    if text is None:
        return None
    rows, sep, cols = text.lower().partition("x")
    if not (sep and rows.isdigit() and cols.isdigit()):
        raise ValueError(f"--shape must be RxC (e.g. 3x3), got {text!r}")
    return int(rows), int(cols)


def _simulation(args: argparse.Namespace) -> Any:
    """Run the simulation ``simulate``'s arguments ask for.

    Random settings, or ``--settings`` measured on the device of ``--device-seed``.
    """
    from ...simulate import measure
    from ...simulate import simulate as run

    mismatch, shape = _mismatch(args.mismatch), _shape(args.shape)
    if args.settings is None:
        sites = args.sites if args.sites is not None or args.topology == "grid" else 5
        return run(sites, 136 if args.experiments is None else args.experiments,
                   device_seed=args.device_seed, mismatch=mismatch, topology=args.topology,
                   shape=shape, parasitic=args.parasitic)
    from ...datasets import read_numeric_columns

    # the CSV checks of every data file (empty, not a CSV, wrong delimiter, ragged rows),
    # then the bias columns as numbers; measure() says which are missing
    settings = read_numeric_columns(args.settings, r"v_[qc][1-9][0-9]*")
    return measure(settings, device_seed=args.device_seed, mismatch=mismatch,
                   topology=args.topology, n_sites=args.sites, shape=shape,
                   parasitic=args.parasitic, noise_seed=args.noise_seed)


def simulate(args: argparse.Namespace) -> int:
    """``workbench simulate``: simulate a device and write its CSV and truth sidecar.

    Parameters
    ----------
    args : argparse.Namespace
        The command's arguments.

    Returns
    -------
    int
        The exit code (0).

    Raises
    ------
    UsageError
        For contradictory options or values the simulation refuses.
    """
    from ...simulate import write_simulation
    from ..scoring.scores import average, mae

    if args.settings is not None and args.experiments is not None:
        raise UsageError("--settings measures the rows of its CSV; drop --experiments")
    if args.noise_seed is not None and args.settings is None:
        raise UsageError("--noise-seed needs --settings (simulate's noise follows --device-seed)")
    try:
        sim = _simulation(args)
        csv_path, truth_path = write_simulation(sim, args.out)
    except (ValueError, OSError) as exc:
        raise UsageError(str(exc)) from None
    prior_mae = average(mae(sim.data.filter(like="measured_E").to_numpy(),  # over targets
                            sim.data.filter(like="model_E").to_numpy()))
    rows = (f"{len(sim.data)} experiments" if args.settings is None
            else f"measured {len(sim.data)} settings")
    print(f"wrote {csv_path} ({rows}, {sim.truth['n_sites']} sites, "
          f"{sim.truth['graph']['topology']}; prior MAE "
          f"{prior_mae:.3f} MHz) and {truth_path}")
    return 0
