"""The outside benchmark (benchmarks/outside.py): its JSON is not older than the code it
measures, its verdicts follow the paired intervals, and its sets are what the docs say
(the physics priors computed by hand, the splits honest: later dates, unseen devices,
extrapolation)."""

from __future__ import annotations

import importlib
import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
RESULT = ROOT / "benchmarks" / "results" / "outside.json"


def _module(name: str):
    """A module of benchmarks/ (which import each other by their plain names)."""
    if str(ROOT / "benchmarks") not in sys.path:
        sys.path.insert(0, str(ROOT / "benchmarks"))
    return importlib.import_module(name)


def _git(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["git", *args], capture_output=True, text=True, cwd=ROOT)


def test_outside_json_is_not_older_than_the_measured_code():
    """benchmarks/results/outside.json was measured at a commit that already holds the last
    change to every file it measures (outside.MEASURED, one list), from a clean tree: change
    the generic config, the selection, the boosting or the peer, and this fails until
    `make bench-outside` is run again (docs/benchmarks.md's table is remade from the JSON)."""
    if shutil.which("git") is None or _git("rev-parse", "HEAD").returncode != 0:
        pytest.skip("not a git checkout")
    if _git("rev-parse", "--is-shallow-repository").stdout.strip() == "true":
        pytest.skip("a shallow clone has no history of the measured files")
    outside = _module("outside")
    data = json.loads(RESULT.read_text())
    assert data["measured_files"] == list(outside.MEASURED), \
        "the measured files changed since the JSON: run make bench-outside"
    assert not data["measured_dirty"], "the JSON was measured with uncommitted measured files"
    last = _git("log", "-1", "--format=%H", "--", *outside.MEASURED).stdout.strip()
    measured_at = data["commit_full"]
    assert _git("cat-file", "-e", f"{measured_at}^{{commit}}").returncode == 0, \
        f"the JSON's commit {measured_at} is not in this repository"
    newer = _git("merge-base", "--is-ancestor", last, measured_at).returncode
    changed = _git("log", "--format=%h %s", f"{measured_at}..HEAD", "--",
                   *outside.MEASURED).stdout.strip()
    assert newer == 0, ("benchmarks/results/outside.json is older than the code it measures "
                        f"(measured at {measured_at[:7]}; changed since:\n{changed}\n): run "
                        "make bench-outside")


def test_verdicts_follow_the_paired_intervals():
    outside = _module("outside")
    row = {"generic_minus_prior": [-0.2, -0.1], "generic_minus_peer": [-0.05, -0.01],
           "ratio_to_peer": 0.9}
    assert outside.verdict(row) == "win"
    assert outside.verdict({**row, "generic_minus_peer": [-0.01, 0.02]}) == "tie"
    assert outside.verdict({**row, "generic_minus_peer": [0.01, 0.02]}) == "loss"
    assert outside.verdict({**row, "generic_minus_prior": [0.01, 0.3]}) == "worse than prior"
    failed = {"set": "x", "error": "ValueError: too few groups"}
    assert outside.verdict(failed) == "failed"
    rows = [row, {**row, "generic_minus_prior": [0.01, 0.3], "ratio_to_peer": 1.1}, failed]
    total = outside.summary(rows)
    assert total["sets"] == 3 and total["failed"] == 1
    assert total["mean_ratio_to_peer"] == pytest.approx(1.0)
    assert total["worst_ratio_to_peer"] == pytest.approx(1.1)
    assert total["worse_than_prior"] == 1 and total["more_than_3pct_behind_peer"] == 1
    assert total["verdicts"] == {"win": 1, "tie": 0, "loss": 0, "worse than prior": 1,
                                 "failed": 1}


def test_the_json_has_every_set_of_the_benchmark_and_three_kinds():
    data = json.loads(RESULT.read_text())
    names = [r["set"] for r in data["rows"]]
    assert len(names) >= 8 and len(set(names)) == len(names)
    assert len({r["kind"] for r in data["rows"]}) >= 3
    for r in data["rows"]:
        assert r["train_rows"] > 0 and r["test_rows"] > 0
        if "error" in r:
            continue
        for key in ("prior", "peer", "generic"):
            low, high = r["ci"][key]
            assert low <= r[key] <= high
        assert r["ratio_to_peer"] == pytest.approx(r["generic"] / r["peer"])


