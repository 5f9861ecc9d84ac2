"""Types of the command line's values.

Each parses one string or raises ``argparse.ArgumentTypeError`` with what was expected and
what was given (shortened).
"""

from __future__ import annotations

import argparse
from typing import Any

__all__ = ["Renamed", "count", "fraction", "nested_folds", "override", "random_states",
           "seconds", "seed"]

#: Most seeds ``--random-states`` takes (each is one more fit of the whole model).
MAX_SEEDS = 1000


def count(value: str) -> int:
    """Parse a count: an integer >= 1.

    Parameters
    ----------
    value : str
        The command-line text.

    Returns
    -------
    int
        The count.

    Raises
    ------
    argparse.ArgumentTypeError
        For anything else.
    """
    try:
        number = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {value[:40]!r}") from None
    if number < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {number}")
    return number


def fraction(value: str) -> float:
    """``--test-fraction``: a number strictly between 0 and 1.

    Parameters
    ----------
    value : str
        The command-line text.

    Returns
    -------
    float
        The fraction.

    Raises
    ------
    argparse.ArgumentTypeError
        For anything else.
    """
    try:
        number = float(value)
    except ValueError:
        number = float("nan")
    if not 0.0 < number < 1.0:
        raise argparse.ArgumentTypeError(f"expected a number between 0 and 1 (exclusive), got "
                                         f"{value[:40]!r}")
    return number


def seconds(value: str) -> float:
    """``--timeout``: a number of seconds > 0.

    Parameters
    ----------
    value : str
        The command-line text.

    Returns
    -------
    float
        The seconds.

    Raises
    ------
    argparse.ArgumentTypeError
        For anything else.
    """
    try:
        number = float(value)
    except ValueError:
        number = float("nan")
    if not 0.0 < number < float("inf"):
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0, got {value[:40]!r}")
    return number


def seed(value: str) -> int:
    """``--split-seed``, ``reproduce --random-state``, ``simulate --device-seed``: an integer >= 0.

    Parameters
    ----------
    value : str
        The command-line text.

    Returns
    -------
    int
        The seed.

    Raises
    ------
    argparse.ArgumentTypeError
        For anything else.
    """
    try:
        number = int(value)
    except ValueError:
        number = -1
    if number < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {value[:40]!r}")
    return number


class Renamed(argparse.Action):
    """An option renamed: giving it is an error naming its new name (a hidden option).

    Parameters
    ----------
    option_strings : list of str
        The old option.
    dest : str
        Unused (nothing is stored).
    new : str
        The new option's name.
    **kwargs
        argparse's other arguments of an action.
    """

    def __init__(self, option_strings: list[str], dest: str, *, new: str, **kwargs: Any):
        self.new = new
        super().__init__(option_strings, dest, nargs="?", default=argparse.SUPPRESS,
                         help=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace,
                 values: Any, option_string: str | None = None) -> None:
        """Fail with the new name."""
        parser.error(f"{option_string} is now {self.new}")


def random_states(value: str) -> list[int]:
    """``--random-states``: two or more distinct seeds, ``A-B`` (``A`` to ``B``), ``A,B,C`` or both.

    E.g. ``0-4`` is 0, 1, 2, 3, 4 and ``0,3,7-9`` is 0, 3, 7, 8, 9.

    Parameters
    ----------
    value : str
        The command-line text.

    Returns
    -------
    list of int
        The seeds, in the order given.

    Raises
    ------
    argparse.ArgumentTypeError
        For anything else: an empty item, a range that runs backwards, a negative or
        non-integer seed, a seed given twice, fewer than two or more than :data:`MAX_SEEDS`.
    """
    from ..config.schema import MAX_INT  # numpy's seeds are 32-bit

    shown = repr(value[:40])
    out: list[int] = []
    for item in value.split(","):
        low, dash, high = item.strip().partition("-")
        try:
            first, last = int(low), int(high if dash else low)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected seeds as A-B or A,B,C (integers >= 0, e.g. 0-4 or 0,3,7), got "
                f"{shown}") from None
        if first < 0 or last < first or last > MAX_INT:
            raise argparse.ArgumentTypeError(f"expected seeds A-B with 0 <= A <= B <= "
                                             f"{MAX_INT}, got {item.strip()[:40]!r} in {shown}")
        if last - first >= MAX_SEEDS or len(out) + last - first >= MAX_SEEDS:
            raise argparse.ArgumentTypeError(f"at most {MAX_SEEDS} seeds, got more in {shown}")
        out.extend(range(first, last + 1))
    if len(set(out)) != len(out):
        raise argparse.ArgumentTypeError(f"a seed given twice in {shown}")
    if len(out) < 2:
        raise argparse.ArgumentTypeError(f"expected two or more seeds to compare, got {shown} "
                                         "(one seed: --set random_state=N)")
    return out


def nested_folds(value: str) -> int:
    """``--nested``: 0 (none) or a number of outer folds >= 2.

    Parameters
    ----------
    value : str
        The command-line text.

    Returns
    -------
    int
        The number of folds.

    Raises
    ------
    argparse.ArgumentTypeError
        For anything else.
    """
    try:
        number = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected 0 or an integer >= 2, got "
                                         f"{value[:40]!r}") from None
    if number < 0 or number == 1:
        raise argparse.ArgumentTypeError(f"expected 0 (none) or an integer >= 2 outer folds, "
                                         f"got {number}")
    return number


def override(value: str) -> tuple[str, Any]:
    """Parse a ``--set SECTION.KEY=VALUE`` override (the value read as TOML).

    Parameters
    ----------
    value : str
        The command-line text.

    Returns
    -------
    tuple of (str, object)
        The dotted key and its value (:func:`workbench.experiment.config.overrides.parse_override`).

    Raises
    ------
    argparse.ArgumentTypeError
        For text that is not ``SECTION.KEY=VALUE``.
    """
    from ..config.overrides import parse_override
    from ..process.errors import ConfigError

    try:
        return parse_override(value)
    except ConfigError as exc:
        # argparse names the option itself: "argument --set: 'x': give ..."
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--set ")) from None
