"""Which experiment next: the closed calibration loop, the design against random choice.

    python benchmarks/design.py [--datasets chain grid google] [--seeds 0 1 2 3 4]
                                [--google-seeds 0 1 ... 9] [--criterion i]
                                [--config experiments/design_loop.toml] [--workers 2]
                                [--tracking-uri URI] [--out reports/design]

Each loop (``workbench.experiment.runs.design.acquisition_loop``) starts from 20 experiments
drawn at random from a pool of settings (the seed draws them; both arms start alike), fits
the config's model (experiments/design_loop.toml: the parameter-space model, covariates
chosen by linearised forward selection with 5-fold CV on the rows measured so far), scores it
on held-out test rows, and adds a batch of 10: chosen by ``workbench design``'s criterion
(``design``) or at random (``random``), up to 200 experiments.

* ``chain`` / ``grid``: a simulated 5-site chain / 3x3 grid (default mismatches) of seed
  ``s``; its pool is 600 random settings and its test rows 400 more, all measured by the
  simulator up front and revealed to the loop when chosen (the noise of each row is drawn
  independently, so this is measuring on demand: ``workbench simulate --settings`` does
  the same one batch at a time). Seeds 0-4.
* ``google``: the Google benchmark replayed as a pool: the 95 training rows are the pool,
  the 41 test rows score; ``--google-seeds`` (0-9) draw the 20 starting rows; to 95.

Prints each loop's curve and, per dataset, the median over seeds of the test MAE at each
size (design, random, and the seeds' spread as the interquartile range), the fewest
experiments at which the design's median reaches the random arm's median at its largest
size, and the median ratio design / random at each size. Every dataset's loops are one
MLflow run (sqlite under mlruns/ by default) with the medians as metric series (step =
experiments measured) and the acquisition-curve figure, also written to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
import tomllib
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

SIMULATED = {"chain": dict(n_sites=5, topology="chain", shape=None),
             "grid": dict(n_sites=None, topology="grid", shape=(3, 3))}
POOL, TEST = 600, 400


def simulated_config(name: str, seed: int, base: Path, tmp: Path, pool: int = POOL) -> Path:
    """A CSV of the seed's device (pool rows "train", test rows "test") and ``base`` with
    its ``[data]`` pointed at it."""
    from peers import write_config

    from workbench.simulate import simulate, write_simulation

    spec = SIMULATED[name]
    sim = simulate(spec["n_sites"], pool + TEST, device_seed=seed, topology=spec["topology"],
                   shape=spec["shape"])
    sim.data["split"] = ["train"] * pool + ["test"] * TEST
    csv = tmp / f"{name}_{seed}.csv"
    write_simulation(sim, csv)
    n, E = sim.truth["n_sites"], len(sim.truth["graph"]["edges"])
    q, c = [f"v_q{k}" for k in range(1, n + 1)], [f"v_c{k}" for k in range(1, E + 1)]
    data = {"csv": str(csv), "prior": [f"model_E{k}" for k in range(1, n + 1)],
            "targets": [f"measured_E{k}" for k in range(1, n + 1)], "features": q + c,
            "split_column": "split",
            "hamiltonian": {"onsite": [f"model_f{k}" for k in range(1, n + 1)],
                            "couplings": [f"model_g{k}" for k in range(1, E + 1)],
                            "edges": sim.truth["graph"]["edges"],
                            "qubit_features": q, "coupler_features": c}}
    return write_config(base, data, tmp / f"{name}_{seed}.toml")


def one_loop(config: str, arm: str, seed: int, stop: int, criterion: str) -> dict:
    """One loop in this process (one BLAS thread): its curve as a dict."""
    from threadpoolctl import threadpool_limits

    from workbench.experiment.config import load_dataset
    from workbench.experiment.runs.design import acquisition_loop
    from workbench.experiment.runs.prepare import load_config

    with threadpool_limits(1):
        cfg = load_config(config)
        ds = load_dataset(cfg)
        run = acquisition_loop(cfg, ds, list(ds.train_index), list(ds.test_index), arm=arm,
                               seed=seed, start=20, batch=10, stop=stop, criterion=criterion)
    return dict(arm=arm, seed=seed, n=run.n_measured, mae=run.test_mae, seconds=run.seconds)


def summarise(name: str, loops: list[dict]) -> dict:
    """Medians and quartiles over seeds per arm and size; the sizes where the design meets
    the random arm's final median."""
    sizes = loops[0]["n"]
    out: dict = {"dataset": name, "n": sizes}
    for arm in ("design", "random"):
        curves = np.array([r["mae"] for r in loops if r["arm"] == arm])
        out[arm] = {"median": np.median(curves, axis=0).tolist(),
                    "q25": np.quantile(curves, 0.25, axis=0).tolist(),
                    "q75": np.quantile(curves, 0.75, axis=0).tolist(),
                    "seeds": len(curves)}
    target = out["random"]["median"][-1]
    reached = [n for n, m in zip(sizes, out["design"]["median"]) if m <= target]
    out["design_reaches_random_final_at"] = reached[0] if reached else None
    ratios = {}
    for j, n in enumerate(sizes):
        pairs = [(d["mae"][j], r["mae"][j]) for d in loops if d["arm"] == "design"
                 for r in loops if r["arm"] == "random" and r["seed"] == d["seed"]]
        ratios[n] = statistics.median(a / b for a, b in pairs)
    out["median_ratio"] = ratios
    spread = np.array(out["random"]["q75"]) - np.array(out["random"]["q25"])
    out["worse_than_random_by_more_than_spread"] = [
        n for n, d, r, s in zip(sizes, out["design"]["median"], out["random"]["median"], spread)
        if d - r > s]
    return out


