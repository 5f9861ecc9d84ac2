"""Benchmark tables of docs/benchmarks.md, made from the JSON the benchmark scripts write.

    python benchmarks/tables.py           # docs/benchmarks.md's tables remade from the JSON
    python benchmarks/tables.py --check   # exit 1 if its tables differ from the JSON
    python benchmarks/tables.py --readme reports/results.json   # README.md's results

Each table sits in docs/benchmarks.md between ``<!-- bench:NAME -->`` and
``<!-- /bench:NAME -->`` and is made from ``benchmarks/results/NAME.json`` (written by
``scaling.py --json``, ``bootstrap.py --json``, ``vs_reference.py --json``,
``peers.py --json``, ``outside.py --json``, ``first_run.py --json --suite-json``) with the
date, commit, machine and load it was measured on; a block whose JSON is not there yet says
so. A number in those tables is never typed by hand: a slower or faster run changes the table
(and tests/test_readme.py fails until docs/benchmarks.md is remade).

README.md's results, between ``<!-- results -->`` and ``<!-- /results -->``, are made the
same way from ``make run``'s ``reports/results.json`` (:func:`readme_results`; ``make run``
remakes them). Each part names the command that made it: the Google table ``make run``,
the IBM gates' paragraph ``workbench reproduce --all``; a results.json without the IBM
benchmark (``make run``'s) leaves the README's paragraph as it was (its last ``--all``
values). ``reproduce --quick`` computes the rows of :data:`QUICK_ROWS` as the full run
does, and tests/test_reproduce.py checks the README's against its JSON.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results"
PAGE = ROOT / "docs" / "benchmarks.md"
README = ROOT / "README.md"
#: The README's rows that ``reproduce --quick`` computes as the full run does (it shortens
#: the search, the parameter-space model's selection and the IBM benchmark's budgets).
QUICK_ROWS = ("control program (prior)",
              "reference implementation, paper settings (mean of 8 runs)",
              "workbench, paper settings")

SCALING_LABELS = {
    "ridge": "eigenvalue, ridge basis",
    "lightgbm": "eigenvalue, LightGBM (100 trees)",
    "kernel_ridge": "eigenvalue, kernel ridge (`simulated_device.toml`'s basis)",
    "hamiltonian": "parameter space, fixed covariates",
}


def _measured(meta: dict) -> str:
    load = meta["load_before"].split("load average:")[-1].strip()
    return (f"Measured {meta['date']} at commit {meta['commit']} on {meta['cores']} cores "
            f"({meta['machine']}, Python {meta['python']}; load average before: {load}).")


def _num(x: float) -> str:
    return f"{x:.3f}" if x < 0.1 else f"{x:.2f}"


def scaling(data: dict) -> str:
    """Seconds per 1,000 rows against rows (5 sites), then seconds against sites."""
    points = [p for p in data["points"] if "error" not in p]
    rows = sorted({p["rows"] for p in points if p["sites"] == 5})
    cases = list(dict.fromkeys(p["case"] for p in points))
    top = max(rows)
    lines = ["| config | " + " | ".join(f"{r:,}" for r in rows)
             + f" rows | peak MiB at {top:,} |",
             "|---" * (len(rows) + 2) + "|"]
    for case in cases:
        by_rows = {p["rows"]: p for p in points if p["case"] == case and p["sites"] == 5}
        cells = [_num(by_rows[r]["per_1k_rows"]) if r in by_rows else "" for r in rows]
        peak = f"{by_rows[top]['peak_mib']:.0f}" if top in by_rows else ""
        lines.append(f"| {SCALING_LABELS.get(case, case)} | " + " | ".join(cells)
                     + f" | {peak} |")
    lines.append("")
    lines.append("Seconds of `evaluate` against sites:")
    lines.append("")
    sites = sorted({p["sites"] for p in points})
    lines.append("| config | rows | " + " | ".join(f"{s} sites" for s in sites) + " |")
    lines.append("|---" * (len(sites) + 2) + "|")
    for case in cases:
        at = {p["rows"] for p in points if p["case"] == case and p["sites"] != 5}
        for n in sorted(at):
            by_sites = {p["sites"]: p for p in points if p["case"] == case and p["rows"] == n}
            cells = [f"{by_sites[s]['wall']:.2f}" if s in by_sites else "" for s in sites]
            lines.append(f"| {SCALING_LABELS.get(case, case)} | {n:,} | " + " | ".join(cells)
                         + " |")
    return "\n".join([_measured(data["measured"]), "", *lines])


def bootstrap(data: dict) -> str:
    """Cornish-Fisher against the percentile bootstrap, per data set and size."""
    lines = ["| data | test rows | largest CF - percentile | two seeds' largest difference "
             "| percentile s | CF s | evaluate uses |", "|---" * 7 + "|"]
    for r in data["rows"]:
        lines.append(f"| {r['data']} | {r['rows']:,} | {r['cf_vs_percentile']:.3f} | "
                     f"{r['seed_vs_seed']:.3f} | {r['percentile_s']:.2f} | "
                     f"{r['cornish_fisher_s']:.3f} | {r['evaluate_uses'].replace('_', '-')} |")
    return "\n".join([_measured(data["measured"]), "", *lines])


REFERENCE_JOBS = {
    "paper": "paper settings on the benchmark, whole process (`evaluate paper_main_body.toml "
             "--no-track --no-intervals`)",
    "default": "the default command, `evaluate paper_main_body.toml` (tracked: 90% intervals, "
               "curves, SHAP, figures, model)",
    "curve": "augmented learning curve of Y3, 7 sizes x 5 folds, whole process",
}


def reference(data: dict) -> str:
    """The workbench against the paper's reference implementation (medians of paired runs)."""
    lines = ["| job | workbench wall / CPU s | reference wall / CPU s | reference / workbench "
             "(wall) |", "|---" * 4 + "|"]
    for r in data["jobs"]:
        ref = (f"{r['reference_wall']:.1f} / {r['reference_cpu']:.1f}"
               if "reference_wall" in r else "not run")
        ratio = (f"{r['reference_wall'] / r['workbench_wall']:.2f}"
                 if "reference_wall" in r else "")
        lines.append(f"| {REFERENCE_JOBS.get(r['job'], r['job'])} ({r['runs']} paired runs) | "
                     f"{r['workbench_wall']:.1f} / {r['workbench_cpu']:.1f} | {ref} | {ratio} |")
    return "\n".join([_measured(data["measured"]), "", *lines])


