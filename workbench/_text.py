"""The one shortening of long text in messages: the core's and the experiment layer's.

:func:`clip` cuts a name or a message to a length, ending in ``...``; the core's data readers
(:mod:`workbench.datasets.csv`) and the experiment layer's errors
(:mod:`workbench.experiment.process.errors`, which the core cannot import) both use it.
"""

from __future__ import annotations

__all__ = ["clip"]


def clip(text: str, limit: int) -> str:
    """Cut ``text`` to at most ``limit`` characters, ending in ``...`` when cut.

    Parameters
    ----------
    text : str
        The text to shorten.
    limit : int
        The longest result, ``...`` included (at least 3).

    Returns
    -------
    str
        ``text`` itself if it fits, else its first ``limit - 3`` characters and ``...``.

    Examples
    --------
    >>> clip("abcdefgh", 6)
    'abc...'
    >>> clip("abc", 6)
    'abc'
    """
    return text if len(text) <= limit else text[:limit - 3] + "..."
