"""``workbench reproduce``: every result and figure of the paper from the Google 5-qubit data.

Writes PNG figures, ``results.json``, ``manifest.json`` (figure id -> file(s)) and a
``README.md`` report under the output folder, and logs the same numbers and figures to the
MLflow experiment ``paper-reproduction`` (a parent run with one child run per figure group).
Every number in a figure comes from the same dictionaries that are written to JSON and MLflow.
"""

from __future__ import annotations

import json
import logging
import time
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.neural_network import MLPRegressor

from .._io import atomic_write
from ..curves import learning_curve_plan
from ..parallel import Task, map_tasks, run_plans
from .config import load_config
from .errors import UsageError
from .evaluate import evaluate
from .explain import shap_values
from .figures import (
    correlation_heatmap,
    learning_curve_figure,
    mae_bars,
    model_comparison_bars,
    prior_target_boxplots,
    save_figure,
    shap_figure,
    voltage_boxplots,
)
from .intervals import family_model
from .results import Result
from .sweep.search import run_sweep
from .tracking.records import dataset_hash, git_commit
from .tracking.runs import Tracker
from .tracking.uris import resolve_tracking_uri

__all__ = ["PAPER_SIZES", "REFERENCE", "TABULA_RASA", "Reproduction", "report", "reproduce"]

#: The source checkout the package may have been imported from (an installed wheel's
#: site-packages has no ``experiments/``).
CHECKOUT = Path(__file__).resolve().parents[2]
#: The configs the reproduction runs, read from an experiments folder.
CONFIGS = ("paper_main_body.toml", "paper_improved.toml", "paper_search.toml",
           "hamiltonian.toml")


def experiments_dir(explicit: str | Path | None = None) -> Path:
    """The folder holding the reproduction's :data:`CONFIGS`: ``explicit`` if given, else the
    ``experiments/`` of the checkout the package runs from, else ``./experiments`` (an
    installed wheel carries no configs). A :class:`UsageError` names what is missing."""
    folders = ([Path(explicit)] if explicit is not None
               else [CHECKOUT / "experiments", Path.cwd() / "experiments"])
    for folder in folders:
        if all((folder / name).is_file() for name in CONFIGS):
            return folder
    shown = folders[0] if explicit is not None else Path("experiments")
    missing = [n for n in CONFIGS if not (folders[-1] / n).is_file()]
    raise UsageError(f"reproduce reads its configs from {shown}/, which lacks "
                     f"{', '.join(missing)}; run it from a workbench checkout or pass "
                     "--experiments DIR")
SHORT = ["Y1", "Y2", "Y3", "Y4", "Y5"]

#: The paper's learning-curve training sizes (23 ... 95 training rows).
PAPER_SIZES = [23, 33, 43, 54, 64, 74, 85, 95]

#: Reference results measured on this kind of machine (``method.md``): per-target test MAE
#: and the documented average (MHz).
REFERENCE = {
    "control program (prior)": ([2.417, 1.400, 0.819, 0.972, 1.098], 1.341),
    "scikit-physlearn, paper settings (mean of 8 runs)":
        ([1.750, 1.036, 0.802, 0.801, 1.004], 1.081),
    "scikit-physlearn, improved settings (4 runs)": ([1.702, 1.008, 0.768, 0.800, 0.981], 1.057),
}

#: Tabula rasa MLPs on the 9 voltages (paper_params.md): hidden, alpha, max_iter per target.
TABULA_RASA = [((10,), 15.0, 4600), ((10,), 15.0, 5020), ((10,), 13.0, 5780),
               ((10,), 19.0, 4160), ((8,), 19.0, 5240)]


def _tabula_rasa(j: int, seed: int) -> MLPRegressor:
    hidden, alpha, max_iter = TABULA_RASA[j]
    return MLPRegressor(hidden_layer_sizes=hidden, activation="relu", solver="lbfgs",
                        alpha=alpha, max_iter=max_iter, random_state=seed)