PEER_DATASETS = {
    "ibm": "IBM gates, time split (honest)",
    "ibm_devices": "IBM gates, 30% of devices held out",
    "google": "Google 5 qubits, paper split",
    "chain": "simulated 5-site chain, 400 experiments",
    "grid": "simulated 3x3 grid, 600 experiments",
    "none": "simulated chain, exact control model",
}


def peers(data: dict) -> str:
    """The recommended config against the peer (``benchmarks/peers.py``), per split, and the
    sum per data set."""
    def ci(pair) -> str:
        return f"({pair[0]:.3f}-{pair[1]:.3f})"

    lines = ["| data set, split | seed | test rows | prior | peer | generic config "
             "| generic / peer | generic - peer | CV chose | seconds: peer, generic |",
             "|---" * 10 + "|"]
    for r in data["rows"]:
        chosen = ", ".join(sorted(set(r.get("chosen") or r["selected"])))
        lines.append(
            f"| {PEER_DATASETS.get(r['dataset'], r['dataset'])} | "
            f"{r.get('split_seed', r['seed'])} | "
            f"{r['test_rows']:,} | {r['prior']:.3f} {ci(r['ci']['prior'])} | "
            f"{r['peer']:.3f} {ci(r['ci']['peer'])} | "
            f"{r['workbench']:.3f} {ci(r['ci']['workbench'])} | "
            f"{r['workbench'] / r['peer']:.3f} | {r['diff'][0]:+.3f} to {r['diff'][1]:+.3f} | "
            f"{chosen} | {r['peer_s']:.0f}, {r['workbench_s']:.0f} |")
    sums = ["", "| data set | splits | peer, summed | generic, summed | generic / peer |",
            "|---" * 5 + "|"]
    for name in dict.fromkeys(r["dataset"] for r in data["rows"]):
        rows = [r for r in data["rows"] if r["dataset"] == name]
        peer = sum(r["peer"] for r in rows)
        generic = sum(r["workbench"] for r in rows)
        sums.append(f"| {PEER_DATASETS.get(name, name)} | {len(rows)} | {peer:.3f} | "
                    f"{generic:.3f} | {generic / peer:.3f} |")
    head = (f"Config `{data['config']}`; the peer: {data['trials']} Optuna trials per target, "
            f"LightGBM's objective {data['peer_objectives']}.")
    return "\n".join([_measured(data["measured"]), head, "", *lines, *sums])


