"""Experiment configs (TOML files under ``experiments/``): a typed schema, checked.

Each section of a config is a pydantic model: the schema *is* the documentation of the
config (see ``experiments/paper_main_body.toml`` for an annotated file)::

    name, description, random_state, n_jobs     # top level (ExperimentConfig)
    [data]         DataConfig       the benchmark, or a CSV of your own
    [data.hamiltonian]  HamiltonianData  the Hamiltonian's columns (physics-aware families)
    [model]        ModelConfig      family + the eigenvalue-space boosting settings
    [model.targets.<target>]  BoostSettings  per-target overrides
    [model.<family>]  the family's own settings (``ModelFamily.settings``)
    [selection]    SelectionConfig  BaseBoostCV's folds and scoring
    [evaluation]   EvaluationConfig extra estimates of ``evaluate``
    [intervals]    IntervalsConfig  conformal prediction intervals of the fitted model
    [search]       the space a sweep searches (:class:`~.space.SearchSpace`;
                   ``[search.<family>]`` varies the family's settings)
    [cv]           CVConfig         nested CV of a sweep
    [study]        StudyConfig      the Optuna studies
    [tracking]     TrackingConfig   MLflow

One module per concern: :mod:`.schema` (``Section``, the base of every table, a family's
settings too), :mod:`.data` (``[data]``), :mod:`.sections` (the other sections),
:mod:`.validation` (a target's boosting settings against the estimators' own
``_parameter_constraints``, scikit-learn's machinery), :mod:`.space` (search spaces),
:mod:`.experiment` (:class:`ExperimentConfig`), :mod:`.loading` (the config's dataset,
:func:`load_dataset`), :mod:`.overrides` (``--set SECTION.KEY=VALUE``) and
:mod:`.toml_text` (TOML text as ``workbench init`` writes it).
Reading a file, which needs the model families, is :mod:`workbench.experiment.runs.prepare`: this
package sits below the families and imports none of them.

May import: process.
"""

from ..process.errors import ConfigError
from .data import DataConfig, HamiltonianData
from .experiment import ExperimentConfig, without_intervals
from .loading import check_training_rows, data_key, load_dataset
from .sections import (
    MODEL_DEFAULTS,
    BoostSettings,
    CVConfig,
    EvaluationConfig,
    IntervalsConfig,
    ModelConfig,
    SelectionConfig,
    StudyConfig,
    TopLevel,
    TrackingConfig,
)
from .validation import check_boost_settings

__all__ = ["MODEL_DEFAULTS", "BoostSettings", "CVConfig", "ConfigError", "DataConfig",
           "EvaluationConfig", "ExperimentConfig", "HamiltonianData", "IntervalsConfig",
           "ModelConfig", "SelectionConfig", "StudyConfig", "TopLevel", "TrackingConfig",
           "check_boost_settings", "check_training_rows", "data_key", "load_dataset",
           "without_intervals"]