@dataclass
class Reproduction:
    """What ``workbench reproduce`` computed: a :class:`Result` per setting ("paper",
    "improved", "search", "hamiltonian"), the tabula-rasa MLPs' test errors, the training
    rows' correlation, the learning curves, the figures (id -> files, relative to the report
    folder) and the parameter-space model's tables."""

    targets: list[str]
    seed: int
    quick: bool
    settings: dict[str, Result]
    tabula_rasa: dict[str, list[float]]
    correlation: dict[str, Any]
    learning_curves: dict[str, Any]
    figures: dict[str, list[str]]
    hamiltonian_tables: dict[str, str] = field(default_factory=dict)
    mlflow: dict[str, str] = field(default_factory=dict)
    wall_s: float = float("nan")

    def to_json(self) -> dict[str, Any]:
        out = {"targets": self.targets, "short": SHORT, "seed": self.seed, "quick": self.quick,
               "settings": {k: r.to_json() for k, r in self.settings.items()},
               "reference": REFERENCE,
               "tabula_rasa": {**self.tabula_rasa,
                               "test_mae_avg": float(np.mean(self.tabula_rasa["test_mae"])),
                               "test_mse_avg": float(np.mean(self.tabula_rasa["test_mse"]))},
               "correlation": self.correlation, "learning_curves": self.learning_curves,
               "figures": self.figures, "hamiltonian_tables": self.hamiltonian_tables,
               "wall_s": self.wall_s}
        if self.mlflow:
            out["mlflow"] = self.mlflow
        return out


_T0 = [time.perf_counter()]


def _say(text: str) -> None:
    logging.getLogger("workbench").info("[reproduce %5.0f s] %s", time.perf_counter() - _T0[0],
                                        text)


