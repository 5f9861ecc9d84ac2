"""The default test suite by cost: each test file's CPU seconds, sorted (prints a table).

    python benchmarks/suite_cost.py [--json benchmarks/results/suite_cost.json]
                                    [--workers 2] [-- PYTEST_ARGS ...]

Runs the default suite as ``make test`` does (``pytest -n 2 --dist loadfile
--no-loadscope-reorder``, one BLAS/OpenMP thread per process; the lint and type checks are
not part of it) with the plugin ``benchmarks/cpu_per_file.py``, which adds up, per test file,
the CPU seconds (user + system) of the process running its tests and of the children it
waited for, and the wall seconds of its tests. Then lists the files by CPU seconds, with
their share of the suite, and the whole suite's wall and CPU seconds (pytest and every
process it waited for). Arguments after ``--`` replace the test selection (e.g.
``-- tests/test_config.py``). :func:`suite_cost` is what ``benchmarks/first_run.py`` calls.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent
THREADS = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


def uptime() -> str:
    """``uptime``'s line (the load the figures were measured at)."""
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return "uptime unavailable"


def children_cpu() -> float:
    """CPU seconds (user + system) of this process's waited-for children so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def suite_cost(workers: int = 2, pytest_args: list[str] | None = None,
               python: str = sys.executable) -> dict:
    """Run the suite (see the module doc); its files' and its whole cost.

    Returns ``{"files": [{"file", "cpu_s", "wall_s", "tests", "failed"}, ...] (most CPU
    first), "wall_s", "cpu_s", "returncode", "workers", "summary"}``.
    """
    with tempfile.TemporaryDirectory(prefix="suite-cost-") as folder:
        env = {**os.environ, **THREADS, "MLFLOW_DISABLE_TELEMETRY": "true",
               "SUITE_COST_DIR": folder,
               "PYTHONPATH": os.pathsep.join(filter(None, [str(HERE), str(ROOT),
                                                           os.environ.get("PYTHONPATH")]))}
        argv = [python, "-m", "pytest", "-p", "cpu_per_file", "-q", "-p", "no:cacheprovider"]
        if workers > 1:
            argv += ["-n", str(workers), "--dist", "loadfile", "--no-loadscope-reorder"]
        argv += list(pytest_args or [])
        cpu, start = children_cpu(), time.perf_counter()
        out = subprocess.run(argv, cwd=ROOT, env=env, capture_output=True, text=True)
        wall, cpu = time.perf_counter() - start, children_cpu() - cpu
        files: dict[str, dict] = {}
        for part in Path(folder).glob("*.json"):
            for name, entry in json.loads(part.read_text()).items():
                into = files.setdefault(name, {"cpu_s": 0.0, "wall_s": 0.0, "tests": 0,
                                               "failed": 0})
                for key, value in entry.items():
                    into[key] += value
    lines = [ln for ln in out.stdout.splitlines() if ln.strip()]
    rows = sorted(({"file": name, **entry} for name, entry in files.items()),
                  key=lambda r: -r["cpu_s"])
    return {"files": rows, "wall_s": wall, "cpu_s": cpu, "returncode": out.returncode,
            "workers": workers, "summary": lines[-1] if lines else out.stderr[-500:]}


def table(cost: dict, top: int | None = None) -> str:
    """The files by CPU seconds as a Markdown table (the ``top`` costliest, then the rest
    summed), and the whole suite's line."""
    total = sum(r["cpu_s"] for r in cost["files"]) or 1.0
    lines = ["| test file | CPU s | share | wall s of its tests | tests |", "|---" * 5 + "|"]
    shown = cost["files"] if top is None else cost["files"][:top]
    for r in shown:
        lines.append(f"| {r['file']} | {r['cpu_s']:.1f} | {100 * r['cpu_s'] / total:.1f}% | "
                     f"{r['wall_s']:.1f} | {r['tests']} |")
    rest = cost["files"][len(shown):]
    if rest:
        cpu = sum(r["cpu_s"] for r in rest)
        lines.append(f"| {len(rest)} other files | {cpu:.1f} | {100 * cpu / total:.1f}% | "
                     f"{sum(r['wall_s'] for r in rest):.1f} | {sum(r['tests'] for r in rest)} |")
    lines.append("")
    lines.append(f"The suite on {cost['workers']} workers: {cost['wall_s']:.1f} s wall, "
                 f"{cost['cpu_s']:.1f} s CPU (pytest and every process it waited for; the files "
                 f"above sum to {total:.1f} s); {cost['summary']}")
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--workers", type=int, default=2, help="xdist workers (1: none)")
    parser.add_argument("--json", type=Path, help="also write the costs as JSON")
    parser.add_argument("pytest_args", nargs="*", help="after --: pytest's test selection")
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    from scaling import write_json

    before = uptime()
    cost = suite_cost(args.workers, args.pytest_args)
    print(table(cost))
    if args.json:
        write_json(args.json, cost, before, uptime())
    return 0 if cost["returncode"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
