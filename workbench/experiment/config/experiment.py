"""The checked config: :class:`ExperimentConfig`, its sections typed.

It also merges the boosting settings of each target (:meth:`ExperimentConfig.model_for`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pydantic import BaseModel

from .data import DataConfig
from .sections import (
    MODEL_DEFAULTS,
    CVConfig,
    EvaluationConfig,
    IntervalsConfig,
    ModelConfig,
    SelectionConfig,
    StudyConfig,
    TrackingConfig,
)
from .space import SearchSpace

__all__ = ["ExperimentConfig", "without_intervals"]


@dataclass(frozen=True)
class ExperimentConfig:
    """A checked config, as :func:`workbench.experiment.runs.prepare.parse_config` makes it.

    Sections are typed (frozen pydantic models), each a table of the file.

    Parameters
    ----------
    path : Path or None
        The config file (``None``: a config made in code); relative data paths start from
        its folder.
    name : str
        The config's name (the top-level ``name``, else the file's stem).
    random_state : int or None
        The top-level ``random_state``: seeds every random component of the model.
    n_jobs : int or None
        The top-level ``n_jobs`` (see :attr:`jobs`).
    data : DataConfig
        ``[data]``.
    model : ModelConfig
        ``[model]``.
    selection : SelectionConfig, default=SelectionConfig()
        ``[selection]``.
    evaluation : EvaluationConfig, default=EvaluationConfig()
        ``[evaluation]``.
    intervals : IntervalsConfig, default=IntervalsConfig()
        ``[intervals]``.
    search : SearchSpace, default=SearchSpace()
        ``[search]``: the space a sweep searches.
    cv : CVConfig, default=CVConfig()
        ``[cv]``.
    study : StudyConfig, default=StudyConfig()
        ``[study]``.
    tracking : TrackingConfig, default=TrackingConfig()
        ``[tracking]``.
    family_settings : pydantic.BaseModel, default=None
        The family's ``[model.<family>]``, checked by its own schema (``None``: the family
        has none).
    description : str, default=""
        The top-level ``description``.
    chosen : dict of str to dict, default={}
        The per-target settings a search chose: target -> its full boosting settings, which
        :meth:`model_for` returns over ``[model]``'s.
    overrides : dict, default={}
        The ``SECTION.KEY=VALUE`` overrides applied over the file (``--set``).
    family : ModelFamily, default=None
        The :class:`~workbench.experiment.families.base.ModelFamily` that ``[model] family``
        names, resolved by the loader: the config package sits below the families and
        imports none of them, so the attribute is typed ``Any`` here.
    """

    path: Path | None
    name: str
    random_state: int | None
    n_jobs: int | None
    data: DataConfig
    model: ModelConfig
    selection: SelectionConfig = SelectionConfig()
    evaluation: EvaluationConfig = EvaluationConfig()
    intervals: IntervalsConfig = IntervalsConfig()
    search: SearchSpace = field(default_factory=SearchSpace)
    cv: CVConfig = CVConfig()
    study: StudyConfig = StudyConfig()
    tracking: TrackingConfig = TrackingConfig()
    family_settings: BaseModel | None = None
    description: str = ""
    chosen: dict[str, dict[str, Any]] = field(default_factory=dict)
    overrides: dict[str, Any] = field(default_factory=dict)
    family: Any = field(default=None, compare=False, repr=False)

    @property
    def label(self) -> str:
        """The config's file, for messages (``"config"`` when it has none)."""
        return str(self.path) if self.path else "config"

    @property
    def jobs(self) -> int:
        """Processes for independent work (``n_jobs``; unset: every core).

        Results do not depend on it (:mod:`workbench.parallel`).
        """
        return -1 if self.n_jobs is None else self.n_jobs

    def model_for(self, target: str | None) -> dict[str, Any]:
        """Merge the boosting settings of one target.

        Defaults < ``[model]`` < its ``[model.targets.<target>]`` table (< a search's choice
        for it). ``basis_params`` (``input_transform_params``) merge over the parent's while
        the target keeps the parent's basis (transform), and start afresh when it names
        another one.

        Parameters
        ----------
        target : str or None
            A target's name (``None``: the ``[model]`` settings every target shares).

        Returns
        -------
        dict
            Every boosting key with its value.
        """
        if target in self.chosen:
            return dict(self.chosen[target])
        merged = {**MODEL_DEFAULTS, **_set(self.model)}
        override = _set(self.model.targets[target]) if target in self.model.targets else {}
        for key, params in (("basis", "basis_params"),
                            ("input_transform", "input_transform_params")):
            if key in override and override[key] != merged[key]:
                merged[params] = {}
            merged[params] = {**merged[params], **override.get(params, {})}
        merged.update({k: v for k, v in override.items() if not k.endswith("_params")})
        return merged

    def with_study(self, **updates: Any) -> ExperimentConfig:
        """Return a copy of the config with ``[study]`` values replaced.

        Parameters
        ----------
        **updates
            ``[study]`` keys and their new values (``None`` values ignored).

        Returns
        -------
        ExperimentConfig
            The updated copy.
        """
        updates = {k: v for k, v in updates.items() if v is not None}
        return dataclasses.replace(self, study=self.study.model_copy(update=updates))


def _set(section: BaseModel) -> dict[str, Any]:
    """Return the boosting keys a section sets (``None``: not given)."""
    return {k: v for k, v in section.model_dump(exclude={"family", "targets"}).items()
            if v is not None}


def without_intervals(cfg: ExperimentConfig, off: bool = True) -> ExperimentConfig:
    """``cfg`` with ``[intervals]`` switched off (``--no-intervals``, or a run that needs none).

    Parameters
    ----------
    cfg : ExperimentConfig
        The config.
    off : bool, default=True
        Whether to switch them off (``False``: ``cfg`` unchanged).

    Returns
    -------
    ExperimentConfig
        The config, its ``[intervals] enabled`` false when ``off``.
    """
    if not off:
        return cfg
    return dataclasses.replace(cfg, intervals=cfg.intervals.model_copy(
        update={"enabled": False}))
