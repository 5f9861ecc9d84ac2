"""Start-up time of the command line and of ``import workbench``, and what each loads.

    python benchmarks/cli_startup.py [--repeats 10]

Prints the median wall time (whole processes, measured in this run) of ``workbench --help``,
``workbench simulate --help``, ``python -c "import workbench"`` and, for scale, of importing
the estimators (scikit-learn, LightGBM) and the experiment layer's heavy libraries; and
whether ``--help`` / ``simulate`` load MLflow, Optuna or SHAP (they must not).
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
        print(f"{name:<48} median {statistics.median(walls):6.3f} s  "
              f"(min {min(walls):.3f}, max {max(walls):.3f}; {args.repeats} runs)", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        sim = ["workbench", "simulate", "--experiments", "20", "--out", f"{tmp}/s.csv"]
        for label, argv in (("--help", ["workbench", "--help"]), ("simulate", sim)):
            print(f"heavy packages loaded by `workbench {label}`: "
                  f"{', '.join(_loaded(argv)) or 'none'}")


if __name__ == "__main__":
    main()
