"""The outside sets without their test rows: where to decide a change of the config.

    python benchmarks/outside_validation.py [--sets ...] [--trials 50] [--set KEY=VALUE ...]
                                            [--config experiments/generic.toml] [--json PATH]

``benchmarks/outside.py`` scores the recommended config on the outside sets' test rows; a
config change chosen for that table would be tuned to those rows. This script drops every
test row and splits each set's *training* rows again by the same kind of rule (the
validation rows: the training rows most like the test rows), then runs the same comparison
(prior, peer, generic with ``--set`` overrides) on that inner split. Compare two configs
here (e.g. ``--set selection.ensemble=1`` against the default) and adopt a change only when
it holds on these rows; the outside table then says, once, whether it held on the test rows.

Inner rules (the test rows are gone before any of them is applied):

* IBM time splits: the training snapshots from 2024 on (the latest before the test
  snapshots); IBM devices splits: 30% of the training devices (seed 1);
* ``nuclear_far``: the 25% of training nuclides farthest from the valley of stability;
  ``nuclear_heavy``: the training nuclides with Z > 70;
* ``chem_tc``, ``chem_pc``: the heaviest 25% of the training compounds;
* ``sim_devices``: two of the seven training devices (five remain, one per CV fold);
  ``sim_bias``: the 30% of training settings with the largest mean coupler bias.
"""

from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))


def _top(values: pd.Series, share: float) -> np.ndarray:
    return (values >= values.quantile(1 - share)).to_numpy()


def _devices(frame: pd.DataFrame, k: int | float, seed: int = 1) -> np.ndarray:
    names = np.array(sorted(frame["device"].unique()))
    n = k if isinstance(k, int) else round(k * len(names))
    held = np.random.default_rng(seed).choice(names, size=n, replace=False)
    return frame["device"].isin(held).to_numpy()


def _ibm_dates(name: str) -> pd.Series:
    from workbench.datasets.ibm_qubits import QUBIT_TARGETS, qubit_table

    prior = QUBIT_TARGETS[name.split("_")[1]][1]
    table = qubit_table()
    return pd.to_datetime(table[table[prior].notna()].reset_index(drop=True)["snapshot"])


def inner_rule(name: str, train: pd.DataFrame) -> np.ndarray:
    """The validation rows among ``train`` (a set's training rows) for set ``name``."""
    if name.startswith("ibm_") and name.endswith("_time"):
        return (_ibm_dates(name).loc[train.index] >= pd.Timestamp("2024-01-01")).to_numpy()
    if name.startswith("ibm_"):
        return _devices(train, 0.3)
    if name == "nuclear_far":
        a = train["A"]
        return _top(((train["N"] - train["Z"]) - 0.4 * a ** 2 / (a + 200)).abs(), 0.25)
    if name == "nuclear_heavy":
        return (train["Z"] > 70).to_numpy()
    if name.startswith("chem_"):
        return _top(train["MW"], 0.25)
    if name == "sim_devices":
        return _devices(train, 2)
    if name == "sim_bias":
        return _top(train[[c for c in train.columns if c.startswith("v_c")]].mean(axis=1), 0.3)
    raise ValueError(f"no inner rule for set {name!r}")


def validation_set(name: str):
    """Set ``name`` with its test rows dropped and its training rows split by its inner
    rule."""
    from outside_data import SETS

    spec = SETS[name]()
    train = spec.frame[spec.frame["split"] == "train"].copy()
    train["split"] = np.where(inner_rule(name, train), "test", "train")
    return dataclasses.replace(spec, frame=train.reset_index(drop=True),
                               description=spec.description + " [validation: training rows "
                               "only, split again]")


def main(argv: list[str] | None = None) -> None:
    import outside
    from outside_data import SETS
    from scaling import write_json

    from workbench.experiment.config.overrides import parse_overrides

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sets", nargs="+", default=list(SETS), choices=list(SETS))
    parser.add_argument("--trials", type=int, default=outside.FULL_TRIALS)
    parser.add_argument("--config", default=str(ROOT / "experiments" / "generic.toml"))
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    overrides = parse_overrides(args.overrides)
    before = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.sets:
            spec = validation_set(name)
            try:
                rows.append(outside._measure(spec, args, overrides, Path(tmp)))
            except Exception as exc:  # noqa: BLE001 - a failure is a result
                rows.append(dict(set=name, error=f"{type(exc).__name__}: {exc}"))
            print(outside._line(rows[-1]), flush=True)
    total = outside.summary(rows)
    print(f"validation rows, {total['sets']} sets ({total['failed']} failed): generic / peer "
          f"mean {total['mean_ratio_to_peer']:.3f}, worst {total['worst_ratio_to_peer']:.3f}; "
          f"{total['verdicts']}")
    if args.json:
        after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
        write_json(args.json, {"config": Path(args.config).name, "overrides": args.overrides,
                               "trials": args.trials, "summary": total, "rows": rows},
                   before, after)


if __name__ == "__main__":
    main()
