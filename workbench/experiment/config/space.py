"""Search spaces from a config's ``[search]`` table.

Each entry is a choice list (categorical), a range table ``{ low, high, log?, step? }`` (int
when both ends are ints, else float) or a plain value (fixed). Basis hyperparameters are
conditional: ``[search.basis_params.<basis>]`` is sampled only in trials that pick that basis,
as parameters named ``<basis>.<name>``. ``[search.<family>]`` varies the model family's own
``[model.<family>]`` settings, as parameters named ``<family>.<key>``. Sampling goes through
any object with Optuna's ``suggest_categorical``/``suggest_int``/``suggest_float`` (an Optuna
trial, or ``optuna.trial.FixedTrial`` to rebuild the settings of a finished trial).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable

import numpy as np
from sklearn.utils._param_validation import InvalidParameterError

from ...bases import BASES, TRANSFORMS, basis_names
from ...boosting import BaseBoostRegressor
from ...losses import LOSSES
from ..process.errors import shorten, unknown_keys
from .schema import check_values

if TYPE_CHECKING:  # Optuna and pydantic types only: nothing imported when the module runs
    from optuna.trial import Trial
    from pydantic import BaseModel

__all__ = ["SearchSpace", "SpaceError", "check_ranges", "draw_params", "has_ranges"]

#: The model settings a search may vary, with the valid values of the categorical ones (read
#: when a space is checked: bases added by plug-ins count).
NAMED_CHOICES: dict[str, Callable[[], tuple[str, ...]]] = {
    "basis": lambda: tuple(basis_names()),
    "loss": lambda: tuple(LOSSES),
    "line_search_loss": lambda: tuple(LOSSES),
    "input_transform": lambda: ("none", *TRANSFORMS),
    "basis_inputs": lambda: ("prior", "prior+features"),
}
#: BaseBoostRegressor's numeric parameters a search may vary: each value a search can take
#: (a choice, a range's ends) is checked against its ``_parameter_constraints``.
NUMERIC = ("n_stages", "line_search_penalty", "alpha")
SEARCH_KEYS = {*NAMED_CHOICES, *NUMERIC, "basis_params"}


class SpaceError(ValueError):
    """A search space that cannot be sampled; the message names the entry."""


def _check_spec(name: str, spec: Any, valid: tuple[str, ...] | None = None) -> None:
    if isinstance(spec, list):
        if not spec:
            raise SpaceError(f"{name}: empty choice list")
        if any(isinstance(v, (list, dict)) for v in spec):
            raise SpaceError(f"{name}: choices must be plain values, got {spec!r}")
        values = spec
    elif isinstance(spec, dict):
        unknown = sorted(set(spec) - {"low", "high", "log", "step"})
        if unknown or not {"low", "high"} <= set(spec):
            raise SpaceError(f"{name}: a range needs low and high (and optionally log, step); "
                             f"got keys {sorted(spec)}")
        if not spec["low"] <= spec["high"]:
            raise SpaceError(f"{name}: low {spec['low']!r} is above high {spec['high']!r}")
        if spec.get("log") and spec["low"] <= 0:
            raise SpaceError(f"{name}: a log range needs low > 0, got {spec['low']!r}")
        values = []
    else:
        values = [spec]
    if valid is not None:
        bad = [v for v in values if v not in valid]
        if bad or isinstance(spec, dict):
            raise SpaceError(f"{name}: unknown value(s) {bad or spec!r}; valid: {list(valid)}")


def _suggest(trial: Trial | _Draw, name: str, spec: Any) -> Any:
    if isinstance(spec, list):
        return trial.suggest_categorical(name, spec)
    if isinstance(spec, dict):
        low, high, log = spec["low"], spec["high"], bool(spec.get("log", False))
        if (isinstance(low, int) and isinstance(high, int)
                and not isinstance(spec.get("step"), float)):
            return trial.suggest_int(name, low, high, log=log, step=spec.get("step", 1))
        return trial.suggest_float(name, float(low), float(high), log=log, step=spec.get("step"))
    return spec


@dataclass(frozen=True)
class SearchSpace:
    """The ``[search]`` table, checked.

    Parameters
    ----------
    table : dict
        The entries that vary the boosting settings (``basis_params`` included).
    family : str or None
        The model family whose settings ``family_table`` varies.
    family_table : dict
        ``[search.<family>]``: the family's own settings, as parameters named
        ``<family>.<key>``.
    """

    table: dict[str, Any] = field(default_factory=dict)
    family: str | None = None
    family_table: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_table(cls, table: dict[str, Any], family: str | None = None,
                   check: Callable[[str, Any], None] | None = None) -> SearchSpace:
        """Check a ``[search]`` table and build its space.

        Parameters
        ----------
        table : dict
            The ``[search]`` table.
        family : str, default=None
            The model family whose settings ``[search.<family>]`` may vary (``None``: it has none,
            so such a table is an error).
        check : callable, default=None
            ``check(key, value)`` raises :class:`SpaceError` for a value the family's settings do
            not allow.

        Returns
        -------
        SearchSpace
            The checked space.

        Raises
        ------
        SpaceError
            An entry that cannot be sampled; the message names it.
        """
        if not isinstance(table, dict):
            raise SpaceError(f"[search] must be a table, got {table!r}")
        table = dict(table)
        sub = table.pop(family, None) if family else None
        valid_keys = SEARCH_KEYS | ({family} if family else set())
        unknown = sorted(set(table) - SEARCH_KEYS)
        if unknown:
            raise SpaceError(unknown_keys(unknown, valid_keys))
        for name, spec in table.items():
            if name != "basis_params":
                choices = NAMED_CHOICES.get(name)
                _check_spec(name, spec, choices() if choices else None)
            if name in NUMERIC:
                for value in _values(spec):
                    try:
                        check_values(BaseBoostRegressor, {name: value})
                    except InvalidParameterError as exc:
                        raise SpaceError(f"{name} = {shorten(value)}: {exc}") from None
        params = table.get("basis_params", {})
        if not isinstance(params, dict):
            raise SpaceError(f"basis_params must be a table of tables, got {params!r}")
        for basis, specs in params.items():
            if basis not in BASES and basis not in basis_names():  # plug-ins: on a miss
                raise SpaceError(f"basis_params.{basis}: unknown basis; valid: {sorted(BASES)}")
            if not isinstance(specs, dict):
                raise SpaceError(f"basis_params.{basis} must be a table, got {specs!r}")
            for pname, spec in specs.items():
                _check_spec(f"basis_params.{basis}.{pname}", spec)
        sub = {} if sub is None else sub
        if not isinstance(sub, dict):
            raise SpaceError(f"{family} must be a table, got {sub!r}")
        for name, spec in sub.items():
            _check_spec(f"{family}.{name}", spec)
            if isinstance(spec, dict) and not all(
                    isinstance(spec[end], (int, float)) and not isinstance(spec[end], bool)
                    for end in ("low", "high")):
                raise SpaceError(f"{family}.{name}: a range needs numbers, got {spec!r}")
            for value in _values(spec):
                if check is not None:
                    check(name, value)
        return cls(table=table, family=family, family_table=dict(sub))

    def sample(self, trial: Trial, base: dict[str, Any]) -> dict[str, Any]:
        """Sample a target's model settings for ``trial``.

        Parameters
        ----------
        trial : optuna.trial.Trial
            Or anything with Optuna's ``suggest_*`` methods (``FixedTrial``).
        base : dict
            A target's ``[model]`` settings.

        Returns
        -------
        dict
            ``base`` with the searched entries replaced by the trial's values.
        """
        settings = dict(base)
        for name, spec in self.table.items():
            if name != "basis_params":
                settings[name] = _suggest(trial, name, spec)
        if settings["input_transform"] != base["input_transform"]:
            settings["input_transform_params"] = {}
        specs = self.table.get("basis_params", {}).get(settings["basis"])
        if settings["basis"] != base["basis"]:
            settings["basis_params"] = {}
        if specs:
            settings["basis_params"] = {
                **settings["basis_params"],
                **{k: _suggest(trial, f"{settings['basis']}.{k}", v) for k, v in specs.items()}}
        return settings

    def sample_family(self, trial: Trial, base: BaseModel) -> BaseModel:
        """Sample the family's own settings for ``trial``.

        Parameters
        ----------
        trial : optuna.trial.Trial
            Or anything with Optuna's ``suggest_*`` methods.
        base : pydantic.BaseModel
            The family's settings.

        Returns
        -------
        pydantic.BaseModel
            ``base`` with the entries of ``[search.<family>]`` replaced by the trial's values
            (``<family>.<key>``).
        """
        if not self.family_table:
            return base
        values = {name: _suggest(trial, f"{self.family}.{name}", spec)
                  for name, spec in self.family_table.items()}
        return type(base).model_validate({**base.model_dump(), **values})


def _values(spec: Any) -> list[Any]:
    """List the values of a spec to check: every choice, a range's ends, or the fixed value."""
    if isinstance(spec, list):
        return list(spec)
    if isinstance(spec, dict):
        return [spec["low"], spec["high"]]
    return [spec]


