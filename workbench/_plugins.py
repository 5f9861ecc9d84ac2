"""The one way plug-ins are found: entry-point groups, loaded on first need.

Bases (:data:`workbench.bases.BASES`), data sources (:data:`workbench.datasets.SOURCES`) and
model families (:data:`workbench.experiment.families.FAMILIES`) are registries of the same
shape: a dict by name, one ``register_*`` function, and an entry-point group
(``workbench.bases``, ``workbench.sources``, ``workbench.families``) through which another
package adds to it without being imported by hand. Each registry's ``discover_*`` passes its
group's entry points to :func:`load_entry_points`, which loads each once and reports a broken
one in one warning line naming it; the others still load.
"""

from __future__ import annotations

import importlib.metadata
import logging
from collections.abc import Callable
from typing import Any

__all__ = ["load_entry_points"]

log = logging.getLogger("workbench")


def load_entry_points(group: str, register: Callable[[str, Any], str],
                      seen: set[str]) -> list[str]:
    """Register the entry points of ``group`` not loaded before, each once.

    Parameters
    ----------
    group : str
        The entry-point group, e.g. ``"workbench.bases"``.
    register : callable
        ``register(entry_name, loaded_object) -> registered_name``; it raises for an object
        of the wrong kind.
    seen : set of str
        The entry points (``module:attr`` values) loaded before, updated in place: a plug-in
        is loaded, or reported broken, once per process.

    Returns
    -------
    list of str
        The names registered by this call.
    """
    added = []
    for entry in importlib.metadata.entry_points(group=group):
        if entry.value in seen:
            continue
        seen.add(entry.value)
        try:
            added.append(register(entry.name, entry.load()))
        except Exception as exc:  # a broken plug-in: reported, the others still load
            log.warning("%s plug-in %r (%s) not loaded: %s: %s", group, entry.name,
                        entry.value, type(exc).__name__, exc)
    return added
