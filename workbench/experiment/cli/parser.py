"""Command line of ``workbench``.

One function per command adds its subparser, whose ``func`` is the command's handler
(:mod:`.commands`, :mod:`.tools`, :mod:`.ui`).
"""

from __future__ import annotations

import argparse
from typing import NoReturn

from . import argtypes, commands, tools, ui

__all__ = ["build_parser"]

#: What ``add_subparsers`` returns.
Subparsers = argparse._SubParsersAction


class _Parser(argparse.ArgumentParser):
    """Parser whose errors are one line, ``workbench: error: ...`` (exit code 2).

    The usage block is left out (``--help`` shows it); the command's subparsers are of this
    class too.
    """

    #: The subcommands (what ``add_subparsers`` returned): the error for a missing command
    #: lists their names, read from the parser itself so the list cannot drift.
    commands: Subparsers | None = None

    def error(self, message: str) -> NoReturn:
        """Exit with one line naming the problem (and the commands, when none was given)."""
        if "required: command" in message and self.commands is not None:
            message += f" ({', '.join(self.commands.choices)}; see workbench --help)"
        self.exit(2, f"workbench: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    """Build the parser of the ``workbench`` command.

    Returns
    -------
    argparse.ArgumentParser
        Its subcommands set ``func``, the handler that takes the parsed arguments.
    """
    parser = _Parser(prog="workbench", description="Base boosting workbench.")
    sub = parser.commands = parser.add_subparsers(dest="command", required=True)
    for add in (_add_init, _add_evaluate, _add_sweep, _add_predict, _add_compare,
                _add_reproduce, _add_ui, _add_design, _add_simulate):
        add(sub)
    return parser


def _add_init(sub: Subparsers) -> None:
    """``workbench init``: a first config for a CSV of one's own."""
    ini = sub.add_parser("init", help="write a first config for a CSV of your own (then: "
                         "workbench evaluate CONFIG)")
    ini.add_argument("data", metavar="DATA.csv",
                     help="the CSV: one row per experiment, a header naming the columns")
    ini.add_argument("--prior", nargs="+", default=None, metavar="COL",
                     help="the physics model's prediction of each target, in the targets' order")
    ini.add_argument("--model", default=None, metavar="FILE.py",
                     help="instead of --prior: the physics model itself, a Python file "
                     "defining PARAMETERS and predict(params, data) (family parametric)")
    ini.add_argument("--target", nargs="+", required=True, metavar="COL",
                     help="the measured values to predict")
    ini.add_argument("--features", nargs="*", default=None, metavar="COL",
                     help="the basis' inputs besides the prior (default: every other numeric "
                     "column but the split column; --features alone: none)")
    ini.add_argument("--group-column", metavar="COL", default=None,
                     help="a column naming each row's group (e.g. its device): CV folds keep "
                     "each group whole")
    ini.add_argument("--order-column", metavar="COL", default="auto",
                     help="a column of dates, times or run numbers: CV folds chain forward by "
                     "it and the latest rows are the test rows (default: found, e.g. a "
                     "column of dates; 'none': a random split and plain folds)")
    split = ini.add_mutually_exclusive_group()
    split.add_argument("--split-column", metavar="COL", default=None,
                       help="a column saying 'train' or 'test' for each row")
    split.add_argument("--test-fraction", type=argtypes.fraction, default=None, metavar="F",
                       help="the share of rows held out for testing: the latest with an "
                       "order column, else drawn at random (default: 0.3 when there is no "
                       "--split-column)")
    ini.add_argument("--split-seed", type=argtypes.seed, default=None, metavar="N",
                     help="the seed of the random split (default: 0; given, the split is "
                     "random with an order column too)")
    ini.add_argument("--name", default=None,
                     help="the config's name (its MLflow experiment; default: the CSV's name "
                     "without .csv)")
    ini.add_argument("--out", default=None, metavar="PATH",
                     help="the config file to write (default: NAME.toml here)")
    ini.add_argument("--force", action="store_true", help="overwrite an existing --out")
    ini.set_defaults(func=tools.init)


def _set_arg(parser: argparse.ArgumentParser) -> None:
    """Add ``--set SECTION.KEY=VALUE`` (repeatable): a config value overridden."""
    parser.add_argument("--set", dest="overrides", type=argtypes.override, action="append",
                        default=[], metavar="SECTION.KEY=VALUE",
                        help="override one config value, checked like the file's (repeatable; "
                        "the value is TOML, a bare word a string), e.g. --set model.n_stages=2 "
                        "--set selection.cv=3; logged as run params set.<KEY> and in the "
                        "logged config")


def _add_evaluate(sub: Subparsers) -> None:
    """``workbench evaluate``: fit and score a config's model."""
    ev = sub.add_parser("evaluate", help="fit a config's model on the training rows and score "
                        "prior and model on the test rows")
    ev.add_argument("config",
                    help="experiment config (TOML), e.g. experiments/paper_main_body.toml")
    ev.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    ev.add_argument("--jobs", type=argtypes.count, default=None, metavar="N",
                    help="processes for independent work: targets, folds, curve points "
                    "(overrides the config's n_jobs; default: every core; the results do "
                    "not depend on it)")
    ev.add_argument("--nested", type=argtypes.nested_folds, default=None, metavar="K",
                    help="also a nested CV over all rows with K outer folds, every choice "
                    "remade in each (K more fits of the whole model; overrides [evaluation] "
                    "nested_folds; 0: none)")
    ev.add_argument("--random-states", type=argtypes.random_states, default=None,
                    metavar="SEEDS",
                    help="fit the config once per random_state, one after another: SEEDS is "
                    "A-B or A,B,C (e.g. 0-4 or 0,3,7); prints the mean and sd of the test MAE "
                    "per target, tracked as a parent run with a child run per seed, --out "
                    "and --json get the seeds' spread (overrides [evaluation] random_states; "
                    "not with --register)")
    ev.add_argument("--seeds", action=argtypes.Renamed, new="--random-states")
    ev.add_argument("--out", metavar="DIR", default=None,
                    help="write every figure (PNG), table (CSV) and data file (JSON) the run "
                    "logs to DIR, for every family: the MAE/MSE bars, the intervals', the "
                    "family's own (e.g. learning curves and SHAP, or coefficients and "
                    "selection) (with --random-states: the seeds' spread figure and table)")
    _model_args(ev)
    _set_arg(ev)
    ev.set_defaults(func=commands.evaluate)


def _add_sweep(sub: Subparsers) -> None:
    """``workbench sweep``: the nested-CV search."""
    sw = sub.add_parser("sweep", help="nested-CV hyperparameter search (Optuna), then one "
                        "evaluation of the chosen configuration on the test rows")
    sw.add_argument("config", help="experiment config (TOML) with [search], [cv], [study]")
    sw.add_argument("--trials", type=argtypes.count, default=None, help="trials per study")
    sw.add_argument("--workers", type=argtypes.count, default=None,
                    help="processes working on the shared storage")
    sw.add_argument("--storage", default=None,
                    help="Optuna storage: a journal file path or an RDB URL")
    sw.add_argument("--timeout", type=argtypes.seconds, default=None, metavar="SECONDS",
                    help="start no trial after SECONDS of search (Optuna's timeout; the "
                    "running trials finish); a sweep stopped so ends its MLflow run KILLED "
                    "and exits 124, and the same command resumes it (overrides [study] "
                    "timeout)")
    sw.add_argument("--out", metavar="DIR", default=None,
                    help="also write each study's Optuna figures (PNG) and parameter "
                    "importances (CSV) to DIR/studies/<study>/, and the outer folds' summary "
                    "figure to DIR")
    _repair_arg(sw)
    sw.add_argument("--json", metavar="PATH", help="also write the results as JSON")
    _model_args(sw)
    _set_arg(sw)
    sw.set_defaults(func=commands.sweep)


def _add_predict(sub: Subparsers) -> None:
    """``workbench predict``: a logged model on the rows of a CSV."""
    pr = sub.add_parser("predict", help="predict the rows of a CSV with a logged or "
                        "registered model (targets, and intervals when the model has them)")
    pr.add_argument("model", help="a run id, runs:/<run_id>/model, models:/NAME/VERSION, "
                    "models:/NAME@ALIAS (e.g. models:/device@champion) or models:/<model_id>")
    pr.add_argument("data", help="CSV with the model's input columns by name (other columns "
                    "are copied to the output)")
    pr.add_argument("--out", required=True, metavar="PATH", help="CSV file to write")
    pr.add_argument("--tracking-uri", default=None,
                    help="MLflow store holding the model (default: $MLFLOW_TRACKING_URI, "
                    "then sqlite:///mlruns/mlflow.db)")
    pr.set_defaults(func=tools.predict)


def _add_compare(sub: Subparsers) -> None:
    """``workbench compare``: two runs' test errors side by side."""
    co = sub.add_parser("compare", help="two tracked runs on the same test rows: per-target "
                        "test MAE and the paired bootstrap interval of the difference (logs "
                        "nothing)")
    co.add_argument("run_a", metavar="RUN_A", help="a run id or a run name")
    co.add_argument("run_b", metavar="RUN_B", help="a run id or a run name")
    co.add_argument("--tracking-uri", default=None,
                    help="MLflow store holding the runs (default: $MLFLOW_TRACKING_URI, "
                    "then sqlite:///mlruns/mlflow.db)")
    co.set_defaults(func=tools.compare)


def _add_reproduce(sub: Subparsers) -> None:
    """``workbench reproduce``: the paper's results and figures."""
    rep = sub.add_parser("reproduce", help="compute the paper's results and figures into a "
                         "report folder and the MLflow experiment paper-reproduction")
    rep.add_argument("--out", default="reports", help="output folder (default: reports)")
    rep.add_argument("--quick", action="store_true",
                     help="fewer curve points, SHAP rows, search trials and folds (for tests)")
    rep.add_argument("--all", action="store_true",
                     help="also the workbench's own nested-CV search (paper_search.toml) and "
                     "the IBM two-qubit gates benchmark (the longest phases; not in make run)")
    rep.add_argument("--random-state", type=argtypes.seed, default=0, metavar="N",
                     help="every config's random_state (default: 0)")
    rep.add_argument("--seed", action=argtypes.Renamed, new="--random-state")
    rep.add_argument("--experiments", metavar="DIR", default=None,
                     help="folder with the configs it runs (paper_main_body.toml, "
                     "paper_improved.toml, paper_search.toml, hamiltonian.toml; default: the "
                     "checkout's experiments/, else ./experiments)")
    rep.add_argument("--storage", default=None,
                     help="Optuna storage of the search of --all (a journal file path or an "
                     "RDB URL)")
    _repair_arg(rep)
    _tracking_args(rep)
    rep.set_defaults(func=commands.reproduce)


def _add_ui(sub: Subparsers) -> None:
    """``workbench ui``: the MLflow UI and optuna-dashboard."""
    cmd = sub.add_parser("ui", help="start the MLflow UI (and optuna-dashboard on the studies) "
                        "at 127.0.0.1")
    cmd.add_argument("--tracking-uri", default=None,
                    help="store to serve (default: $MLFLOW_TRACKING_URI or mlruns/mlflow.db)")
    cmd.add_argument("--port", type=int, default=5000)
    cmd.add_argument("--workers", type=argtypes.count, default=1,
                    help="MLflow server processes (default 1: one user's browser)")
    cmd.add_argument("--storage", default=None,
                    help="also serve the Optuna studies of this storage (journal file or RDB "
                    "URL) with optuna-dashboard (default: mlruns/optuna.journal if present)")
    cmd.add_argument("--dashboard-port", type=int, default=8080)
    cmd.set_defaults(func=ui.run)


def _add_design(sub: Subparsers) -> None:
    """``workbench design``: the settings to measure next."""
    des = sub.add_parser("design", help="choose the settings to measure next: the candidates "
                         "whose measurement would most lower the model's uncertainty")
    des.add_argument("config", help="experiment config (TOML); its model is fitted on the "
                     "config's training rows")
    des.add_argument("--candidates", required=True, metavar="CANDIDATES.csv",
                     help="settings that could be measured: the model's input columns (features, "
                     "the control model's prediction, Hamiltonian parameters), no measurement")
    des.add_argument("--n", type=argtypes.count, required=True, help="how many to choose (a batch)")
    des.add_argument("--out", required=True, metavar="NEXT.csv",
                     help="the chosen rows, in the order chosen, with the reason for each")
    des.add_argument("--criterion", choices=("i", "d"), default="i",
                     help="i: lower the average predictive variance over the candidates "
                     "(default); d: most information about the model's coefficients (log det)")
    des.add_argument("--jobs", type=argtypes.count, default=None, help="worker processes (default: "
                     "the config's n_jobs)")
    _set_arg(des)
    des.set_defaults(func=commands.design)


def _add_simulate(sub: Subparsers) -> None:
    """``workbench simulate``: a simulated device's CSV."""
    sim = sub.add_parser("simulate", help="simulate a device of coupled qubits and write a CSV "
                         "(plus a .truth.json sidecar with the graph and injected mismatches); "
                         "with --settings, measure given bias settings on the device of "
                         "--device-seed")
    sim.add_argument("--sites", type=int, default=None,
                     help="qubits in the chain or ring (>= 2; default 5, with --settings the "
                     "number of v_q columns; grid: rows x cols)")
    sim.add_argument("--topology", choices=("chain", "ring", "grid"), default="chain")
    sim.add_argument("--shape", default=None, metavar="RxC", help="grid rows x columns")
    sim.add_argument("--parasitic", choices=("next_nearest", "diagonal", "none"), default=None,
                     help="where parasitic couplings go (default: grid diagonal, else "
                     "next-nearest)")
    sim.add_argument("--experiments", type=int, default=None,
                     help="random bias settings to simulate (default 136; not with --settings)")
    sim.add_argument("--settings", metavar="SETTINGS.csv", default=None,
                     help="measure these rows instead (columns v_q1..v_qN, v_c1..v_cE, others "
                     "ignored) on the device --device-seed and the options above make; "
                     "voltages outside the simulated ranges are allowed")
    sim.add_argument("--noise-seed", type=int, default=None,
                     help="with --settings: seed of the noise and misidentified peaks (default: "
                     "derived from --device-seed and the settings, so the same settings measure "
                     "the same)")
    sim.add_argument("--device-seed", type=argtypes.seed, default=0, metavar="N",
                     help="the device (and, without --settings, the settings and noise; "
                     "default: 0)")
    sim.add_argument("--seed", action=argtypes.Renamed, new="--device-seed")
    sim.add_argument("--mismatch", nargs="+", metavar="NAME", default=None,
                     help="mechanisms to switch on (default: all at realistic sizes; 'none': "
                     "the control model is exact)")
    sim.add_argument("--out", required=True, help="CSV file to write")
    sim.set_defaults(func=tools.simulate)


def _model_args(parser: argparse.ArgumentParser) -> None:
    """Options of the commands that fit a config's model (evaluate, sweep)."""
    parser.add_argument("--no-intervals", action="store_true",
                        help="no prediction intervals (overrides [intervals] enabled; "
                        "the default method 'oof' fits nothing more, 'cv_plus' refits the "
                        "model once per fold)")
    _tracking_args(parser, register=True)


def _tracking_args(parser: argparse.ArgumentParser, register: bool = False) -> None:
    """Options of the commands that log to MLflow (``register``: ``--register`` too)."""
    parser.add_argument("--tracking-uri", default=None,
                        help="MLflow store (default: $MLFLOW_TRACKING_URI, then the config's "
                        "[tracking], then sqlite:///mlruns/mlflow.db)")
    parser.add_argument("--no-track", action="store_true", help="do not log to MLflow")
    if register:
        parser.add_argument("--register", metavar="NAME", default=None,
                            help="register the model in the store's Model Registry as NAME; "
                            "the new version gets the alias 'champion' "
                            "(then: workbench predict models:/NAME@champion ...)")


def _repair_arg(parser: argparse.ArgumentParser) -> None:
    """``--repair`` of the commands that open an Optuna journal."""
    parser.add_argument("--repair", action="store_true",
                        help="first repair a damaged Optuna journal file: every complete "
                        "record is kept (the original stays as FILE.damaged), then the "
                        "command goes on")