def test_nuclear_masses_and_the_liquid_drop_prior():
    """208Pb by hand: AME2020's mass excess (-21.749 MeV) and the liquid-drop formula's
    binding energy from the textbook coefficients; the splits extrapolate."""
    data = _module("outside_data")
    table = data.nuclide_table()
    pb = table[(table["Z"] == 82) & (table["A"] == 208)].iloc[0]
    assert pb["mass_excess_MeV"] == pytest.approx(-21.749, abs=0.01)
    c, a, z, n = data.SEMF, 208, 82, 126
    binding = (c["volume"] * a - c["surface"] * a ** (2 / 3) - c["coulomb"] * z * (z - 1)
               / a ** (1 / 3) - c["asymmetry"] * (n - z) ** 2 / a + c["pairing"] / a ** 0.5)
    free = z * (1.00782503190 - 1) * data.U_MEV + n * (data.M_NEUTRON_U - 1) * data.U_MEV
    assert pb["semf_mass_excess_MeV"] == pytest.approx(free - binding)
    heavy = data.nuclear("heavy").frame
    assert set(heavy.loc[heavy["split"] == "test", "Z"]) == set(range(83, heavy["Z"].max() + 1))
    far = data.nuclear("far").frame.join(table["valley_distance"])
    test = far["split"] == "test"
    assert far.loc[test, "valley_distance"].abs().min() >= \
        far.loc[~test, "valley_distance"].abs().max()
    assert (far.loc[test, "valley_distance"] > 0).any() and \
        (far.loc[test, "valley_distance"] < 0).any()  # both neutron- and proton-rich


@pytest.mark.parametrize("target", ["tc", "pc"])
def test_critical_constants_hold_out_the_heaviest(target):
    data = _module("outside_data")
    s = data.chem(target)
    f = s.frame
    assert np.isfinite(f[[s.target, s.prior, *s.features]].to_numpy()).all()
    test = f["split"] == "test"
    assert f.loc[test, "MW"].min() >= f.loc[~test, "MW"].max()
    if target == "tc":
        assert (f["guldberg_Tc"] == 1.5 * f["Tb"]).all() and (f["Tc"] > f["Tb"]).all()
    else:
        expected = data.ZC_TYPICAL * data.R_GAS * f["Tc"] / (f["Vc_cm3"] * 1e-6) / 1e5
        assert np.allclose(f["corresponding_states_Pc"], expected)


def test_simulated_sets_hold_out_devices_and_biases():
    data = _module("outside_data")
    devices = data.sim_devices().frame
    by_device = devices.groupby("device")["split"].agg(set)
    assert all(len(s) == 1 for s in by_device) and (by_device == {"test"}).sum() == 3
    grid = data.sim_bias().frame
    mean_c = grid[[c for c in grid.columns if c.startswith("v_c")]].mean(axis=1)
    test = grid["split"] == "test"
    assert mean_c[test].min() >= mean_c[~test].max()


@pytest.mark.parametrize("name", ["chem_pc", "nuclear_heavy", "sim_devices"])
def test_validation_sets_hold_no_test_row(name):
    """benchmarks/outside_validation.py splits a set's training rows again: no test row is
    left, and its validation rows follow the set's own kind of split."""
    data, validation = _module("outside_data"), _module("outside_validation")
    full = data.SETS[name]().frame
    inner = validation.validation_set(name).frame
    assert len(inner) == (full["split"] == "train").sum()
    held = inner["split"] == "test"
    assert 0 < held.sum() < len(inner)
    if name == "chem_pc":
        assert inner.loc[held, "MW"].min() >= inner.loc[~held, "MW"].max()
        assert inner["MW"].max() <= full.loc[full["split"] == "test", "MW"].min()
    elif name == "nuclear_heavy":
        assert inner["Z"].max() <= 82 and inner.loc[held, "Z"].min() > 70
    else:
        assert not set(inner.loc[held, "device"]) & set(inner.loc[~held, "device"])
        assert inner["device"].nunique() == 7