def reproduce(out: str | Path = "reports", *, tracking_uri: str | None = None,
              storage: str | None = None, quick: bool = False, track: bool = True, seed: int = 0,
              experiments: str | Path | None = None) -> Reproduction:
    """Compute the paper's results and figures; returns them (also written as
    ``results.json``). The configs come from ``experiments`` (see :func:`experiments_dir`)."""
    start = _T0[0] = time.perf_counter()
    configs = experiments_dir(experiments)
    out = Path(out)
    figdir = out / "figures"
    figdir.mkdir(parents=True, exist_ok=True)
    files: dict[str, list[Path]] = {}
    groups: dict[str, list[str]] = {}

    def save(fig_id: str, group: str, fig, name: str | None = None) -> None:
        path = save_figure(fig, figdir / f"{name or fig_id}.png")
        files.setdefault(fig_id, []).append(path)
        groups.setdefault(group, []).append(fig_id)

    # -- the benchmark under three settings --------------------------------------------
    settings = {}
    for key, toml in (("paper", "paper_main_body.toml"), ("improved", "paper_improved.toml")):
        _say(f"evaluating the {key} settings ({toml})")
        cfg = _no_intervals(replace(load_config(configs / toml), random_state=seed))
        run = evaluate(cfg, return_model=True)
        settings[key], ds = run.result, run.dataset
    _say("nested-CV search for the workbench's own best configuration "
                   "(experiments/paper_search.toml)")

    search_cfg = load_config(configs / "paper_search.toml")
    cv = {"seed": seed, **({"outer_folds": 2, "inner_folds": 3} if quick else {})}
    search_cfg = _no_intervals(replace(search_cfg, random_state=seed,
                                       cv=search_cfg.cv.model_copy(update=cv)))
    # another seed, or --quick (other folds and budgets), must not resume these studies
    search_cfg = search_cfg.with_study(study_name=f"{search_cfg.name}-seed{seed}"
                                                  f"{'-quick' if quick else ''}",
                                       trials=2 if quick else None, storage=storage)
    with warnings.catch_warnings():  # a candidate basis's convergence notes: not the user's
        warnings.simplefilter("ignore", ConvergenceWarning)
        # a line per trial: the longest phase of the job
        settings["search"] = run_sweep(search_cfg, progress=True).result
    hamiltonian_model = _hamiltonian(settings, seed, quick, configs)
    X_train, X_test, y_train, y_test = ds.split()
    targets = ds.target_names
    paper = settings["paper"]

    save("fig2_mae_bars", "benchmark",
         mae_bars(SHORT, paper.prior.test_mae, paper.model.test_mae,
                  title="Test MAE per eigenenergy (Fig. 2)", setting="paper settings"))
    save("figS4_mse_bars", "benchmark",
         mae_bars(SHORT, paper.prior.test_mse, paper.model.test_mse, metric="MSE",
                  unit="MHz²", title="Test MSE per eigenenergy (Fig. S4)",
                  setting="paper settings"))

    # -- beyond the paper: the parameter-space model -------------------------------------
    ham = settings["hamiltonian"]
    save("figH1_hamiltonian_mae_bars", "hamiltonian",
         mae_bars(SHORT, ham.prior.test_mae, ham.model.test_mae,
                  labels=("control program", "parameter-space model"),
                  title="Test MAE per eigenenergy: corrected Hamiltonian",
                  setting="experiments/hamiltonian.toml"))
    ham_cfg, hamiltonian_model = hamiltonian_model
    ham_out = ham_cfg.family.outputs(family_model(hamiltonian_model), ds,
                                     setting="experiments/hamiltonian.toml")
    save("figH2_parameter_corrections", "hamiltonian", ham_out.figures["parameter_corrections"])
    save("figH3_selection_path", "hamiltonian", ham_out.figures["selection_path"])
    tables = {name: str(path.relative_to(out))
              for name, path in ham_out.write(out / "hamiltonian", figures=False).items()}

    # -- the data --------------------------------------------------------------------------
    _say("data figures")
    train = ds.X.loc[ds.train_index]
    frame = train[ds.prior_names].set_axis([f"X{j}" for j in range(1, 6)], axis=1)
    frame = frame.join(y_train.set_axis(SHORT, axis=1))
    correlation = frame.corr()
    save("fig3_correlation", "data", correlation_heatmap(
        frame, title="Correlation of training examples (Fig. 3)"))
    save("figS2_voltage_boxplots", "data", voltage_boxplots(
        ds.features.loc[ds.train_index], title="Bias voltages, training rows (Fig. S2)"))
    save("figS3_prior_target_boxplots", "data", prior_target_boxplots(
        train[ds.prior_names].set_axis(SHORT, axis=1), y_train.set_axis(SHORT, axis=1),
        title="Control program (X) and measured (Y) eigenenergies (Fig. S3)"))

    # -- augmented learning curves -------------------------------------------------------
    folds = 5
    largest = len(X_train) - -(-len(X_train) // folds)
    sizes = [s for s in PAPER_SIZES if s <= largest]
    sizes = sorted(set(sizes + [largest]))
    if quick:
        sizes = [sizes[0], sizes[len(sizes) // 2], sizes[-1]]
    _say(f"augmented learning curves at training sizes {sizes} "
                   f"(5-fold CV on the training rows: at most {largest} rows)")
    curves = {}
    # the five curves' (size, fold) fits share the worker processes (every core)
    fitted = run_plans([learning_curve_plan(est, X_train, y_train[target].to_numpy(),
                                            train_sizes=sizes, cv=folds, random_state=seed)
                        for target, est in zip(targets, _paper_candidates(ds, configs))], -1)
    for j, (target, curve) in enumerate(zip(targets, fitted)):
        curves[SHORT[j]] = curve.to_dict()
        fig = learning_curve_figure(curve, target=f"{SHORT[j]} ({target})",
                                    setting="paper settings")
        save("figS5_learning_curves", "learning_curves", fig, f"figS5_learning_curve_{SHORT[j]}")
        if SHORT[j] == "Y3":
            save("fig4_learning_curve_Y3", "learning_curves",
                 learning_curve_figure(curve, target=f"Y3 ({target})",
                                       title="Augmented learning curve, Y3 (Fig. 4)",
                                       setting="paper settings"))

    # -- tabula rasa and SHAP ------------------------------------------------------------
    _say("tabula rasa MLPs on the 9 voltages, SHAP summaries")
    V_train, V_test = X_train[ds.feature_names], X_test[ds.feature_names]
    tabula: dict[str, list[float]] = {"test_mae": [], "test_mse": []}
    shap_rows = V_train.iloc[:30] if quick else V_train
    background = 10 if quick else 50
    # one task per target on the workers (fit, test errors, SHAP values); figures here
    per_target = map_tasks([Task(_tabula_rasa_target, j, seed, V_train, y_train[target],
                                 V_test, y_test[target], shap_rows, background)
                            for j, target in enumerate(targets)], -1)
    for j, (target, (mae, mse, values, expected)) in enumerate(zip(targets, per_target)):
        tabula["test_mae"].append(mae)
        tabula["test_mse"].append(mse)
        if SHORT[j] == "Y1":
            save("fig5_shap_Y1", "shap", shap_figure(
                values, expected, shap_rows, target=f"Y1 ({target})",
                title="SHAP summary, Y1 (Fig. 5)", random_state=seed,
                setting="MLP on the 9 voltages"))
        save("figS8_shap", "shap", shap_figure(
            values, expected, shap_rows, target=f"{SHORT[j]} ({target})", random_state=seed,
            setting="MLP on the 9 voltages"), f"figS8_shap_{SHORT[j]}")
    for metric, fig_id, unit in (("mae", "figS6_tabula_rasa_mae", "MHz"),
                                 ("mse", "figS7_tabula_rasa_mse", "MHz²")):
        values = {"tabula rasa MLP (voltages only)": tabula[f"test_{metric}"],
                  "control program": getattr(paper.prior, f"test_{metric}"),
                  "base boosting (paper settings)": getattr(paper.model, f"test_{metric}")}
        save(fig_id, "tabula_rasa", model_comparison_bars(
            SHORT, values, metric=metric.upper(), unit=unit, log=True,
            title=f"Tabula rasa vs base boosting, test {metric.upper()} (Fig. "
                  f"{'S6' if metric == 'mae' else 'S7'})"))

    rep = Reproduction(
        targets=targets, seed=seed, quick=quick, settings=settings,
        tabula_rasa=tabula, correlation=correlation.round(6).to_dict(),
        learning_curves={"train_sizes": sizes, "folds": folds, "curves": curves},
        figures={k: [str(p.relative_to(out)) for p in v] for k, v in files.items()},
        hamiltonian_tables=tables)
    rep.wall_s = time.perf_counter() - start
    _write(out / "results.json", rep.to_json())
    _write(out / "manifest.json", {k: (v[0] if len(v) == 1 else v)
                                   for k, v in rep.figures.items()})
    if track:
        rep.mlflow = _log(rep, files, groups, out, tracking_uri, ds)
        _write(out / "results.json", rep.to_json())
    atomic_write(out / "README.md", report(rep))
    _say(f"done in {rep.wall_s:.0f} s: {out / 'README.md'}")
    return rep


def _tabula_rasa_target(j: int, seed: int, V_train, y_train, V_test, y_test, shap_rows,
                        background: int) -> tuple[float, float, np.ndarray, float]:
    """Target ``j``'s tabula rasa MLP on the voltages: its test MAE and MSE, and the SHAP
    values (and expected value) of its predictions on ``shap_rows``."""
    with warnings.catch_warnings():  # the paper's max_iter, kept as published
        warnings.simplefilter("ignore", ConvergenceWarning)
        mlp = _tabula_rasa(j, seed).fit(V_train.to_numpy(), y_train.to_numpy())
    err = y_test.to_numpy() - mlp.predict(V_test.to_numpy())
    values, expected = shap_values(lambda a: mlp.predict(a), shap_rows,
                                   background_size=background, random_state=seed)
    return float(np.mean(np.abs(err))), float(np.mean(err ** 2)), values, expected


def _no_intervals(cfg):
    """``cfg`` without prediction intervals: the reproduction reports the paper's errors, and
    CV+ would refit every model 5 more times (``workbench evaluate`` reports the intervals;
    ``python benchmarks/intervals.py`` measures them)."""
    return replace(cfg, intervals=cfg.intervals.model_copy(update={"enabled": False}))


def _hamiltonian(settings: dict[str, Any], seed: int, quick: bool, configs: Path):
    """Evaluate ``experiments/hamiltonian.toml`` into ``settings["hamiltonian"]``; returns
    the fitted model. Its nested CV over all rows (about 4 minutes, which would take the main
    job near 10) is left to ``workbench evaluate experiments/hamiltonian.toml``; quick mode
    also uses a smaller pool and one CV repeat."""
    cfg = load_config(configs / "hamiltonian.toml")
    evaluation = {"nested_folds": 0}
    hamiltonian: dict[str, Any] = {}
    if quick:
        evaluation.update(cv_repeats=1)
        hamiltonian.update(candidates="local", max_steps=2, selection_cv=3)
    assert cfg.family_settings is not None  # family = "hamiltonian" has settings
    cfg = replace(cfg, random_state=seed, evaluation=cfg.evaluation.model_copy(update=evaluation),
                  family_settings=cfg.family_settings.model_copy(update=hamiltonian))
    cfg = _no_intervals(cfg)
    _say("the parameter-space model (experiments/hamiltonian.toml): covariate "
                   "selection by CV on the training rows")
    run = evaluate(cfg, return_model=True)
    settings["hamiltonian"] = run.result
    return cfg, run.model


def _paper_candidates(ds, configs: Path):
    """The paper-settings candidate (an unfitted BaseBoostRegressor) of each target."""
    cfg = load_config(configs / "paper_main_body.toml")
    model = cfg.family.build(cfg, ds)
    return [model.target_estimators[t].estimator for t in ds.target_names]


def _write(path: Path, obj) -> None:
    atomic_write(path, json.dumps(obj, indent=2, default=str) + "\n")


def _log(rep: Reproduction, files, groups, out: Path, tracking_uri, ds) -> dict[str, str]:
    uri = resolve_tracking_uri(tracking_uri, None, Path.cwd())
    tracker = Tracker(uri, "paper-reproduction")
    tags = {"workbench.kind": "reproduce", "dataset_hash": dataset_hash(ds.X, ds.targets),
            "git_commit": git_commit(Path(__file__).resolve().parents[2]) or "unknown"}
    with tracker.run("paper reproduction", tags=tags,
                     params={"seed": rep.seed, "quick": rep.quick}) as parent:
        metrics = {}
        for key, res in rep.settings.items():
            metrics[f"{key}.test_mae_avg"] = res.model.avg("test_mae")
            for s, v in zip(SHORT, res.model.test_mae):
                metrics[f"{key}.test_mae.{s}"] = v
        metrics["prior.test_mae_avg"] = rep.settings["paper"].prior.avg("test_mae")
        search = rep.settings["search"].sweep
        assert search is not None  # a sweep's result
        metrics["search.nested_cv_mae_avg"] = search.nested_cv_mae_avg
        metrics["tabula_rasa.test_mae_avg"] = float(np.mean(rep.tabula_rasa["test_mae"]))
        ham = rep.settings["hamiltonian"]
        for key in ("repeated_cv", "nested_cv_all"):
            if getattr(ham, key) is not None:
                metrics[f"hamiltonian.{key}_mae_avg"] = getattr(ham, key).model_mae_avg
        tracker.log_metrics(parent, metrics)
        tracker.log_dict(parent, json.loads(json.dumps(rep.to_json(), default=str)),
                         "results.json")
        for group, fig_ids in groups.items():
            with tracker.run(group, parent_run_id=parent,
                             tags={"workbench.kind": "figure_group"}) as child:
                for fig_id in dict.fromkeys(fig_ids):
                    for path in files[fig_id]:
                        tracker.log_file(child, path, "figures")
    return {"tracking_uri": uri, "run_id": parent}


def _row(name: str, values, avg=None) -> str:
    avg = float(np.mean(values)) if avg is None else avg
    return f"| {name} | " + " | ".join(f"{v:.3f}" for v in values) + f" | **{avg:.3f}** |"


def _hamiltonian_section(ham: Result, tables: dict[str, str]) -> str:
    """The report's paragraph on the parameter-space model, from its evaluate result."""
    sel = ham.details["hamiltonian"].get("selection", {})
    rep = ham.repeated_cv
    nested = ham.nested_cv_all
    lines = [
        "The control program's prediction is the spectrum of a chain Hamiltonian (5 qubit "
        "frequencies, 4 couplings). The parameter-space model (`experiments/hamiltonian.toml`) "
        "corrects each parameter by a linear function of physical covariates (the parameter "
        "and its square, adjacent couplings, detunings, the voltages acting on the site or "
        "coupler and its neighbours) and re-diagonalises, fitting all five eigenenergies at "
        "once by robust Gauss-Newton through the Hellmann-Feynman Jacobian. Covariates are "
        f"chosen by forward selection with {sel.get('folds', '?')}-fold CV on the "
        f"{ham.n_train} training rows ({sel.get('steps', 0)}"
        f" added to the default library, selection CV MAE {sel.get('cv_mae', float('nan')):.3f}"
        " MHz); an eigenvalue-space boosting stage on top is kept per target only where "
        f"BaseBoostCV says it helps (kept for: "
        f"{', '.join(t for t, x in zip(SHORT, ham.model.selected) if '+' in x) or 'none'}).",
        "",
        f"- Test MAE (41 rows, scored once): **{ham.model.avg('test_mae'):.3f} MHz** against "
        f"{ham.prior.avg('test_mae'):.3f} for the control program.",
    ]
    if rep:
        lines.append(f"- Repeated CV of the chosen model on the training rows ({rep.repeats} x "
                     f"{rep.folds} folds, seeds other than the selection's): "
                     f"{rep.model_mae_avg:.3f} MHz (control program {rep.prior_mae_avg:.3f})."
                     " The covariates were chosen on these rows, so this is optimistic.")
    if nested:
        lines.append(f"- Nested CV over all {nested.n_rows} experiments ({nested.folds} outer "
                     f"folds, the selection redone inside each): {nested.model_mae_avg:.3f} MHz"
                     f" (control program {nested.prior_mae_avg:.3f}), the least noisy "
                     "estimate.")
    else:
        lines.append("- The least noisy estimate, a nested CV over all 136 experiments with the "
                     "selection redone inside each outer fold, takes about 4 minutes more: "
                     "`workbench evaluate experiments/hamiltonian.toml` computes it.")
    if tables:
        lines.append("- Tables: " + ", ".join(f"[{n}]({p})" for n, p in tables.items())
                     + " (coefficients in MHz per covariate standard deviation; corrected "
                       "parameters per experiment).")
    return "\n".join(lines)


def report(rep: Reproduction) -> str:
    """The Markdown report (``reports/README.md``), from the reproduction's results only."""
    s = rep.settings
    head = "| system | " + " | ".join(SHORT) + " | average |\n|---|" + "---|" * 6
    rows = [_row(k, v, avg) for k, (v, avg) in REFERENCE.items()]
    rows += [_row("workbench, paper settings (this run)", s["paper"].model.test_mae),
             _row("workbench, improved settings (this run)", s["improved"].model.test_mae),
             _row("workbench, best configuration of its nested-CV search (this run)",
                  s["search"].model.test_mae),
             _row("workbench, Hamiltonian parameter-space model (this run)",
                  s["hamiltonian"].model.test_mae),
             _row("tabula rasa MLP on the 9 voltages (this run)", rep.tabula_rasa["test_mae"])]
    figs = rep.figures
    lc = rep.learning_curves

    def img(fig_id, caption):
        return "\n".join(f"![{caption}]({p})" for p in figs[fig_id])

    nested = s["search"].sweep
    assert nested is not None  # a sweep's result
    quick = " (quick mode: reduced curves, SHAP rows and search)" if rep.quick else ""
    return f"""# Reproducing "Boosting on the shoulders of giants in quantum device calibration"

Generated by `workbench reproduce`{quick} (seed {rep.seed}, {rep.wall_s:.0f} s).
Data: the Google 5-qubit calibration benchmark, the paper's split (95 training / 41 test
experiments). Targets Y1..Y5 are the measured eigenenergies (ascending); the prior X1..X5 is
the control program's prediction. Every choice is made on the training rows; the 41 test rows
are scored once per setting.

## Test mean absolute error (MHz)

{head}
{chr(10).join(rows)}

The first three rows are the control program and the reference implementation as measured on
this kind of machine (not recomputed here). The paper's claim is that base boosting with its
settings beats the control program on every eigenenergy, at about 1.08 MHz on average; its
own per-target table is not part of this project's material, so the reference
implementation's measured rows stand in for it. "Paper settings": the paper's stacking basis,
K = 1, squared-error residuals, absolute-error line search with penalty 0.1, inbuilt model
selection by 5-fold CV. "Improved settings": Huber losses, ridge basis for Y3. The search row
is the configuration chosen per target by nested cross-validation on the training rows
(`experiments/paper_search.toml`); its nested-CV estimate on the training rows is
{nested.nested_cv_mae_avg:.3f} MHz against {nested.nested_cv_prior_mae_avg:.3f} for the
control program.

{img('fig2_mae_bars', 'Fig. 2')}

{img('figS4_mse_bars', 'Fig. S4')}

## Beyond the paper: correcting the Hamiltonian

{_hamiltonian_section(s["hamiltonian"], rep.hamiltonian_tables)}

{img('figH1_hamiltonian_mae_bars', 'Parameter-space model, test MAE')}

{img('figH2_parameter_corrections', 'Corrections of the Hamiltonian parameters')}

{img('figH3_selection_path', 'Forward covariate selection')}

## The data

{img('fig3_correlation', 'Fig. 3')}

{img('figS2_voltage_boxplots', 'Fig. S2')}

{img('figS3_prior_target_boxplots', 'Fig. S3')}

## Augmented learning curves

Training error, 5-fold CV error and the control program's (incumbent's) CV error against the
number of training rows actually used: {lc['train_sizes']}. The paper's sizes run to 95, but
5-fold CV on 95 training rows trains on at most {max(lc['train_sizes'])} rows; larger sizes
would need rows outside the training set (the reference labelled sizes up to 95 while
training on fewer rows).

{img('fig4_learning_curve_Y3', 'Fig. 4')}

{img('figS5_learning_curves', 'Fig. S5')}

## Tabula rasa and SHAP

A ReLU MLP on the 9 voltages alone (no prior, the paper's per-target settings) reaches
{float(np.mean(rep.tabula_rasa['test_mae'])):.1f} MHz average test MAE in this run (its result
depends strongly on the random initialisation; about 11 MHz was measured for the reference):
either way the physics prior is worth an order of magnitude.

{img('figS6_tabula_rasa_mae', 'Fig. S6')}

{img('figS7_tabula_rasa_mse', 'Fig. S7')}

SHAP summaries (Kernel SHAP over the training rows) of that MLP per target:

{img('fig5_shap_Y1', 'Fig. 5')}

{img('figS8_shap', 'Fig. S8')}
"""
