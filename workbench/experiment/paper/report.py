"""The reproduction's Markdown report (``reports/README.md``), from its results only.

:func:`report` joins one section per subject; every number comes from the
:class:`~.reproduction.Reproduction`, its errors in the data's unit.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from ..families.stage import candidate_settings
from ..scoring.bootstrap import bootstrap_description
from ..scoring.results import Result
from ..scoring.units import unit_name, unit_suffix, with_unit
from .compute import SHORT
from .gates import Gates
from .reproduction import REFERENCE, Reproduction

__all__ = ["report"]

#: ``img(fig_id, caption)``: the Markdown images of a figure id's files.
Images = Callable[[str, str], str]


def _row(name: str, values: Sequence[float], avg: float | None = None,
         ci: Sequence[Sequence[float] | None] | None = None,
         diff: Sequence[float] | None = None) -> str:
    """Write a table row: per target the value, the average in bold, the paired interval.

    With ``ci`` each value has its 95% interval (one ``[low, high]`` per target, then the
    average's); ``diff`` is the paired interval of model - prior on average (blank without).
    """
    avg = float(np.mean(values)) if avg is None else avg
    bounds_of = ci or [None] * (len(values) + 1)

    def cell(v: float, bounds: Sequence[float] | None, bold: bool = False) -> str:
        text = f"**{v:.3f}**" if bold else f"{v:.3f}"
        return text if bounds is None else f"{text} ({bounds[0]:.2f}-{bounds[1]:.2f})"

    gain = "" if diff is None else f"{diff[0]:+.2f} to {diff[1]:+.2f}"
    return (f"| {name} | " + " | ".join(cell(v, b) for v, b in zip(values, bounds_of))
            + f" | {cell(avg, bounds_of[-1], bold=True)} | {gain} |")


def _system_row(name: str, result: Result) -> str:
    """Write a system's table row from its result's test MAE and intervals."""
    m = result.model
    diff = m.ci("test_mae_diff")
    return _row(name, m.test_mae, ci=m.ci("test_mae"), diff=diff[-1] if diff else None)


def _hamiltonian_section(ham: Result, tables: dict[str, str]) -> str:
    """Write the report's paragraph on the parameter-space model, from its evaluate result."""
    sel = ham.details["hamiltonian"].get("selection", {})
    repeated = ham.repeated_cv
    nested = ham.nested_cv_all
    u = unit_suffix(ham.unit)
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
        f"{u}); an eigenvalue-space boosting stage on top is kept per target only where "
        f"BaseBoostCV says it helps (kept for: "
        f"{', '.join(t for t, x in zip(SHORT, ham.model.selected) if '+' in x) or 'none'}).",
        "",
        f"- Test MAE (41 rows, scored once): **{ham.model.avg('test_mae'):.3f}{u}** against "
        f"{ham.prior.avg('test_mae'):.3f} for the control program.",
    ]
    if repeated:
        lines.append(f"- Repeated CV of the chosen model on the training rows "
                     f"({repeated.repeats} x {repeated.folds} folds, seeds other than the "
                     f"selection's): {repeated.model_mae_avg:.3f}{u} (control program "
                     f"{repeated.prior_mae_avg:.3f}). The covariates were chosen on these "
                     "rows, so this is optimistic.")
    if nested:
        lines.append(f"- Nested CV over all {nested.n_rows} experiments ({nested.folds} outer "
                     f"folds, the selection redone inside each): {nested.model_mae_avg:.3f}{u}"
                     f" (control program {nested.prior_mae_avg:.3f}), the least noisy "
                     "estimate.")
    else:
        lines.append("- The least noisy estimate, a nested CV over all 136 experiments with the "
                     "selection redone inside each outer fold, is left out of the reproduction: "
                     "`workbench evaluate experiments/hamiltonian.toml` computes it.")
    if tables:
        lines.append("- Tables: " + ", ".join(f"[{n}]({p})" for n, p in tables.items())
                     + f" (coefficients in {unit_name(ham.unit)} per covariate standard "
                       "deviation; corrected parameters per experiment).")
    return "\n".join(lines)


