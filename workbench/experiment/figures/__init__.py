"""Figures of the base-boosting paper, as functions that return a matplotlib ``Figure``.

* :func:`mae_bars` -- per-target test error, control program vs learned model (Fig. 2, S4),
  with the errors' bootstrap intervals as error bars when given them; :func:`error_bars`
  draws them from an ``evaluate`` result.
* :func:`model_comparison_bars` -- per-target error bars of 2 to 6 systems (Fig. S6, S7), with
  intervals as error bars when given them.
* :func:`learning_curve_figure` -- the augmented learning curve (Fig. 4, S5).
* :func:`shap_summary` -- SHAP beeswarm summary of a model's predictions (Fig. 5, S8);
  :func:`~workbench.experiment.scoring.explain.shap_values` and :func:`shap_figure` are its halves.
* :func:`correction_shap_figure` -- the SHAP summary of what a base-boosting model adds to its
  prior (model - prior), or a note that the model is the prior.
* :func:`correlation_heatmap` -- pairwise Pearson correlations of the training examples (Fig. 3).
* :func:`voltage_boxplots` -- boxplots of the qubit and coupler bias voltages (Fig. S2).
* :func:`prior_target_boxplots` -- paired boxplots of prior and target eigenenergies (Fig. S3).
* :func:`interval_figure` -- measured against predicted with each row's prediction interval.
* :func:`seed_spread` -- each seed's test error per target, and the mean +- sd over seeds.
* :func:`save_figure` -- write a figure to PNG and close it.

A family's own figures live beside the family (e.g.
:mod:`workbench.experiment.families.hamiltonian_figures`), drawn with the shared look of
:mod:`.style`. Every figure takes the targets' ``unit`` (a dataset's
:attr:`~workbench.datasets.Dataset.unit`; ``None``: no unit shown). The same data give the
same figure; nothing is shown, and matplotlib loads with the first figure drawn.

May import: scoring.
"""

from ._bars import error_bars, mae_bars, model_comparison_bars
from ._curves import learning_curve_figure
from ._data import correlation_heatmap, prior_target_boxplots, voltage_boxplots
from ._intervals import interval_figure
from ._seeds import seed_spread
from ._shap import correction_shap_figure, shap_figure, shap_summary
from .style import save_figure

__all__ = ["correction_shap_figure", "correlation_heatmap", "error_bars", "interval_figure",
           "learning_curve_figure", "mae_bars", "model_comparison_bars",
           "prior_target_boxplots", "save_figure", "seed_spread", "shap_figure",
           "shap_summary", "voltage_boxplots"]
