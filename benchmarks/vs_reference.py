"""The workbench against the paper's reference implementation on the same work (prints a
table; no assertions).

    python benchmarks/vs_reference.py [--repeats 5] [--reference-venv /tmp/reference-venv]
                                      [--only paper|default|curve] [--workbench-args ...]

Three jobs, each run as whole processes (start-up included), paired and alternating (workbench,
reference, workbench, ...; the side that goes first alternates too), with one BLAS/OpenMP
thread per process (``OMP_NUM_THREADS=OPENBLAS_NUM_THREADS=MKL_NUM_THREADS=1``; each side
may still use both cores through its own worker processes, as the reference does with
joblib):

* ``paper``: ``workbench evaluate experiments/paper_main_body.toml --no-track
  --no-intervals`` (the reference computes no intervals: the same work) against the
  reference's paper-settings script (``/work/shared/bench/reference/paper_settings.py``
  or ``$REFERENCE_SCRIPT``): per target a stacking basis, K = 1, the inbuilt model selection
  by 5-fold CV, on the 95 training rows, scored on the 41 test rows.
* ``default``: the default command a user runs, ``workbench evaluate
  experiments/paper_main_body.toml`` (tracked into an MLflow store made beforehand, its 90%
  intervals, learning curves, SHAP summaries, figures and the logged model), against the
  same reference run: issue 19 asks for at most 1.5x the reference's wall.
* ``curve``: the augmented learning curve of Y3 (the paper-settings candidate against the
  prior) at the training sizes of ``workbench reproduce`` (23 ... 76 rows, 5-fold CV on the
  95 training rows) on both sides: ``workbench.curves.augmented_learning_curve`` and the
  reference's ``LearningCurve._modified_learning_curve(..., return_incumbent_score=True)``.

Prints each run's wall time and CPU time (user + system of the process and its children,
less sensitive to other load on the machine) (and, for the paper job, each side's
per-target test MAE once), the medians, the reference/workbench ratio, and ``uptime``'s
load before and after. The reference side runs only when its virtualenv exists (build it
with ``bash /work/shared/bench/reference/setup.sh [VENV]``).
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REFERENCE_SCRIPT = Path(os.environ.get("REFERENCE_SCRIPT",
                                       "/work/shared/bench/reference/paper_settings.py"))
THREADS = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
#: The learning-curve sizes of ``workbench reproduce`` (the paper's sizes up to the largest
#: fold-training set of 5-fold CV on 95 rows, plus that one).
CURVE_SIZES = [23, 33, 43, 54, 64, 74, 76]
CURVE_FOLDS = 5

WORKBENCH_CURVE = f"""
import time
t0 = time.perf_counter()
from workbench.curves import augmented_learning_curve
from workbench.experiment.config import load_dataset
from workbench.experiment.runs.prepare import load_config
cfg = load_config("experiments/paper_main_body.toml")
ds = load_dataset(cfg)
X_train, _, y_train, _ = ds.split()
est = cfg.family.build(cfg, ds).target_estimators["eeig3"].estimator  # the paper's candidate
t1 = time.perf_counter()
curve = augmented_learning_curve(est, X_train, y_train["eeig3"].to_numpy(),
                                 train_sizes={CURVE_SIZES}, cv={CURVE_FOLDS}, random_state=0,
                                 n_jobs=-1)  # both cores, as the reference
t2 = time.perf_counter()
print("cv error:", " ".join(f"{{v:.3f}}" for v in curve.cv_error_mean))
print(f"curve compute {{t2 - t1:.1f}} s")
"""

REFERENCE_CURVE = f"""
import time, warnings
t0 = time.perf_counter()
warnings.simplefilter("ignore")
import numpy as np
from physlearn.datasets import load_benchmark, paper_params
from physlearn.supervised.model_selection.learning_curve import LearningCurve
X_train, X_test, y_train, y_test = load_benchmark(return_split=True)
line_search = dict(init_guess=1, opt_method="minimize", method="Nelder-Mead", tol=1e-7,
                   options={{"maxiter": 10000}}, niter=None, T=None, loss="lad",
                   regularization=0.1)
boosting = dict(n_regressors=1, boosting_loss="ls", line_search_options=line_search)
layers = dict(regressors=["mlpregressor", "lgbmregressor"], final_regressor="mlpregressor")
lc = LearningCurve(regressor_choice="stackingregressor", params=paper_params(2), target_index=2,
                   cv={CURVE_FOLDS}, stacking_options=dict(layers=layers),
                   base_boosting_options=boosting)
t1 = time.perf_counter()
sizes, train, cv, incumbent = lc._modified_learning_curve(
    X_train, y_train, train_sizes=np.array({CURVE_SIZES}), return_incumbent_score=True)
