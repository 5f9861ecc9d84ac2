"""The base of every config table (:class:`Section`) and its shared field helpers.

Apart from :mod:`~workbench.experiment.config` so that a model family's settings (a section
of their own) build on it without importing the config module, which finds the families.

A section checks structure: types, required and unknown keys, and the values that are the
config's own (paths, names, study settings). A key that is an estimator's parameter is
marked :class:`ParameterOf` and its value is checked against that estimator's
``_parameter_constraints`` by scikit-learn's machinery (:func:`check_values`), at load
time, without data: the config restates no range or choice of its own.
"""

from __future__ import annotations

import typing
from dataclasses import dataclass
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, Field, GetCoreSchemaHandler, model_validator
from pydantic_core import PydanticCustomError, core_schema
from sklearn.utils._param_validation import InvalidParameterError, validate_parameter_constraints

from ..process.errors import shorten, unknown_keys

__all__ = ["MAX_INT", "MAX_MESSAGE", "ParameterOf", "Section", "Seed", "check_values",
           "parameters_of"]

#: The largest seed or count a config may give (numpy seeds are 32-bit).
MAX_INT = 2**32 - 1
#: Most characters of a config error line (with the "workbench: error: " before it: under 300).
MAX_MESSAGE = 280


class Section(BaseModel):
    """A config table: strict types (TOML's), unknown keys an error listing the valid ones.

    A key renamed is an error naming its new name (:attr:`renamed`): an old config fails
    rather than being read differently.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)
    #: Old key -> its new name, for the error an old config gets.
    renamed: ClassVar[dict[str, str]] = {}

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data: Any) -> Any:
        if isinstance(data, dict):
            old = sorted(set(data) & set(cls.renamed))
            if old:
                raise ValueError(f"key {old[0]!r} is now {cls.renamed[old[0]]!r}: rename it")
            unknown = sorted(set(data) - set(cls.model_fields))
            if unknown:
                raise ValueError(unknown_keys(unknown, cls.model_fields))
        return data


def Seed() -> Any:  # noqa: N802  (a field, like pydantic's Field)
    """Declare a seed field: default 0, from 0 to :data:`MAX_INT` (numpy seeds are 32-bit).

    Returns
    -------
    pydantic.fields.FieldInfo
        The field, as ``pydantic.Field`` returns it.
    """
    return Field(default=0, ge=0, le=MAX_INT)


# --------------------------------------------------------------------------- estimator parameters

def check_values(estimator: type, values: dict[str, Any],
                 rename: dict[str, str] | None = None) -> None:
    """Check config values that are parameters of ``estimator`` against its constraints.

    The constraints are those the estimator declares (``_parameter_constraints``, read now),
    checked with scikit-learn's ``validate_parameter_constraints``.

    Parameters
    ----------
    estimator : type
        The estimator class.
    values : dict
        Config key -> value.
    rename : dict, default=None
        Config key -> the parameter's name, where they differ.

    Raises
    ------
    InvalidParameterError
        A value the estimator does not allow (a ``ValueError``), with scikit-learn's message,
        the value shortened.
    TypeError
        A parameter the estimator does not declare: a bug, not a bad config.
    """
    constraints = estimator._parameter_constraints  # type: ignore[attr-defined]
    for key, value in values.items():
        param = (rename or {}).get(key, key)
        if param not in constraints:
            raise TypeError(f"{estimator.__name__} declares no parameter {param!r} (config "
                            f"key {key!r})")
        try:
            validate_parameter_constraints({param: constraints[param]}, {param: value},
                                           caller_name=estimator.__name__)
        except InvalidParameterError as exc:
            text = str(exc)
            if len(repr(value)) > 30:  # scikit-learn quotes the value in full
                text = text.replace(f"Got {value!r} instead.",
                                    f"Got {shorten(value, 30)} instead.")
            raise InvalidParameterError(text) from None


@dataclass(frozen=True)
class ParameterOf:
    """Field metadata: this config key is ``estimator``'s parameter ``name``.

    Its value, once of the field's type, is checked by :func:`check_values`; an invalid one is
    a validation error of type ``"parameter"`` with scikit-learn's message (the config's error
    line then names the file, ``section.key`` and the value). Use it as
    ``Annotated[float, ParameterOf(Estimator)]``; keep the default beside the field.

    Parameters
    ----------
    estimator : type
        The estimator class.
    name : str or None
        The parameter's name (``None``: the config key).
    """

    estimator: type
    name: str | None = None

    def __get_pydantic_core_schema__(self, source: Any,
                                     handler: GetCoreSchemaHandler) -> core_schema.CoreSchema:
        """Add the parameter check after pydantic's own validation of the field."""
        return core_schema.with_info_after_validator_function(self._check, handler(source))

    def _check(self, value: Any, info: core_schema.ValidationInfo) -> Any:
        key = info.field_name or ""
        try:
            check_values(self.estimator, {key: value}, {key: self.name} if self.name else None)
        except InvalidParameterError as exc:
            raise PydanticCustomError("parameter", "{message}", {"message": str(exc)}) from None
        return value


def parameters_of(section: type[BaseModel]) -> dict[str, tuple[type, str]]:
    """Find the keys of ``section`` that are estimator parameters.

    Parameters
    ----------
    section : type of pydantic.BaseModel
        A config table's class.

    Returns
    -------
    dict
        ``{key: (estimator, param)}``.
    """
    def found(annotation: Any, metadata: list) -> ParameterOf | None:
        for meta in metadata:
            if isinstance(meta, ParameterOf):
                return meta
        for arg in typing.get_args(annotation):
            hit = found(arg, list(getattr(arg, "__metadata__", ())))
            if hit is not None:
                return hit
        return None

    out = {}
    for key, field in section.model_fields.items():
        meta = found(field.annotation, list(field.metadata))
        if meta is not None:
            out[key] = (meta.estimator, meta.name or key)
    return out