def peer_bound(data: dict) -> str:
    """How far ahead of the peer the generic config's candidates get, chosen by CV, by three
    choosers that see only the training rows, by a random pick among the candidates CV
    cannot tell apart, and by oracles that see the test rows, on all of them or on half
    (``benchmarks/peer_bound.py``), summed per data set."""
    keys = ("cv", "greedy", "top_k", "tied_mean", "tied_pick", "best_single", "best_mean",
            "held_out_single", "held_out_mean")
    lines = ["| data set | splits | CV's choice | greedy ensemble | top k | mean of the tied "
             "| random tied pick | oracle, best single | oracle, best mean "
             "| held-out oracle, single | held-out oracle, mean |", "|---" * 11 + "|"]
    for name in dict.fromkeys(r["dataset"] for r in data["rows"]):
        rows = [r for r in data["rows"] if r["dataset"] == name and r["peer"]]
        peer = sum(r["peer"] for r in rows)
        ratios = " | ".join(f"{sum(r[k] for r in rows) / peer:.3f}" for k in keys)
        lines.append(f"| {PEER_DATASETS.get(name, name)} | {len(rows)} | {ratios} |")
    head = (f"Config `{data['config']}`; test MAE summed over the splits / the peer's "
            "(`peers.json`).")
    return "\n".join([_measured(data["measured"]), head, "", *lines])


def peer_gap(data: dict) -> str:
    """The generic config against the peer on the outside sets' validation rows (their
    training rows split again; ``benchmarks/peer_gap.py``): per set, the validation MAE of
    the prior, the peer, each variant of the config and the bound of its candidates chosen
    on the validation rows, each as a ratio to the peer's; then the mean and worst ratio."""
    variants = list(data["variants"])
    oracle = ("best_single", "best_mean", "held_out_single", "held_out_mean")
    has_oracle = all("oracle" in r for r in data["rows"])
    names = {"prior": "prior", "best_single": "oracle, best single",
             "best_mean": "oracle, best mean", "held_out_single": "held-out oracle, single",
             "held_out_mean": "held-out oracle, mean"}
    cols = ["prior", *variants, *(oracle if has_oracle else ())]
    lines = ["| set | inner train / validation rows | peer | "
             + " | ".join(names.get(c, f"`{c}`") for c in cols) + " |",
             "|---" * (3 + len(cols)) + "|"]
    for r in data["rows"]:
        values = {"prior": r["prior"], **{v: r["variants"][v]["mae"] for v in variants},
                  **(r["oracle"] if has_oracle else {})}
        lines.append(f"| `{r['set']}` | {r['train_rows']:,} / {r['validation_rows']:,} | "
                     f"{r['peer']:.4g} | "
                     + " | ".join(f"{values[c] / r['peer']:.3f}" for c in cols) + " |")
    summary = data["summary"]
    keys = [*variants, *(f"oracle:{k}" for k in oracle if has_oracle)]
    mean = " | ".join(f"{summary[k]['mean_ratio_to_peer']:.3f}" for k in keys)
    worst = " | ".join(f"{summary[k]['worst_ratio_to_peer']:.3f}" for k in keys)
    prior = [r["prior"] / r["peer"] for r in data["rows"]]
    lines.append(f"| mean | | | {sum(prior) / len(prior):.3f} | {mean} |")
    lines.append(f"| worst | | | {max(prior):.3f} | {worst} |")
    worse = ", ".join(f"`{v}` {summary[v]['worse_than_prior']}" for v in variants)
    head = (f"Config `{data['config']}`; the peer: {data['trials']} Optuna trials; validation "
            f"MAE / the peer's (1 = the peer; below 1 ahead of it). Sets where a variant is "
            f"worse than the prior: {worse}.")
    return "\n".join([_measured(data["measured"]), head, "", *lines])


