"""Model families: one module each, found through one registry.

A family (:class:`~workbench.experiment.families.base.ModelFamily`) knows how to build its
estimator from a config, what its ``[model.<family>]`` settings and ``[search.<family>]``
space are, what a sweep's study unit is and how a trial is scored, how its result is
assembled, and which extra artifacts and report section it has. Nothing outside a family's
own module looks at a family's name: ``[model] family = "<name>"`` is resolved here.

Today: ``eigenvalue`` (base boosting per target from the control program's eigenvalues) and
``hamiltonian`` (the parameter-space model). A new family is a module with a
:class:`ModelFamily` subclass, added with :func:`register_family`.
"""

from __future__ import annotations

from .base import Artifacts, ModelFamily
from .eigenvalue import EigenvalueFamily
from .hamiltonian import HamiltonianFamily

__all__ = ["FAMILIES", "Artifacts", "ModelFamily", "get_family", "register_family"]

#: Families by name.
FAMILIES: dict[str, ModelFamily] = {}


def register_family(family: ModelFamily) -> ModelFamily:
    """Add ``family`` (an instance) to :data:`FAMILIES` under ``family.name``."""
    if not family.name or not family.name.isidentifier():
        raise ValueError(f"a family needs an identifier as its name, got {family.name!r}")
    if family.name in ("family", "targets"):
        raise ValueError(f"{family.name!r} is a [model] key, not a family name")
    FAMILIES[family.name] = family
    return family


def get_family(name: str) -> ModelFamily:
    """The family called ``name``; an unknown name is an error listing the valid ones."""
    try:
        return FAMILIES[name]
    except KeyError:
        raise ValueError(f"unknown model family {name!r}; valid: {sorted(FAMILIES)}") from None


register_family(EigenvalueFamily())
register_family(HamiltonianFamily())
