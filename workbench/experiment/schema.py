"""The base of every config table (:class:`Section`) and its shared field helpers, apart
from :mod:`~workbench.experiment.config` so that a model family's settings (a section of
their own) build on it without importing the config module, which finds the families."""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_validator

from .errors import unknown_keys

__all__ = ["MAX_INT", "MAX_MESSAGE", "Section", "Seed"]

#: The largest seed or count a config may give (numpy seeds are 32-bit).
MAX_INT = 2**32 - 1
#: Most characters of a config error line (``workbench: error: `` before it: under 300).
MAX_MESSAGE = 280


class Section(BaseModel):
    """A config table: strict types (TOML's), unknown keys an error listing the valid ones."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data: Any) -> Any:
        if isinstance(data, dict):
            unknown = sorted(set(data) - set(cls.model_fields))
            if unknown:
                raise ValueError(unknown_keys(unknown, cls.model_fields))
        return data


def Seed():  # noqa: N802  (a field, like pydantic's Field)
    return Field(default=0, ge=0, le=MAX_INT)
