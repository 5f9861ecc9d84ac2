"""A newcomer's first two commands against the reference script, timed in one run.

    python benchmarks/first_run.py [--json benchmarks/results/first_run.json]
        [--suite-json benchmarks/results/suite_cost.json] [--fresh] [--repeats 3]
        [--reference-venv /tmp/reference-venv]

Times, one after another on the same machine:

* the reference implementation's paper-settings script (``$REFERENCE_SCRIPT``, default
  ``/work/shared/bench/reference/paper_settings.py``, in the virtualenv that
  ``bash /work/shared/bench/reference/setup.sh [VENV]`` builds), the median of ``--repeats``
  runs with one BLAS/OpenMP thread (as ``benchmarks/vs_reference.py``): the unit of the
  ratios;
* with ``--fresh``, ``make install`` into a new virtualenv with empty caches (uv's and the
  benchmark data's: ``XDG_CACHE_HOME`` is a new folder), as on a fresh clone;
* ``make run``'s reproduction, ``workbench reproduce`` into a temporary folder and MLflow
  store (the environment ``make run`` gives it; with ``--fresh`` its data are downloaded
  first, as on a fresh clone);
* ``make test``'s lint (``ruff check`` and ``mypy``, as ``make lint``) and its default test
  suite (``benchmarks/suite_cost.py``: each file's CPU seconds too, written to
  ``--suite-json``).

Each step's wall and CPU seconds (user + system of the process and every child it waited
for) and its wall as a multiple of the reference script's go to ``--json``;
``benchmarks/tables.py`` renders both files into docs/benchmarks.md (``make bench``).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from suite_cost import ROOT, THREADS, children_cpu, suite_cost, table, uptime  # noqa: E402

REFERENCE_SCRIPT = Path(os.environ.get("REFERENCE_SCRIPT",
                                       "/work/shared/bench/reference/paper_settings.py"))
#: The issue's targets, as multiples of the reference script's wall (a quiet 2-core machine).
TARGETS = {"make_run": 10.0, "reproduce": 6.0, "make_test": 12.0, "suite": 8.0}


def _timed(argv: list[str], env: dict[str, str], cwd: Path) -> dict:
    """Run ``argv``; its wall and CPU seconds (exit on failure)."""
    cpu, start = children_cpu(), time.perf_counter()
    out = subprocess.run(argv, cwd=cwd, env=env, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - start, children_cpu() - cpu
    if out.returncode != 0:
        sys.exit(f"failed ({out.returncode}): {' '.join(argv)}\n{out.stderr[-3000:]}")
    return {"wall_s": wall, "cpu_s": cpu}


def _reference(venv: Path, repeats: int, env: dict[str, str]) -> dict | None:
    python = venv / "bin" / "python"
    if not (python.is_file() and REFERENCE_SCRIPT.is_file()):
        print(f"reference environment not found ({python}); build it with `bash "
              f"/work/shared/bench/reference/setup.sh {venv}`: no ratios", flush=True)
        return None
    runs = [_timed([str(python), str(REFERENCE_SCRIPT)], {**env, **THREADS}, ROOT)
            for _ in range(repeats)]
    return {"wall_s": statistics.median(r["wall_s"] for r in runs),
            "cpu_s": statistics.median(r["cpu_s"] for r in runs), "runs": repeats,
            "walls": [r["wall_s"] for r in runs]}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", type=Path, help="write the steps' figures as JSON")
    parser.add_argument("--suite-json", type=Path, help="write the suite's per-file costs")
    parser.add_argument("--fresh", action="store_true",
                        help="also time make install into a new venv with empty caches, and "
                        "the reproduction's data download")
    parser.add_argument("--repeats", type=int, default=3, help="runs of the reference script")
    parser.add_argument("--reference-venv", type=Path, default=Path(
        os.environ.get("REFERENCE_VENV", "/tmp/reference-venv")))
    args = parser.parse_args()

    from scaling import write_json

    env = {**os.environ, "MLFLOW_DISABLE_TELEMETRY": "true"}
    env.setdefault("MPLCONFIGDIR", "/tmp/workbench-bench-mpl")
    before = uptime()
    print(f"load before: {before}", flush=True)
    steps: dict[str, dict | None] = {"reference": _reference(args.reference_venv,
                                                             args.repeats, env)}
    with tempfile.TemporaryDirectory(prefix="workbench-first-run-") as tmp:
        python = sys.executable
        if args.fresh:
            env["XDG_CACHE_HOME"] = f"{tmp}/cache"  # uv's and the data's caches: empty
            steps["install"] = _timed(["make", "install", f"VENV={tmp}/venv"], env, ROOT)
            python = f"{tmp}/venv/bin/python"
        reports = Path(tmp) / "reports"
        steps["reproduce"] = _timed(
            [python, "-m", "workbench.experiment.cli", "reproduce", "--out", str(reports),
             "--tracking-uri", f"sqlite:///{tmp}/mlflow.db"],
            {**env, "PYTHONPATH": str(ROOT)}, Path(tmp))
        print(f"reproduce: {steps['reproduce']['wall_s']:.1f} s wall", flush=True)
        bin_dir = Path(python).parent
        lint = [_timed([str(bin_dir / "ruff"), "check"], env, ROOT),
                _timed([str(bin_dir / "mypy")], env, ROOT)]
        steps["lint"] = {k: sum(step[k] for step in lint) for k in ("wall_s", "cpu_s")}
        cost = suite_cost(2, python=python)
        print(table(cost, top=20), flush=True)
    steps["suite"] = {"wall_s": cost["wall_s"], "cpu_s": cost["cpu_s"],
                      "summary": cost["summary"], "returncode": cost["returncode"]}
    ref = steps["reference"]
    ratios = {}
    if ref is not None:
        install = steps.get("install") or {"wall_s": 0.0}
        ratios = {"reproduce": steps["reproduce"]["wall_s"] / ref["wall_s"],
                  "suite": steps["suite"]["wall_s"] / ref["wall_s"],
                  "make_test": (steps["lint"]["wall_s"] + steps["suite"]["wall_s"])
                  / ref["wall_s"]}
        if "install" in steps:
            ratios["make_run"] = ((install["wall_s"] + steps["reproduce"]["wall_s"])
                                  / ref["wall_s"])
    after = uptime()
    print(f"load after:  {after}")
    for name, ratio in ratios.items():
        print(f"{name}: {ratio:.1f}x the reference script (target <= {TARGETS[name]:.0f}x)")
    if args.json:
        write_json(args.json, {"steps": steps, "ratios": ratios, "targets": TARGETS,
                               "fresh": args.fresh}, before, after)
    if args.suite_json:
        write_json(args.suite_json, cost, before, after)
    return 0


if __name__ == "__main__":
    sys.exit(main())