def _gates_section(gates: Gates, figure: str) -> str:
    """Write the report's section on the IBM benchmark, its table drawn as the Google one."""
    g, p = gates.generic, gates.peer
    ds = gates.dataset
    assert ds.groups is not None  # the benchmark's rows name their device
    n_dev_train = ds.groups[ds.train_index].nunique()
    n_dev_test = ds.groups[ds.test_index].nunique()
    d = gates.generic_minus_peer
    head = ("| system | gate error | average | model - coherence limit, average |\n"
            "|---|---|---|---|")
    rows = [_row("coherence limit (prior)", g.prior.test_mae, ci=g.prior.ci("test_mae")),
            _row("LightGBM from the prior, tuned by CV (peer)", p.model.test_mae,
                 ci=p.model.ci("test_mae"), diff=p.model.test_mae_diff_avg_ci or None),
            _row("workbench, generic config", g.model.test_mae, ci=g.model.ci("test_mae"),
                 diff=g.model.test_mae_diff_avg_ci or None)]
    ratio = g.model.avg("test_mae") / p.model.avg("test_mae")
    n_candidates = len(candidate_settings(gates.config.model_for(g.targets[0]), 0))
    return f"""## A second benchmark: IBM two-qubit gates

The calibration snapshots of {ds.groups.nunique()} IBM Quantum devices (2020-2026, shipped
in `qiskit-ibm-runtime`'s fake provider; Apache-2.0): one row per two-qubit gate, the target
its measured error (percent), the prior the error that the two qubits' T1 and T2 alone cause
during the gate (the coherence limit), the features the qubits' T1, T2, readout and
single-qubit gate errors, the gate's length, the device's size and the gate type. The honest
split holds out the snapshots taken from 2025 on: {len(ds.test_index)} gates of
{n_dev_test} devices never seen in training, on later dates, against {len(ds.train_index)}
training gates of {n_dev_train} devices. Every choice is made by CV on the training rows.

Test mean absolute error (percentage points of gate error), with 95% bootstrap intervals
over the test rows ({bootstrap_description(gates.peer.bootstrap)}):

{head}
{chr(10).join(rows)}

The generic config's error is {ratio:.3f} of the peer's (paired 95% interval of the
difference, generic - peer: {d[0]:+.3f} to {d[1]:+.3f}). Both learn from the same rows and
features. CV chose {", ".join(gates.chosen)} among {n_candidates} candidates and the
prior alone. `benchmarks/peers.py` repeats the comparison on the devices split (30% of the
devices held out at random) and on the other benchmarks.

{figure}
"""


def _table(rep: Reproduction) -> str:
    """Write the table of every system's test MAE (the reference rows first)."""
    s = rep.settings
    head = ("| system | " + " | ".join(SHORT) + " | average | model - control program, "
            "average |\n|---|" + "---|" * 7)
    rows = [_row(k, v, avg) for k, (v, avg) in REFERENCE.items()]
    rows += [_row("control program (this run)", s["paper"].prior.test_mae,
                  ci=s["paper"].prior.ci("test_mae")),
             _system_row("workbench, paper settings (this run)", s["paper"]),
             _system_row("workbench, improved settings (this run)", s["improved"])]
    if "search" in s:  # `reproduce --all`
        rows.append(_system_row("workbench, best configuration of its nested-CV search "
                                "(this run)", s["search"]))
    rows += [_system_row("workbench, Hamiltonian parameter-space model (this run)",
                         s["hamiltonian"]),
             _row(f"tabula rasa MLP on the 9 voltages (this run, mean of "
                  f"{len(rep.tabula_rasa['seeds'])} seeds)", rep.tabula_rasa["test_mae"],
                  ci=rep.tabula_rasa["test_mae_ci"])]
    return head + "\n" + "\n".join(rows)


def _search_text(rep: Reproduction) -> str:
    """Write what the report says of the nested-CV search: its row, or how to get it."""
    if "search" not in rep.settings:
        return ("The workbench's own\nnested-CV search (`experiments/paper_search.toml`) and "
                "the second benchmark, the IBM\ntwo-qubit gates, are not part of this run: "
                "`workbench reproduce --all` adds them (their\nrows, figures and MLflow runs).")
    nested = rep.settings["search"].sweep
    assert nested is not None  # a sweep's result
    return f"""The search row
is the configuration chosen per target by nested cross-validation on the training rows
(`experiments/paper_search.toml`); its nested-CV estimate on the training rows is
{nested.nested_cv_mae_avg:.3f}{unit_suffix(rep.unit)} against \
{nested.nested_cv_prior_mae_avg:.3f} for the
control program."""


def _results_section(rep: Reproduction, img: Images) -> str:
    """Write the report's head: the data, the table of every system, Fig. 2 and S4."""
    quick = " (quick mode: reduced curves, SHAP rows and search)" if rep.quick else ""
    command = "`workbench reproduce --all`" if rep.all_systems else "`workbench reproduce`"
    return f"""# Reproducing "Boosting on the shoulders of giants in quantum device calibration"

Generated by {command}{quick} (random_state {rep.random_state}).
Data: the Google 5-qubit calibration benchmark, the paper's split (95 training / 41 test
experiments). Targets Y1..Y5 are the measured eigenenergies (ascending); the prior X1..X5 is
the control program's prediction. Every choice is made on the training rows; the 41 test rows
are scored once per setting.

## {with_unit("Test mean absolute error", rep.unit)}

{_table(rep)}

In parentheses: 95% bootstrap intervals over the 41 test rows (percentile bootstrap, 10,000
resamples of the rows, all targets of a row together); the last column is the paired interval
of the system's average test MAE minus the control program's on the same resamples (below 0:
the system beats the control program beyond the test set's noise). Overlapping intervals
show no difference: on 41 rows, settings 0.01 MHz apart cannot be told apart.

The first three rows are the control program and the reference implementation as measured on
this kind of machine (not recomputed here). The paper's claim is that base boosting with its
settings beats the control program on every eigenenergy, at about 1.08 MHz on average; its
own per-target table is not part of this project's material, so the reference
implementation's measured rows stand in for it. "Paper settings": the paper's stacking basis,
K = 1, squared-error residuals, absolute-error line search with penalty 0.1, inbuilt model
selection by 5-fold CV. "Improved settings": Huber losses, ridge basis for Y3. {_search_text(rep)}

{img('figR1_systems_mae', 'Every system')}

The same numbers are in `systems.csv` and, one run per system, in MLflow's experiment
`paper-reproduction` (`workbench ui`): the runs share the metric keys of `workbench evaluate`
(`test_mae/<target>`, `test_mae_avg`, ...), so MLflow's compare view lines them up with each
other and with any evaluate run.

{img('fig2_mae_bars', 'Fig. 2')}

{img('figS4_mse_bars', 'Fig. S4')}
"""