# --------------------------------------------------------------------------- random draws
class _Draw:
    """Answer Optuna's ``suggest_*`` by independent draws of a seeded numpy Generator.

    Uniform, or log-uniform for ``log`` ranges; on the ``step`` grid when given.
    """

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng

    def suggest_categorical(self, name: str, choices: list[Any]) -> Any:
        return choices[int(self.rng.integers(len(choices)))]

    def _uniform(self, low: float, high: float, log: bool) -> float:
        if log:
            return math.exp(self.rng.uniform(math.log(low), math.log(high)))
        return float(self.rng.uniform(low, high))

    def suggest_int(self, name: str, low: int, high: int, log: bool = False,
                    step: int = 1) -> int:
        if log:
            return min(high, max(low, round(self._uniform(low, high, True))))
        return low + step * int(self.rng.integers((high - low) // step + 1))

    def suggest_float(self, name: str, low: float, high: float, log: bool = False,
                      step: float | None = None) -> float:
        if step:
            return low + step * int(self.rng.integers(int(round((high - low) / step)) + 1))
        return self._uniform(low, high, log)


def has_ranges(params: dict[str, Any]) -> bool:
    """Tell whether a basis's ``basis_params`` hold a table to draw from.

    Parameters
    ----------
    params : dict
        The basis's ``basis_params``.

    Returns
    -------
    bool
        Whether some entry is a range (``{ low, high, log? }``) or a choice
        (``{ choices = [...] }``; a plain list is a value).
    """
    return any(isinstance(v, dict) for v in params.values())


def _spec(spec: dict[str, Any]) -> Any:
    """Read a drawn entry as a search-space spec: ``{ choices = [...] }`` is a choice list."""
    return spec["choices"] if set(spec) == {"choices"} else spec


def check_ranges(name: str, params: dict[str, Any]) -> list[dict[str, Any]]:
    """Check the tables to draw from of ``basis_params.<name>``.

    Parameters
    ----------
    name : str
        The basis.
    params : dict
        Its ``basis_params``.

    Returns
    -------
    list of dict
        The settings to validate against the basis: every range at its low end, and at its
        high end (choices: each).

    Raises
    ------
    SpaceError
        A table that cannot be drawn from.
    """
    width = 2
    for key, spec in params.items():
        if isinstance(spec, dict):
            _check_spec(f"basis_params.{name}.{key}", _spec(spec))
            if isinstance(_spec(spec), list):
                width = max(width, len(spec["choices"]))

    def at(spec: Any, i: int) -> Any:
        if not isinstance(spec, dict):
            return spec
        values = _values(_spec(spec))
        return values[min(i, len(values) - 1)]
    return [{k: at(v, i) for k, v in params.items()} for i in range(width)]


def draw_params(params: dict[str, Any], n: int, seed: int | None) -> list[dict[str, Any]]:
    """Draw ``n`` settings of a basis whose ``basis_params`` hold tables to draw from.

    Each range is drawn at random (uniform, or log-uniform), each choice uniformly, fixed
    values kept. The same seed gives the same draws.

    Parameters
    ----------
    params : dict
        The basis's ``basis_params``.
    n : int
        Settings to draw.
    seed : int or None
        Seed of the draws.

    Returns
    -------
    list of dict
        The drawn settings.
    """
    draw = _Draw(np.random.default_rng(seed))
    return [{k: (_suggest(draw, k, _spec(v)) if isinstance(v, dict) else v)
             for k, v in params.items()} for _ in range(n)]
