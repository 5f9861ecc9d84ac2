"""Start-up time of the command line and of ``import workbench``, and what each loads.

    python benchmarks/cli_startup.py [--repeats 10]

Prints the median wall time (whole processes, measured in this run) of ``workbench --help``,
``workbench simulate --help``, ``python -c "import workbench"`` and, for scale, of importing
the estimators (scikit-learn, LightGBM) and the experiment layer's heavy libraries; of
``workbench simulate`` (300 experiments) and ``workbench evaluate CONFIG --no-track
--no-intervals`` on them (a ridge stage: start-up is the time to its first progress line,
"fitting ...", with the config and data loaded and the workers forked; then the whole
command); and whether ``--help`` / ``simulate`` load MLflow, Optuna or SHAP (they must not).
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SCRIPT = Path(sys.executable).parent / "workbench"
CASES = {
    "workbench --help": [str(SCRIPT), "--help"],
    "workbench simulate --help": [str(SCRIPT), "simulate", "--help"],
    "import workbench": [sys.executable, "-c", "import workbench"],
    "import workbench.BaseBoostCV (sklearn, lightgbm)":
        [sys.executable, "-c", "from workbench import BaseBoostCV"],
    "import mlflow, optuna, shap": [sys.executable, "-c", "import mlflow, optuna, shap"],
}
HEAVY = ("mlflow", "optuna", "shap", "sklearn", "lightgbm")
CONFIG = """name = "startup"
[data]
csv = "s.csv"
prior = ["model_E1", "model_E2", "model_E3", "model_E4", "model_E5"]
targets = ["measured_E1", "measured_E2", "measured_E3", "measured_E4", "measured_E5"]
features = ["v_q1", "v_q2", "v_q3", "v_q4", "v_q5", "v_c1", "v_c2", "v_c3", "v_c4"]
test_fraction = 0.3
[model]
basis = "ridge"
n_stages = 1
"""


def _timed(argv: list[str], marker: str | None = None) -> tuple[float, float]:
    """Wall time of a whole process, and until ``marker`` first appears on its stderr."""
    start = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    seen = None
    for line in proc.stderr:
        if seen is None and marker is not None and marker in line:
            seen = time.perf_counter() - start
    if proc.wait() != 0:
        raise SystemExit(f"{' '.join(argv)} failed")
    whole = time.perf_counter() - start
    return whole, whole if seen is None else seen


def _report(name: str, walls: list[float]) -> None:
    print(f"{name:<48} median {statistics.median(walls):6.3f} s  "
          f"(min {min(walls):.3f}, max {max(walls):.3f}; {len(walls)} runs)", flush=True)


def _loaded(argv: list[str]) -> list[str]:
    """The heavy top-level packages a command line imports."""
    code = ("import sys, runpy; sys.argv = {argv!r}; "
            "from workbench.experiment.cli import main\n"
            "try:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
            "print('LOADED:' + ','.join(sorted({{m.split('.')[0] for m in sys.modules}} "
            "& {heavy!r})))")
    out = subprocess.run([sys.executable, "-c", code.format(argv=argv, heavy=set(HEAVY))],
                         capture_output=True, text=True, check=True)
    line = [x for x in out.stdout.splitlines() if x.startswith("LOADED:")][-1]
    return [m for m in line.removeprefix("LOADED:").split(",") if m]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=10)
    args = parser.parse_args()
    for name, argv in CASES.items():
        walls = []
        for _ in range(args.repeats):
            start = time.perf_counter()
            subprocess.run(argv, capture_output=True, check=True)
            walls.append(time.perf_counter() - start)
        _report(name, walls)
    with tempfile.TemporaryDirectory() as tmp:
        simulate = [str(SCRIPT), "simulate", "--experiments", "300", "--out", f"{tmp}/s.csv"]
        _report("workbench simulate (300 experiments)",
                [_timed(simulate)[0] for _ in range(args.repeats)])
        (Path(tmp) / "c.toml").write_text(CONFIG)
        evaluate = [str(SCRIPT), "evaluate", f"{tmp}/c.toml", "--no-track", "--no-intervals"]
        runs = [_timed(evaluate, "fitting") for _ in range(args.repeats)]
        _report("workbench evaluate --no-track: to 'fitting'", [seen for _, seen in runs])
        _report("workbench evaluate --no-track: whole", [whole for whole, _ in runs])
        sim = ["workbench", "simulate", "--experiments", "20", "--out", f"{tmp}/s.csv"]
        for label, argv in (("--help", ["workbench", "--help"]), ("simulate", sim)):
            print(f"heavy packages loaded by `workbench {label}`: "
                  f"{', '.join(_loaded(argv)) or 'none'}")


if __name__ == "__main__":
    main()