def outside(data: dict) -> str:
    """The recommended config against the prior and the peer on the outside sets
    (``benchmarks/outside.py``): one row per set, a win, tie or loss against the peer by the
    paired interval, then the summary the issue's goals are stated in."""
    def ci(pair) -> str:
        return f"{pair[0]:+.3g} to {pair[1]:+.3g}"

    def verdict(r: dict) -> str:
        if "error" in r:
            return "**failed**"
        if r["generic_minus_prior"][0] > 0:
            return "**worse than prior**"
        low, high = r["generic_minus_peer"]
        return "win" if high < 0 else "loss" if low > 0 else "tie"

    lines = ["| kind | set (split) | train / test rows | prior | peer | generic "
             "| generic - prior | generic - peer | generic / peer | vs peer | CV chose "
             "| wall / CPU s: peer, generic |", "|---" * 12 + "|"]
    for r in data["rows"]:
        if "error" in r:
            lines.append(f"| {r['kind']} | `{r['set']}`: {r['description']} | "
                         f"{r['train_rows']:,} / {r['test_rows']:,} | | | | | | | "
                         f"{verdict(r)} | {r['error'].replace('|', '/')} | |")
            continue
        s = r["seconds"]
        chosen = ", ".join(sorted({c["chosen"] for c in r["cv"].values()})) or "-"
        lines.append(
            f"| {r['kind']} | `{r['set']}`: {r['description']} | "
            f"{r['train_rows']:,} / {r['test_rows']:,} | {r['prior']:.4g} | {r['peer']:.4g} | "
            f"{r['generic']:.4g} | {ci(r['generic_minus_prior'])} | "
            f"{ci(r['generic_minus_peer'])} | {r['ratio_to_peer']:.3f} | {verdict(r)} | "
            f"{chosen} | {s['peer_wall']:.0f} / {s['peer_cpu']:.0f}, "
            f"{s['generic_wall']:.0f} / {s['generic_cpu']:.0f} |")
    t = data["summary"]
    v = t["verdicts"]
    head = (f"Config `{data['config']}`"
            + (f" with `{' '.join(data['overrides'])}`" if data["overrides"] else "")
            + f"; the peer: {data['trials']} Optuna trials, LightGBM's objective searched"
            + ("; **a reduced run** (fewer trials or draws than `make bench-outside`)"
               if data["reduced"] else "") + ". Test MAE in each set's unit; intervals: "
            "paired 95% bootstrap over the test rows.")
    foot = (f"Over {t['sets']} sets ({t['failed']} failed): generic / peer "
            f"{t['mean_ratio_to_peer']:.3f} on average "
            f"(goal <= 0.92), worst {t['worst_ratio_to_peer']:.3f} (goal <= 1.03); worse than "
            f"the prior beyond the interval on {t['worse_than_prior']}; against the peer "
            f"{v['win']} wins, {v['tie']} ties, {v['loss']} losses. Seen: every test score "
            "here (a config change chosen for them would be tuned to these sets).")
    return "\n".join([_measured(data["measured"]), head, "", *lines, "", foot])


FIRST_RUN_STEPS = {
    "reference": "the reference implementation's paper-settings script (median of {runs})",
    "install": "`make install`: a new venv, empty caches (uv's, the data's)",
    "reproduce": "`make run`'s reproduction (`workbench reproduce`)",
    "lint": "`make test`'s lint (`ruff check`, `mypy`)",
    "suite": "`make test`'s suite (`pytest -n 2`)",
}


def first_run(data: dict) -> str:
    """A newcomer's first commands against the reference script (``first_run.py``)."""
    steps, ref = data["steps"], data["steps"].get("reference")
    lines = ["| step | wall s | CPU s | wall / reference script |", "|---" * 4 + "|"]
    for key, label in FIRST_RUN_STEPS.items():
        step = steps.get(key)
        if step is None:
            continue
        ratio = f"{step['wall_s'] / ref['wall_s']:.1f}x" if ref else ""
        lines.append(f"| {label.format(runs=step.get('runs', 1))} | {step['wall_s']:.1f} | "
                     f"{step['cpu_s']:.1f} | {ratio} |")
    targets = data["targets"]
    names = {"make_run": "`make run` whole (install + reproduction)",
             "reproduce": "the reproduction", "make_test": "`make test` (lint + suite)",
             "suite": "the suite"}
    shown = [f"{names[k]} {v:.1f}x (target <= {targets[k]:.0f}x)"
             for k, v in data["ratios"].items() if k in names]
    tail = ["", "Against the reference script: " + "; ".join(shown) + "."] if shown else []
    return "\n".join([_measured(data["measured"]), "", *lines, *tail])


