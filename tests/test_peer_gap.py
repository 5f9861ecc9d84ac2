"""benchmarks/peer_gap.py: its summary, the merge of runs split over processes, the table, and
the candidates it adds beside the config's own (benchmarks/peer_candidates.py)."""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]


def _module(name: str):
    if str(ROOT / "benchmarks") not in sys.path:
        sys.path.insert(0, str(ROOT / "benchmarks"))
    return importlib.import_module(name)


def _row(name: str, prior: float, peer: float, **maes: float) -> dict:
    return {"set": name, "train_rows": 10, "validation_rows": 5, "prior": prior, "peer": peer,
            "peer_params": [{}], "cpu_s": {"peer": 1.0},
            "variants": {v: {"mae": m, "chosen": {"y": "prior"}} for v, m in maes.items()}}


def test_summary_counts_ratios_to_the_peer_and_sets_worse_than_the_prior() -> None:
    gap = _module("peer_gap")
    rows = [_row("a", prior=2.0, peer=1.0, base=0.9), _row("b", prior=1.0, peer=1.0, base=1.1)]
    s = gap.summarise(rows, ["base"])["base"]
    assert np.isclose(s["mean_ratio_to_peer"], 1.0)
    assert np.isclose(s["worst_ratio_to_peer"], 1.1)
    assert s["more_than_3pct_behind_peer"] == 1
    assert s["worse_than_prior"] == 1


def test_merge_joins_sets_and_variants_run_apart(tmp_path: Path) -> None:
    gap, tables = _module("peer_gap"), _module("tables")
    meta = {"date": "2026-01-01", "commit": "abc1234", "cores": 2, "machine": "x86_64",
            "python": "3.11", "load_before": "load average: 1.0, 1.0, 1.0",
            "load_after": "load average: 2.0, 2.0, 2.0"}
    runs = [{"measured": meta, "config": "generic.toml", "overrides": [], "trials": 50,
             "variants": {"base": {}}, "rows": [_row("a", 2.0, 1.0, base=0.9),
                                                _row("b", 2.0, 1.0, base=1.2)]},
            {"measured": meta, "config": "generic.toml", "overrides": [], "trials": 50,
             "variants": {"new": {}}, "rows": [_row("a", 2.0, 1.0, new=0.8)]},
            {"measured": meta, "config": "generic.toml", "overrides": [], "trials": 50,
             "variants": {"new": {}}, "rows": [_row("b", 2.0, 1.0, new=1.0)]}]
    paths = []
    for i, run in enumerate(runs):
        paths.append(tmp_path / f"{i}.json")
        paths[-1].write_text(json.dumps(run))
    out = tmp_path / "merged.json"
    gap.merge(paths, out)
    data = json.loads(out.read_text())
    assert [r["set"] for r in data["rows"]] == ["a", "b"]
    assert set(data["rows"][1]["variants"]) == {"base", "new"}
    assert np.isclose(data["summary"]["new"]["mean_ratio_to_peer"], 0.9)
    assert np.isclose(data["summary"]["base"]["worst_ratio_to_peer"], 1.2)
    table = tables.peer_gap(data)
    assert "| `b` | 10 / 5 | 1 | 2.000 | 1.200 | 1.000 |" in table
    assert "| mean | | | 2.000 | 1.050 | 0.900 |" in table


def test_added_candidates_share_the_prior_inputs_and_link_of_the_config_s() -> None:
    from workbench import BaseBoostRegressor
    from workbench.multitarget import MultiTargetBaseBoost
    from workbench.selection import BasisChoiceCV, find_prior

    cands = _module("peer_candidates")
    lgbm = BaseBoostRegressor(prior="p", basis=cands.LGBMRegressor(n_estimators=5, verbose=-1),
                              basis_features=["p", "x"], link="identity")
    est = BasisChoiceCV([("lightgbm#00/identity", lgbm)], cv=3)
    model = MultiTargetBaseBoost(target_estimators={"y": est})
    cands.add_candidates(model, ("early", "peer_params"), SimpleNamespace(random_state=0),
                         None, [{"n_estimators": 7, "num_leaves": 4}])
    names = [n for n, _ in est.candidates]
    assert names == ["lightgbm#00/identity", "early", "peer_params"]
    for _, c in est.candidates[1:]:
        assert find_prior(c) == "p" and c.basis_features == ["p", "x"]
    assert est.candidates[2][1].basis.get_params()["n_estimators"] == 7
    rng = np.random.default_rng(0)
    X = pd.DataFrame({"p": rng.normal(size=120), "x": rng.normal(size=120)})
    y = X["p"] + np.sin(3 * X["x"])
    est.fit(X, y.to_numpy())
    assert np.all(np.isfinite(est.candidate_scores_["early"]))


def test_the_halving_candidate_races_the_draws_of_its_own_link() -> None:
    from workbench import BaseBoostRegressor, HalvingChoiceCV
    from workbench.multitarget import MultiTargetBaseBoost
    from workbench.selection import BasisChoiceCV

    cands = _module("peer_candidates")

    def drawn(i: int, link: str) -> tuple[str, BaseBoostRegressor]:
        basis = cands.LGBMRegressor(n_estimators=5 + i, verbose=-1)
        return (f"lightgbm#{i:02d}/{link}",
                BaseBoostRegressor(prior="p", basis=basis, basis_features=["p"], link=link))

    est = BasisChoiceCV([drawn(i, link) for i in range(3) for link in ("identity", "log")],
                        cv=3)
    cands.add_candidates(MultiTargetBaseBoost(target_estimators={"y": est}), ("halving",),
                         SimpleNamespace(random_state=0), None)
    added = dict(est.candidates[6:])
    assert list(added) == ["lightgbm#halving/identity", "lightgbm#halving/log"]
    for link, c in zip(("identity", "log"), added.values()):
        assert c.link == link and isinstance(c.basis, HalvingChoiceCV)
        assert [b.n_estimators for _, b in c.basis.estimators] == [5, 6, 7]
