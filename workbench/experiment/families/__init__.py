"""Model families: one module each, found through one registry.

A family (:class:`~workbench.experiment.families.base.ModelFamily`) knows how to build its
estimator from a config, what its ``[model.<family>]`` settings and ``[search.<family>]``
space are, what a sweep's study block is and how a trial is scored, how its result is
assembled, and which extra artifacts it has. Nothing outside a family's own module looks at
a family's name: ``[model] family = "<name>"`` is resolved here.

Built in: ``eigenvalue`` (base boosting per target from the control program's eigenvalues),
``hamiltonian`` (the parameter-space model) and ``parametric`` (a user's model file,
corrected in its own parameter space). A new family is a module with a
:class:`ModelFamily` subclass, added with :func:`register_family` or, from another package,
through an entry point of the group :data:`FAMILY_ENTRY_POINT_GROUP` (MLflow's plug-in
convention; bases and data sources are added the same way, :mod:`workbench._plugins`)::

    [project.entry-points."workbench.families"]
    my_family = "my_package.family:MyFamily"

May import: process, config, splits, scoring, figures (a family module imports no other
family).
"""

from __future__ import annotations

from ..._plugins import load_entry_points
from .artifacts import Artifacts
from .base import ModelFamily
from .eigenvalue import EigenvalueFamily
from .hamiltonian import HamiltonianFamily
from .parametric import ParametricFamily

__all__ = ["FAMILIES", "FAMILY_ENTRY_POINT_GROUP", "Artifacts", "ModelFamily", "discover_families",
           "register_family"]

#: Families by name.
FAMILIES: dict[str, ModelFamily] = {}

#: The entry-point group other packages add families through.
FAMILY_ENTRY_POINT_GROUP = "workbench.families"

_discovered: set[str] = set()


def register_family(family: ModelFamily) -> ModelFamily:
    """Add ``family`` (an instance) to :data:`FAMILIES` under ``family.name``.

    Parameters
    ----------
    family : ModelFamily
        The family.

    Returns
    -------
    ModelFamily
        ``family``.

    Raises
    ------
    ValueError
        For a name that is not an identifier or is a ``[model]`` key.
    """
    if not family.name or not family.name.isidentifier():
        raise ValueError(f"a family needs an identifier as its name, got {family.name!r}")
    if family.name in ("family", "targets"):
        raise ValueError(f"{family.name!r} is a [model] key, not a family name")
    FAMILIES[family.name] = family
    return family


def discover_families() -> list[str]:
    """Register the families other packages declare as entry points, each once.

    The entry point group is :data:`FAMILY_ENTRY_POINT_GROUP`.

    An entry point names a :class:`ModelFamily` subclass (instantiated without arguments)
    or an instance, registered under the family's own ``name``. One that cannot be loaded
    is reported in one warning line naming it and left out: a broken plug-in does not stop
    the built-in families.

    Returns
    -------
    list of str
        The names of the families registered by this call.
    """
    def register(entry_name: str, found: object) -> str:
        family = found() if isinstance(found, type) else found
        if not isinstance(family, ModelFamily):
            raise TypeError(f"{found!r} is not a ModelFamily")
        return register_family(family).name

    return load_entry_points(FAMILY_ENTRY_POINT_GROUP, register, _discovered)


register_family(EigenvalueFamily())
register_family(HamiltonianFamily())
register_family(ParametricFamily())
