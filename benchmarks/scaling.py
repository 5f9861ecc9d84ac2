"""Time and peak memory of ``evaluate`` against rows and sites, for both model families
(prints a table; no assertions).

    python benchmarks/scaling.py                     # rows 300 ... 10,000, sites 5 ... 50
    python benchmarks/scaling.py --max-rows 30000    # rows up to 30,000 (a few minutes more)
    python benchmarks/scaling.py --only ridge lightgbm --rows 3000 30000

Cases (each point a fresh process fitting a simulated chain device, ``workbench simulate``'s
default mismatches, 30 % test rows; the data are simulated before the clock starts):

* ``ridge``, ``lightgbm`` (100 trees): the eigenvalue-space family, one BaseBoostCV per
  target (5-fold CV, prior + voltages as basis inputs), 5 sites, against rows; and, for
  ``ridge``, against sites at 3,000 rows;
* ``kernel_ridge``: the config of ``experiments/simulated_device.toml``: a basis quadratic in
  rows, which switches to a Nystroem approximation above ``bases.KERNEL_EXACT_ROWS`` rows;
* ``hamiltonian``: the parameter-space model with fixed covariates (the default library,
  ``selection = "none"``, no stage on top), against rows at 5 sites and against sites
  (5 ... 50) at 300 rows.

Prediction intervals are off (``[intervals] enabled = false``): their CV+ refits the model
once per fold (5 more fits), the same growth times six. Each point reports the wall time of
``evaluate`` (fit, CV, scoring; not the imports), the
time per 1,000 rows, and the peak resident memory of the process and of its worker processes
(``ru_maxrss``). Every command uses both cores (``n_jobs`` unset). Also prints ``uptime``.
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
ROWS = [300, 1000, 3000, 10_000, 30_000]
SITES = [5, 10, 20, 50]
ROWS_FOR_SITES = {"ridge": 3000, "hamiltonian": 300}
CASES = ("ridge", "lightgbm", "kernel_ridge", "hamiltonian")


def _config(case: str, csv: Path, n_sites: int) -> str:
    q = [f"v_q{i}" for i in range(1, n_sites + 1)]
    c = [f"v_c{i}" for i in range(1, n_sites)]
    head = f"""name = "scaling_{case}"