def _beyond_section(rep: Reproduction, img: Images) -> str:
    """Write the sections on the parameter-space model, the IBM benchmark and the data."""
    gates = (_gates_section(rep.gates, img('figG1_gates_mae', 'IBM two-qubit gates'))
             if rep.gates else "")
    return f"""
## Beyond the paper: correcting the Hamiltonian

{_hamiltonian_section(rep.settings["hamiltonian"], rep.hamiltonian_tables)}

{img('figH1_hamiltonian_mae_bars', 'Parameter-space model, test MAE')}

{img('figH2_parameter_corrections', 'Corrections of the Hamiltonian parameters')}

{img('figH3_selection_path', 'Forward covariate selection')}

{gates}
## The data

{img('fig3_correlation', 'Fig. 3')}

{img('figS2_voltage_boxplots', 'Fig. S2')}

{img('figS3_prior_target_boxplots', 'Fig. S3')}
"""


def _curves_and_shap_section(rep: Reproduction, img: Images) -> str:
    """Write the sections on the learning curves, the tabula rasa MLPs and SHAP."""
    lc, tr, figs = rep.learning_curves, rep.tabula_rasa, rep.figures
    u = unit_suffix(rep.unit)
    return f"""
## Augmented learning curves

Training error, 5-fold CV error and the control program's (incumbent's) CV error against the
number of training rows actually used: {lc['train_sizes']}. The paper's sizes run to 95, but
5-fold CV on 95 training rows trains on at most {max(lc['train_sizes'])} rows; larger sizes
would need rows outside the training set (the reference labelled sizes up to 95 while
training on fewer rows).

{img('figS5_learning_curves', 'Fig. S5')}

The paper's Fig. 4 is the Y3 panel of Fig. S5 ({figs['fig4_learning_curve_Y3'][0]}), drawn
once.

## Tabula rasa and SHAP

A ReLU MLP on the 9 voltages alone (no prior, the paper's per-target settings, the voltages
mapped to normal quantiles first as the reference implementation does by default) reaches
{float(np.mean(tr['test_mae'])):.1f}{u} average test MAE, the mean of {len(tr['seeds'])}
random initialisations (seeds {tr['seeds'][0]} to {tr['seeds'][-1]}: from
{tr['test_mae_avg_min']:.1f} to {tr['test_mae_avg_max']:.1f}{u}, standard deviation
{tr['test_mae_avg_sd']:.1f}); about 11 MHz was measured for the reference. Either way the
physics prior is worth an order of magnitude.

{img('figS6_tabula_rasa_mae', 'Fig. S6')}

{img('figS7_tabula_rasa_mse', 'Fig. S7')}

SHAP summaries (exact SHAP values over the training rows) of that MLP per target (the
first seed's):

{img('figS8_shap', 'Fig. S8')}

The paper's Fig. 5 is the Y1 panel of Fig. S8 ({figs['fig5_shap_Y1'][0]}), drawn once.

## What base boosting learned: SHAP of the correction

The paper settings' prediction is the control program's plus a learned correction. A SHAP
summary of the whole prediction is dominated by the prior (tens of MHz); what boosting learned
is the correction, model minus prior (about 1 MHz). Per target, the correction's summary
first, then the whole prediction's, on the same training rows over the same background. A
target whose model is its prior (cross-validation chose it, or every boosted stage's
coefficient is 0) has no correction to explain; its figure says so.

{img('figR2_shap_correction', 'SHAP of the correction')}

{img('figR3_shap_prediction', 'SHAP of the whole prediction')}
"""


def report(rep: Reproduction) -> str:
    """Write the Markdown report (``reports/README.md``) from the reproduction's results.

    Parameters
    ----------
    rep : Reproduction
        What was computed.

    Returns
    -------
    str
        The report.
    """
    def img(fig_id: str, caption: str) -> str:
        return "\n".join(f"![{caption}]({p})" for p in rep.figures[fig_id])

    return (_results_section(rep, img) + _beyond_section(rep, img)
            + _curves_and_shap_section(rep, img))
