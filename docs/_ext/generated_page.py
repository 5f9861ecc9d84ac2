"""What the page-generating extensions share: writing a page and hooking it into a build."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Callable


def write_page(srcdir: str | Path, name: str, text: str) -> Path:
    """Write ``text`` as ``srcdir/reference/<name>`` (only when it changed, so Sphinx does
    not rebuild an unchanged page)."""
    path = Path(srcdir) / "reference" / name
    if not path.is_file() or path.read_text() != text:
        path.write_text(text)
    return path


def connect(app: Any, name: str, render: Callable[[], str]) -> dict[str, Any]:
    """Generate the page ``name`` from ``render()`` at the start of every build."""
    app.connect("builder-inited", lambda app: write_page(app.srcdir, name, render()))
    return {"parallel_read_safe": True, "version": "1"}