random_state = 0
[data]
csv = "{csv}"
prior = {[f"model_E{i}" for i in range(1, n_sites + 1)]}
targets = {[f"measured_E{i}" for i in range(1, n_sites + 1)]}
features = {q + c}
test_fraction = 0.3
split_seed = 0
[data.hamiltonian]
onsite = {[f"model_f{i}" for i in range(1, n_sites + 1)]}
couplings = {[f"model_g{i}" for i in range(1, n_sites)]}
qubit_features = {q}
coupler_features = {c}
sign = -1
[selection]
cv = 5
[intervals]
enabled = false
"""
    model = {
        "ridge": '[model]\nbasis = "ridge"\nbasis_params = { alpha = 1.0 }\n',
        "lightgbm": '[model]\nbasis = "lightgbm"\nbasis_params = { n_estimators = 100 }\n',
        "kernel_ridge": ('[model]\nbasis = "kernel_ridge"\n'
                         'basis_params = { alpha = 0.1, gamma = 0.05 }\nn_stages = 2\n'
                         'loss = "huber"\n'),
        "hamiltonian": ('[model]\nfamily = "hamiltonian"\nbasis = "ridge"\n'
                        '[model.hamiltonian]\nselection = "none"\ncandidates = "none"\n'
                        'boost_stage = false\n'),
    }[case]
    if case != "hamiltonian":
        model += ('basis_inputs = "prior+features"\ninput_transform = "standard"\n'
                  'line_search_loss = "absolute_error"\n')
    return head + model


def _child(case: str, n_rows: int, n_sites: int) -> None:
    """Run one point in this process; print a JSON line."""
    import logging

    from workbench.experiment.runs.evaluate import evaluate
    from workbench.experiment.runs.prepare import load_config
    from workbench.simulate import simulate, write_simulation

    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "device.csv"
        write_simulation(simulate(n_sites, n_rows, device_seed=0), csv)
        cfg_path = Path(tmp) / "scaling.toml"
        cfg_path.write_text(_config(case, csv, n_sites))
        cfg = load_config(cfg_path)
        caught: list[str] = []
        handler = logging.Handler()
        handler.emit = lambda record: caught.append(record.getMessage())
        logging.getLogger("workbench").addHandler(handler)
        start = time.perf_counter()
        result = evaluate(cfg)
        wall = time.perf_counter() - start
    kib = max(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
              resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
    notes = sorted({m[:100] for m in caught if "warning" in m})
    if case == "kernel_ridge":
        from workbench.bases import KERNEL_EXACT_ROWS

        rows = round(n_rows * 0.7 * 0.8)  # a CV fold's training rows
        notes.append("Nystroem features" if rows > KERNEL_EXACT_ROWS else "exact kernel")
    print(json.dumps({"wall": wall, "peak_mib": kib / 1024,
                      "mae": result.model.avg("test_mae"),
                      "prior_mae": result.prior.avg("test_mae"), "notes": notes}))


def _point(case: str, n_rows: int, n_sites: int) -> dict:
    env = {**os.environ, "MLFLOW_DISABLE_TELEMETRY": "true", "OMP_NUM_THREADS": "1",
           "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    out = subprocess.run([sys.executable, __file__, "--child", case, str(n_rows), str(n_sites)],
                         capture_output=True, text=True, env=env, cwd=ROOT)
    if out.returncode != 0:
        return {"error": out.stderr.strip().splitlines()[-1][:150]}
    return json.loads(out.stdout.strip().splitlines()[-1])


def _row(case: str, n_rows: int, n_sites: int) -> dict:
    p = _point(case, n_rows, n_sites)
    p.update(case=case, sites=n_sites, rows=n_rows)
    if "error" in p:
        print(f"{case:<13}{n_sites:>6}{n_rows:>8,}  failed: {p['error']}", flush=True)
        return p
    per = p["wall"] / n_rows * 1000
    p["per_1k_rows"] = per
    print(f"{case:<13}{n_sites:>6}{n_rows:>8,}{p['wall']:>9.2f}{per:>11.3f}{p['peak_mib']:>10.0f}"
          f"{p['mae']:>9.3f}{p['prior_mae']:>9.3f}  {'; '.join(p['notes'])}", flush=True)
    return p


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--only", nargs="+", choices=CASES, default=list(CASES))
    parser.add_argument("--rows", nargs="+", type=int, default=None)
    parser.add_argument("--max-rows", type=int, default=10_000,
                        help="largest row count of the default list (30000 for the full run)")
    parser.add_argument("--sites", nargs="+", type=int, default=SITES)
    parser.add_argument("--json", type=Path,
                        help="also write the points as JSON (benchmarks/results/scaling.json "
                             "is what docs/benchmarks.md's table is made from: make bench)")
    parser.add_argument("--child", nargs=3, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        case, n_rows, n_sites = args.child
        _child(case, int(n_rows), int(n_sites))
        return
    rows = args.rows or [r for r in ROWS if r <= args.max_rows]
    before = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(f"load before: {before}\ncases {args.only}; rows {rows}; sites {args.sites}")
    print(f"{'case':<13}{'sites':>6}{'rows':>8}{'wall s':>9}{'s/1k rows':>11}{'peak MiB':>10}"
          f"{'MAE':>9}{'prior':>9}  notes")
    points = []
    for case in args.only:
        for n_rows in rows:
            points.append(_row(case, n_rows, 5))
        if case in ROWS_FOR_SITES:
            for n_sites in args.sites:
                if n_sites != 5 or ROWS_FOR_SITES[case] not in rows:
                    points.append(_row(case, ROWS_FOR_SITES[case], n_sites))
    after = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    print(f"load after:  {after}")
    if args.json:
        write_json(args.json, {"points": points}, before, after)


def write_json(path: Path, payload: dict, load_before: str, load_after: str) -> None:
    """A benchmark's figures with the machine, date, commit and load they were measured on."""
    import platform
    from datetime import date

    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                            text=True, cwd=ROOT).stdout.strip()
    meta = {"date": date.today().isoformat(), "commit": commit, "cores": os.cpu_count(),
            "machine": platform.machine(), "python": platform.python_version(),
            "load_before": load_before, "load_after": load_after}
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"measured": meta, **payload}, indent=1) + "\n")


if __name__ == "__main__":
    main()