t2 = time.perf_counter()
print("cv error:", " ".join(f"{{v:.3f}}" for v in cv.mean(axis=1)))
print(f"curve compute {{t2 - t1:.1f}} s")
"""


def _uptime() -> str:
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return "uptime unavailable"


def _cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _run(argv: list[str], env: dict[str, str]) -> tuple[float, float, str]:
    """Wall time, CPU time (user + system, the process and its waited-for children) and
    output of one run."""
    cpu, start = _cpu(), time.perf_counter()
    out = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=ROOT)
    wall = time.perf_counter() - start
    if out.returncode != 0:
        sys.exit(f"failed ({out.returncode}): {' '.join(argv)}\n{out.stderr[-3000:]}")
    return wall, _cpu() - cpu, out.stdout + out.stderr


def _maes(text: str) -> str:
    """The per-target test MAE printed by either side."""
    rows = re.findall(r"^eeig\d\s+[\d.]+\s+([\d.]+)", text, flags=re.M)
    if rows:
        return " ".join(rows)
    m = re.search(r"test MAE per target: ([\d. ]+)", text)
    return m.group(1).strip() if m else "?"


def _line(text: str, prefix: str) -> str:
    return next((ln for ln in text.splitlines() if ln.startswith(prefix)), "")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--reference-venv", default=os.environ.get("REFERENCE_VENV",
                                                                     "/tmp/reference-venv"))
    parser.add_argument("--only", choices=("paper", "default", "curve"), default=None)
    parser.add_argument("--json", type=Path, help="also write the medians as JSON (make bench)")
    parser.add_argument("--workbench-args", nargs=argparse.REMAINDER, default=[],
                        help="extra arguments of the workbench evaluate (e.g. --jobs 1)")
    args = parser.parse_args()

    env = {**os.environ, **THREADS, "MLFLOW_DISABLE_TELEMETRY": "true"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    env.setdefault("MPLCONFIGDIR", "/tmp/workbench-bench-mpl")
    ref_python = Path(args.reference_venv) / "bin" / "python"
    have_ref = ref_python.is_file() and REFERENCE_SCRIPT.is_file()
    if not have_ref:
        print(f"reference environment not found ({ref_python}); build it with "
              f"`bash /work/shared/bench/reference/setup.sh {args.reference_venv}`; "
              "timing the workbench only")
    wb = [sys.executable, "-m", "workbench.experiment.cli"]
    store_dir = tempfile.mkdtemp(prefix="workbench-vs-reference-")
    store = f"sqlite:///{store_dir}/mlflow.db"
    _run([sys.executable, "-c", f"from mlflow import MlflowClient; "
          f"MlflowClient({store!r}).search_experiments()"], env)  # the store exists
    jobs = {
        "paper": ([*wb, "evaluate", "experiments/paper_main_body.toml", "--no-track",
                   "--no-intervals", *args.workbench_args],
                  [str(ref_python), str(REFERENCE_SCRIPT)]),
        "default": ([*wb, "evaluate", "experiments/paper_main_body.toml", "--tracking-uri",
                     store, *args.workbench_args],
                    [str(ref_python), str(REFERENCE_SCRIPT)]),
        "curve": ([sys.executable, "-c", WORKBENCH_CURVE],
                  [str(ref_python), "-c", REFERENCE_CURVE]),
    }
    before = _uptime()
    print(f"load before: {before}")
    print(f"{os.cpu_count()} CPUs; {args.repeats} paired runs per job; one BLAS/OpenMP thread "
          "per process", flush=True)
    summary, medians = [], []
    for name, (wb_argv, ref_argv) in jobs.items():
        if args.only and name != args.only:
            continue
        walls: dict[str, list[float]] = {"workbench": [], "reference": []}
        cpus: dict[str, list[float]] = {"workbench": [], "reference": []}
        shown = set()
        for rep in range(args.repeats):
            order = ["workbench", "reference"] if rep % 2 == 0 else ["reference", "workbench"]
            for side in order:
                if side == "reference" and not have_ref:
                    continue
                wall, cpu, text = _run(wb_argv if side == "workbench" else ref_argv, env)
                walls[side].append(wall)
                cpus[side].append(cpu)
                extra = ""
                if side not in shown:
                    shown.add(side)
                    extra = (f"  test MAE {_maes(text)}" if name != "curve" else
                             f"  {_line(text, 'cv error:')}; {_line(text, 'curve compute')}")
                print(f"{name} run {rep}: {side:<9} {wall:6.1f} s wall {cpu:6.1f} s CPU{extra}",
                      flush=True)
        w, wc = statistics.median(walls["workbench"]), statistics.median(cpus["workbench"])
        line = f"{name}: median wall workbench {w:.1f} s"
        row = {"job": name, "runs": args.repeats, "workbench_wall": w, "workbench_cpu": wc}
        if walls["reference"]:
            r, rc = statistics.median(walls["reference"]), statistics.median(cpus["reference"])
            line += (f", reference {r:.1f} s; reference / workbench = {r / w:.2f} "
                     f"(CPU: {wc:.1f} s vs {rc:.1f} s, {rc / wc:.2f})")
            row.update(reference_wall=r, reference_cpu=rc)
        summary.append(line)
        medians.append(row)
        print(line, flush=True)
    after = _uptime()
    print(f"load after:  {after}")
    print("\n".join(["summary:", *summary]))
    if args.json:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from scaling import write_json

        write_json(args.json, {"jobs": medians}, before, after)


if __name__ == "__main__":
    main()