def suite_cost(data: dict) -> str:
    """The default suite's files by CPU seconds (``suite_cost.py``), the 15 costliest."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from suite_cost import table

    return "\n".join([_measured(data["measured"]), "", table(data, top=15)])


#: The first words of the README's paragraph on the IBM gates (``reproduce --all``'s).
GATES_PARAGRAPH = "On the IBM two-qubit gates"


def readme_gates(gates: dict) -> str:
    """The README's paragraph on the IBM gates from results.json's ``ibm_gates``."""
    return "\n".join([
        f"{GATES_PARAGRAPH} (`workbench reproduce --all`; {gates['generic']['n_test']:,} test "
        f"gates of devices", "never seen, gate error in percent): coherence limit "
        f"{gates['generic']['prior']['test_mae_avg']:.3f}, a tuned LightGBM boosted from",
        f"the prior {gates['peer']['model']['test_mae_avg']:.3f}, the generic config "
        f"`experiments/generic.toml` {gates['generic']['model']['test_mae_avg']:.3f}."])


def readme_results(res: dict, old: str | None = None) -> str:
    """README.md's results block from ``reports/results.json`` (``res``); without its IBM
    benchmark (``make run``'s), the IBM paragraph of ``old`` (the block as it was) is kept."""
    settings = res["settings"]
    reference = res["reference"]["scikit-physlearn, paper settings (mean of 8 runs)"]

    def row(label: str, values: list[float], average: float) -> str:
        return "| " + " | ".join([label, *(f"{v:.3f}" for v in values), f"{average:.3f}"]) \
            + " |"

    def scores(part: dict) -> list:
        return [part["test_mae"], part["test_mae_avg"]]

    head = "| system | " + " | ".join(res["short"]) + " | average |"
    lines = [
        f"The paper's settings on the Google 5-qubit benchmark (`make run`; test MAE on the "
        f"{settings['paper']['n_test']} test",
        # a results.json from before issue 44 says "seed"
        f"rows, {res['unit']}, seed {res.get('random_state', res.get('seed'))}):", "",
        head, "|---" * (len(res["short"]) + 2) + "|",
        row(QUICK_ROWS[0], *scores(settings["paper"]["prior"])),
        row(QUICK_ROWS[1], *reference),
        row(QUICK_ROWS[2], *scores(settings["paper"]["model"])),
        row("workbench, parameter-space model (`hamiltonian.toml`)",
            *scores(settings["hamiltonian"]["model"]))]
    if "ibm_gates" in res:
        lines += ["", readme_gates(res["ibm_gates"])]
    elif old is not None and GATES_PARAGRAPH in old:
        kept = old[old.index(GATES_PARAGRAPH):].split("\n\n")[0].rstrip("\n")
        lines += ["", kept]
    return "\n".join(lines)


def render_readme(text: str, res: dict) -> str:
    """``text`` (README.md's) with its ``<!-- results -->`` block remade from ``res``."""
    pattern = re.compile(r"(<!-- results -->\n).*?(<!-- /results -->)", re.S)
    match = pattern.search(text)
    if match is None:
        raise ValueError("README.md has no <!-- results --> block")
    block = readme_results(res, text[match.end(1):match.start(2)])
    return pattern.sub(lambda m: m.group(1) + block + "\n" + m.group(2), text)


TABLES: dict[str, Callable[[dict], str]] = {"scaling": scaling, "bootstrap": bootstrap,
                                            "reference": reference, "peers": peers,
                                            "peer_bound": peer_bound, "outside": outside,
                                            "peer_gap": peer_gap,
                                            "first_run": first_run, "suite_cost": suite_cost}
#: What a block says before its JSON is written.
NOT_MEASURED = "Not measured yet: `make bench` writes `benchmarks/results/{name}.json`."


def render(text: str) -> str:
    """``text`` with every ``<!-- bench:NAME -->`` block remade from its JSON."""
    for name, make in TABLES.items():
        pattern = re.compile(rf"(<!-- bench:{name} -->\n).*?(<!-- /bench:{name} -->)", re.S)
        if not pattern.search(text):
            continue
        path = RESULTS / f"{name}.json"
        table = (make(json.loads(path.read_text())) if path.is_file()
                 else NOT_MEASURED.format(name=name))
        text = pattern.sub(lambda m, t=table: m.group(1) + t + "\n" + m.group(2), text)
    return text


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--check", action="store_true",
                        help="only check: exit 1 where docs/benchmarks.md's tables are not "
                        "the JSON's")
    parser.add_argument("--readme", type=Path, metavar="RESULTS_JSON",
                        help="remake README.md's results from this reports/results.json instead")
    args = parser.parse_args()
    if args.readme:
        res = json.loads(args.readme.read_text())
        if res.get("quick"):
            print(f"{args.readme} is a reproduce --quick run's: README.md keeps the full "
                  "run's results", file=sys.stderr)
            return 1
        old = README.read_text()
        new = render_readme(old, res)
        if args.check:
            return int(new != old)
        README.write_text(new)
        return 0
    old = PAGE.read_text()
    new = render(old)
    if args.check:
        if new != old:
            print("docs/benchmarks.md's benchmark tables differ from "
                  "benchmarks/results/*.json: run python benchmarks/tables.py", file=sys.stderr)
            return 1
        return 0
    PAGE.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
