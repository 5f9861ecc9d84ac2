"""The one reading of a drift's covariate names: columns, products, differences, geometric means.

A covariate of the parameter-space drift is a *variable* of the data's columns, optionally
raised to a power: a column ``"x"``, a product ``"a*b"``, a difference ``"a-b"`` or a
geometric mean ``"sqrt|a*b|"`` of two columns, then ``"^k"``. The regressors
(:mod:`workbench.parametric_boost`), the linearised selection (:mod:`workbench.param_linear`)
and the drift figures read the names here.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd


def variable(name: str, columns: set[str]) -> tuple[str, ...] | None:
    """A variable: a column ``(c,)``, a product ``("*", a, b)``, a difference
    ``("-", a, b)`` or a geometric mean ``("gm", a, b)`` (``"sqrt|a*b|"``) of two columns;
    None if ``name`` is none of these."""
    if name in columns:
        return (name,)
    if name.startswith("sqrt|") and name.endswith("|"):
        inner = variable(name[5:-1], columns)
        return ("gm", *inner[1:]) if inner is not None and inner[0] == "*" else None
    for op in ("*", "-"):
        for k, char in enumerate(name):
            if char == op and name[:k] in columns and name[k + 1:] in columns:
                return (op, name[:k], name[k + 1:])
    return None


def term(name: str, columns: set[str]) -> tuple[str, int]:
    """Covariate name -> (variable, power): ``"x"``, ``"x^2"``, ``"a*b"``, ``"a-b^2"``."""
    if variable(name, columns):
        return name, 1
    base, sep, power = name.rpartition("^")
    if sep and variable(base, columns) and power.isdigit() and int(power) >= 1:
        return base, int(power)
    raise ValueError(f"unknown covariate {name!r}: a covariate is a column of X, a product "
                     "'a*b', a difference 'a-b' or a geometric mean 'sqrt|a*b|' of two "
                     f"columns, optionally followed by '^k'; X's columns are {sorted(columns)}")


def column(X: pd.DataFrame, name: str) -> np.ndarray:
    """The column ``name`` of ``X`` as floats (a frame's columns by name, read as str)."""
    key: Any = name
    if name not in X.columns:
        key = {str(c): c for c in X.columns}[name]
    return pd.to_numeric(X[key], errors="coerce").to_numpy(dtype=float)


def float_block(X: pd.DataFrame, names: list[str]) -> np.ndarray:
    """The columns ``names`` of ``X`` (by name, read as str) as one float array, converted
    at once; raises ``KeyError`` for a missing one, ``TypeError`` or ``ValueError`` where
    one is not numeric."""
    position = {str(c): i for i, c in enumerate(X.columns)}
    index = [position[n] for n in names]
    try:  # an all-numeric frame converts as one block (the fits read it thousands of times)
        return X.to_numpy(dtype=float)[:, index]
    except (TypeError, ValueError):
        return X.iloc[:, index].to_numpy(dtype=float)


def columns(X: pd.DataFrame, names: list[str]) -> dict[str, np.ndarray]:
    """The columns ``names`` of ``X`` as floats, each as :func:`column` reads it (a value
    that is not a number is NaN), in one block where they convert at once."""
    try:
        block = float_block(X, names)
    except (TypeError, ValueError):
        return {n: column(X, n) for n in names}
    return {n: block[:, j] for j, n in enumerate(names)}