def figure(summary: dict, title: str):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    n = summary["n"]
    for arm, colour in (("design", "C0"), ("random", "C1")):
        s = summary[arm]
        ax.plot(n, s["median"], "o-", color=colour, ms=3,
                label=f"{arm} (median of {s['seeds']} seeds)")
        ax.fill_between(n, s["q25"], s["q75"], color=colour, alpha=0.2, lw=0)
    ax.set_xlabel("experiments measured")
    ax.set_ylabel("test MAE (MHz, average over targets)")
    ax.set_title(title, fontsize=10)
    ax.legend(title="band: seeds' interquartile range", fontsize=8, title_fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def track(summary: dict, fig, params: dict, tracking_uri: str | None) -> str:
    """One MLflow run per dataset: params, the medians as metric series, the figure."""
    import mlflow
    from mlflow.entities import Metric

    from workbench.experiment.tracking.uris import resolve_tracking_uri

    uri = resolve_tracking_uri(tracking_uri, None, ROOT)
    client = mlflow.MlflowClient(uri)
    experiment = client.get_experiment_by_name("design loop")
    exp_id = (experiment.experiment_id if experiment is not None
              else client.create_experiment("design loop"))
    run = client.create_run(exp_id, run_name=f"design vs random: {summary['dataset']}")
    now = int(time.time() * 1000)
    metrics = [Metric(f"{arm}_test_mae_{stat}", float(v), now, int(n))
               for arm in ("design", "random") for stat in ("median", "q25", "q75")
               for n, v in zip(summary["n"], summary[arm][stat])]
    metrics += [Metric("design_over_random_median", float(v), now, int(n))
                for n, v in summary["median_ratio"].items()]
    client.log_batch(run.info.run_id, params=[
        mlflow.entities.Param(k, str(v)[:500]) for k, v in params.items()])
    for start in range(0, len(metrics), 1000):  # MLflow takes 1000 metrics per batch
        client.log_batch(run.info.run_id, metrics=metrics[start:start + 1000])
    client.log_figure(run.info.run_id, fig, f"acquisition_{summary['dataset']}.png")
    client.log_dict(run.info.run_id, summary, f"acquisition_{summary['dataset']}.json")
    client.set_terminated(run.info.run_id)
    return run.info.run_id


def dataset_arguments(parser: argparse.ArgumentParser) -> None:
    """The datasets and seeds options (this script's and design_bound.py's)."""
    parser.add_argument("--datasets", nargs="+", default=["chain", "grid", "google"],
                        choices=["chain", "grid", "google"])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    parser.add_argument("--google-seeds", type=int, nargs="+", default=list(range(10)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    dataset_arguments(parser)
    parser.add_argument("--stop", type=int, default=200)
    parser.add_argument("--pool", type=int, default=POOL,
                        help=f"candidate settings of a simulated device (default {POOL})")
    parser.add_argument("--criterion", choices=("i", "d"), default="i")
    parser.add_argument("--config", default=str(ROOT / "experiments" / "design_loop.toml"))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--tracking-uri", default=None)
    parser.add_argument("--no-track", action="store_true")
    parser.add_argument("--out", default=str(ROOT / "reports" / "design"))
    args = parser.parse_args()
    from concurrent.futures import ProcessPoolExecutor

    from workbench.experiment.figures import save_figure

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    base = Path(args.config)
    tomllib.loads(base.read_text())  # a malformed config fails here, not in a worker
    with tempfile.TemporaryDirectory() as tmp, \
            ProcessPoolExecutor(args.workers) as pool:
        for name in args.datasets:
            start = time.perf_counter()
            if name == "google":
                seeds, stop = args.google_seeds, 95
                configs = {s: str(base) for s in seeds}
            else:
                seeds, stop = args.seeds, args.stop
                configs = {s: str(simulated_config(name, s, base, Path(tmp), args.pool))
                           for s in seeds}
            jobs = {(arm, s): pool.submit(one_loop, configs[s], arm, s, stop, args.criterion)
                    for s in seeds for arm in ("design", "random")}
            loops = []
            for (arm, s), job in jobs.items():
                r = job.result()
                loops.append(r)
                print(f"{name} seed {s} {arm:6s} ({r['seconds']:.0f} s): "
                      + " ".join(f"{n}:{m:.3f}" for n, m in zip(r["n"], r["mae"])), flush=True)
            summary = summarise(name, loops)
            summary["seconds"] = time.perf_counter() - start
            title = (f"{name}: test MAE against experiments measured "
                     f"({args.criterion.upper()}-optimal design vs random)")
            fig = figure(summary, title)
            save_figure(fig, out / f"acquisition_{name}.png")
            (out / f"acquisition_{name}.json").write_text(json.dumps(summary, indent=1) + "\n")
            print(f"{name}: medians " + " ".join(
                f"{n}:{d:.3f}/{r:.3f}" for n, d, r in zip(
                    summary["n"], summary["design"]["median"], summary["random"]["median"]))
                  + " (design/random)", flush=True)
            print(f"{name}: the design's median reaches the random arm's final median "
                  f"({summary['random']['median'][-1]:.3f} at {summary['n'][-1]}) at "
                  f"{summary['design_reaches_random_final_at']}; median ratio design/random "
                  + " ".join(f"{n}:{v:.3f}" for n, v in summary["median_ratio"].items())
                  + "; sizes where the design is worse than random by more than the seeds' "
                  f"spread: {summary['worse_than_random_by_more_than_spread'] or 'none'}; "
                  f"{summary['seconds']:.0f} s", flush=True)
            if not args.no_track:
                run_id = track(summary, fig, dict(dataset=name, seeds=seeds, stop=stop,
                                                  criterion=args.criterion,
                                                  config=str(base)), args.tracking_uri)
                print(f"{name}: MLflow run {run_id}", flush=True)


if __name__ == "__main__":
    main()
