"""Move the loose modules of ``workbench/experiment/`` into their homes, and every import.

Re-runnable and idempotent: run it from the repository's root, on any checkout (a branch
merged after the move included)::

    python tools/move_homes.py            # move, rewrite, sort the rewritten imports
    python tools/move_homes.py --dry-run  # print what it would move and rewrite

What it does, each step skipped where it is already done:

1. ``git mv`` each module of :data:`MOVES` to its home (a home's ``__init__.py`` is written,
   with its docstring, when missing);
2. in every Python file under ``workbench/``, rewrites each relative import whose target
   moved, and each relative import of a moved file whose target is now elsewhere relative to
   it (an import written for a file's old place, e.g. by a branch merged after the move, is
   read from that place);
3. in every text file of the project (Python, Markdown, TOML, the Makefile, ...; not
   ``CHANGES.md``, which is history), rewrites the dotted names ``workbench.experiment.<old>``
   and the paths ``workbench/experiment/<old>.py``; ``from workbench.experiment import <old>``
   becomes ``from workbench.experiment.<home> import <old>``;
4. sorts the imports of the files it changed (``ruff check --select I --fix``) and prints
   their lines over 100 characters (a longer dotted name in a docstring), to wrap by hand.

No re-export is left behind: an old import path fails after the move.
"""

from __future__ import annotations

import argparse
import ast
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXP = "workbench.experiment"

#: Old dotted name (below ``workbench.experiment``) -> new one. A package moves whole.
MOVES: dict[str, str] = {
    # process/: what every command's process has (the bottom of the layer)
    "errors": "process.errors",
    "signals": "process.signals",
    "startup": "process.startup",
    "outputs": "process.outputs",
    # config/: the config's text, schema and search space
    "schema": "config.schema",
    "space": "config.space",
    "overrides": "config.overrides",
    "toml_text": "config.toml_text",
    # splits/: the rows' structure (the columns that group and order them, the folds that follow)
    "columns": "splits.columns",
    "folds": "splits.folds",
    # scoring/: what is measured of a fitted model
    "scores": "scoring.scores",
    "results": "scoring.results",
    "bootstrap": "scoring.bootstrap",
    "units": "scoring.units",
    "explain": "scoring.explain",
    # runs/: a command's work on a config, whatever the family
    "prepare": "runs.prepare",
    "init": "runs.init",
    "evaluate": "runs.evaluate",
    "seeds": "runs.seeds",
    "intervals": "runs.intervals",
    "run_outputs": "runs.run_outputs",
    "run_fields": "runs.run_fields",
    "record": "runs.record",
    "design": "runs.design",
    # tracking/: the only home importing MLflow
    "lifecycle": "tracking.lifecycle",
    "serving": "tracking.serving",
    "predict": "tracking.predict",
    "compare": "tracking.compare",
    # storage/: the only home touching Optuna's storages and private names
    "sweep.storage": "storage",
}

#: The docstring of each new home's ``__init__.py`` (written only when the file is missing).
HOMES: dict[str, str] = {
    "process": '''"""What every command's process has: the bottom of the experiment layer.

* :mod:`.errors` -- the errors reported as one line (``ConfigError``, ``UsageError``,
  ``StorageError``, ``TrackingError``, ``SweepTimedOut``) and the helpers that shorten,
  list and redact what they say;
* :mod:`.startup` -- what a command sets up first: its progress logging;
* :mod:`.signals` -- SIGINT and SIGTERM: one line, runs ended ``KILLED``;
* :mod:`.outputs` -- the files a command writes, checked before work, written all or nothing.

May import: nothing of the experiment layer (the core and the standard library only).
"""
''',
    "splits": '''"""How the rows are split: the columns that group and order them, and the CV folds.

* :mod:`.columns` -- what ``workbench init`` reads off a CSV's columns (the features, the
  columns that group the rows, the column that orders them in time);
* :mod:`.folds` -- every CV fold of a command, following the rows' groups or order.

May import: process, config.
"""
''',
    "scoring": '''"""What is measured of a fitted model, and how it is written.

* :mod:`.scores` -- the score records (``Scores``, ``ModelScores``, ``CVEstimate``) and the
  per-target errors;
* :mod:`.results` -- the result dataclasses (``Result.to_json`` is what ``--json`` writes);
* :mod:`.bootstrap` -- bootstrap intervals of the test errors over the test rows;
* :mod:`.units` -- a unit beside a number;
* :mod:`.explain` -- SHAP values of a model's predictions.

May import: nothing of the experiment layer.
"""
''',
    "runs": '''"""A command's work on a config, whatever the model family.

* :mod:`.prepare` -- reading a config file (the family resolved) and the prepared run;
* :mod:`.init` -- ``workbench init``, a first config for a CSV;
* :mod:`.evaluate` -- fit and score once, repeated and nested CV; :mod:`.seeds` the same per
  seed; :mod:`.intervals` the conformal intervals around every family's model;
* :mod:`.run_outputs` -- a run's figures, tables and predictions, computed once;
  :mod:`.run_fields` what every MLflow run carries; :mod:`.record` what an evaluate or
  sweep logs, computing nothing;
* :mod:`.design` -- ``workbench design``, which settings to measure next.

May import: process, config, splits, scoring, figures, families, tracking.
"""
''',
}

TEXT_SUFFIXES = {".py", ".md", ".toml", ".txt", ".cfg", ".ini", ".yml", ".yaml", ".rst",
                 ".sh"}
TEXT_NAMES = {"Makefile"}
SKIP_DIRS = {".git", ".venv", "mlruns", "node_modules", "__pycache__", "_build", ".mypy_cache",
             ".ruff_cache", ".pytest_cache", "reports"}
SKIP_FILES = {"CHANGES.md", "tools/move_homes.py"}


def _path(dotted: str) -> Path:
    """The file or package directory of a module below ``workbench.experiment``."""
    base = ROOT / "workbench" / "experiment" / Path(*dotted.split("."))
    return base if base.is_dir() else base.with_suffix(".py")


def _exists(module: str) -> bool:
    """Whether ``module`` (absolute, dotted) is a module or package of the tree now."""
    base = ROOT / Path(*module.split("."))
    return base.with_suffix(".py").is_file() or (base / "__init__.py").is_file()


def _mapped(module: str) -> str | None:
    """The new name of ``module`` (absolute), or None when it did not move."""
    for old in sorted(MOVES, key=len, reverse=True):
        full = f"{EXP}.{old}"
        if module == full or module.startswith(full + "."):
            return f"{EXP}.{MOVES[old]}{module[len(full):]}"
    return None


def _unmapped(module: str) -> str | None:
    """The old name of a moved module (absolute), or None."""
    for old, new in sorted(MOVES.items(), key=lambda kv: len(kv[1]), reverse=True):
        full = f"{EXP}.{new}"
        if module == full or module.startswith(full + "."):
            return f"{EXP}.{old}{module[len(full):]}"
    return None


def move(dry: bool) -> list[str]:
    """``git mv`` the modules and write the new homes' ``__init__``; return what moved."""
    done = []
    for home, doc in HOMES.items():
        init = ROOT / "workbench" / "experiment" / home / "__init__.py"
        if not init.exists():
            done.append(f"create {init.relative_to(ROOT)}")
            if not dry:
                init.parent.mkdir(parents=True, exist_ok=True)
                init.write_text(doc)
                subprocess.run(["git", "add", str(init)], cwd=ROOT, check=True)
    for old, new in MOVES.items():
        src, dst = _path(old), _path(new)
        if src.is_dir():
            dst = dst.with_suffix("")
        if not src.exists():
            continue
        if dst.exists() and not src.is_dir():
            sys.exit(f"both {src} and {dst} exist: merge them by hand, then run again")
        done.append(f"git mv {src.relative_to(ROOT)} {dst.relative_to(ROOT)}")
        if not dry:
            dst.parent.mkdir(parents=True, exist_ok=True)
            if src.is_dir() and dst.exists():  # a branch added files to the old package
                for f in sorted(src.rglob("*.py")):
                    target = dst / f.relative_to(src)
                    if target.exists():
                        sys.exit(f"both {f} and {target} exist: merge them by hand")
                    subprocess.run(["git", "mv", str(f), str(target)], cwd=ROOT, check=True)
            else:
                subprocess.run(["git", "mv", str(src), str(dst)], cwd=ROOT, check=True)
    return done


def _module_of(path: Path) -> tuple[str, bool]:
    """The dotted name of ``path`` and whether it is a package's ``__init__``."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    is_init = parts[-1] == "__init__"
    return ".".join(parts[:-1] if is_init else parts), is_init


def _resolve(package: str, level: int, module: str | None) -> str:
    base = package.split(".")
    base = base[:len(base) - (level - 1)]
    return ".".join(base + ([module] if module else []))


def _relative(package: str, target: str) -> tuple[int, str]:
    """``target`` as a relative import from ``package``: (level, module)."""
    here, there = package.split("."), target.split(".")
    common = 0
    while common < min(len(here), len(there)) and here[common] == there[common]:
        common += 1
    return len(here) - common + 1, ".".join(there[common:])


def _new_target(package: str, old_package: str | None, level: int,
                module: str | None) -> str | None:
    """The absolute module a relative import should name now, or None if unchanged.

    In a moved file an import that names an existing module from the file's new place was
    written for it (a rewritten one); else it was written for the file's old place.
    """
    target = _resolve(package, level, module)
    if old_package is None:
        return _mapped(target)
    if _exists(target):
        return None
    old_target = _resolve(old_package, level, module)
    new = _mapped(old_target)
    if new is not None:
        return new
    return old_target if _exists(old_target) else _mapped(target)


def _render(node: ast.ImportFrom, level: int, module: str, names: list[ast.alias]) -> str:
    listed = ", ".join(a.name + (f" as {a.asname}" if a.asname else "") for a in names)
    return f"from {'.' * level}{module} import {listed}"


def rewrite_imports(path: Path) -> bool:
    """Rewrite the relative imports of one Python file under ``workbench/``."""
    text = path.read_text()
    try:
        tree = ast.parse(text)
    except SyntaxError:
        return False
    name, is_init = _module_of(path)
    package = name if is_init else name.rpartition(".")[0]
    old_name = _unmapped(name)
    old_package = None if old_name is None else (old_name if is_init
                                                 else old_name.rpartition(".")[0])
    lines = text.splitlines(keepends=True)
    edits = []  # (start line, start col, end line, end col, new text)
    for node in ast.walk(tree):
        if not isinstance(node, ast.ImportFrom) or not node.level:
            continue
        target = _new_target(package, old_package, node.level, node.module)
        base = target or _resolve(package, node.level, node.module)
        # "from . import module": a moved module named among the imported names
        groups: dict[str, list[ast.alias]] = {}
        for alias in node.names:
            moved = _mapped(f"{base}.{alias.name}")
            home = moved.rpartition(".")[0] if moved else base
            groups.setdefault(home, []).append(alias)
        if target is None and list(groups) == [base]:
            continue
        parts = []
        for home, aliases in groups.items():
            level, module = _relative(package, home)
            if not module:  # "from . import x" stays a relative import of the package
                parts.append(f"from {'.' * level} import "
                             + ", ".join(a.name + (f" as {a.asname}" if a.asname else "")
                                         for a in aliases))
            elif len(groups) == 1 and node.module is not None:
                segment = ast.get_source_segment(text, node) or ""
                head = re.match(r"from\s+\.+[\w.]*\s+import", segment)
                assert head, segment
                parts.append(f"from {'.' * level}{module} import" + segment[head.end():])
            else:
                parts.append(_render(node, level, module, aliases))
        indent = " " * node.col_offset
        edits.append((node.lineno, node.col_offset, node.end_lineno, node.end_col_offset,
                      ("\n" + indent).join(parts)))
    if not edits:
        return False
    for start, col, end, end_col, new in sorted(edits, reverse=True):
        head = lines[start - 1][:col]
        tail = lines[end - 1][end_col:]
        lines[start - 1:end] = [head + new + tail]
    path.write_text("".join(lines))
    return True


_DOTTED = re.compile(r"\b" + re.escape(EXP) + r"\.("
                     + "|".join(re.escape(k) for k in sorted(MOVES, key=len, reverse=True))
                     + r")(?![\w])")
_PATHS = re.compile(r"\bworkbench/experiment/("
                    + "|".join(re.escape(k.replace(".", "/"))
                               for k in sorted(MOVES, key=len, reverse=True))
                    + r")(?=\.py\b|/|\b)")
_FROM_PACKAGE = re.compile(r"^(?P<indent>[ \t]*)from workbench\.experiment import "
                           r"(?P<names>[\w ,]+?)(?P<comment>[ \t]*#.*)?$", re.M)


def _split_from_package(match: re.Match) -> str:
    """``from workbench.experiment import a, b as c`` with moved modules, one line per home."""
    groups: dict[str, list[str]] = {}
    for item in match["names"].split(","):
        item = item.strip()
        if not item:
            continue
        name = item.split()[0]
        moved = MOVES.get(name)
        home = f"{EXP}.{moved.rpartition('.')[0]}" if moved and "." in moved else EXP
        groups.setdefault(home, []).append(item)
    if list(groups) == [EXP]:
        return match[0]
    comment = match["comment"] or ""
    lines = [f"{match['indent']}from {home} import {', '.join(items)}"
             for home, items in groups.items()]
    lines[0] += comment
    return "\n".join(lines)


def rewrite_text(path: Path) -> bool:
    """Rewrite the dotted names and paths of moved modules in one text file."""
    try:
        text = path.read_text()
    except (UnicodeDecodeError, OSError):
        return False
    new = _DOTTED.sub(lambda m: f"{EXP}.{MOVES[m[1]]}", text)
    new = _PATHS.sub(lambda m: "workbench/experiment/"
                     + MOVES[m[1].replace("/", ".")].replace(".", "/"), new)
    if path.suffix == ".py":
        new = _FROM_PACKAGE.sub(_split_from_package, new)
    if new == text:
        return False
    path.write_text(new)
    return True


def _text_files() -> list[Path]:
    files = []
    for path in ROOT.rglob("*"):
        rel = path.relative_to(ROOT)
        if any(part in SKIP_DIRS for part in rel.parts) or not path.is_file():
            continue
        if rel.as_posix() in SKIP_FILES:
            continue
        if path.suffix in TEXT_SUFFIXES or path.name in TEXT_NAMES:
            files.append(path)
    return sorted(files)


def main(argv: list[str] | None = None) -> int:
    """Run the move; print what changed."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dry-run", action="store_true", help="change nothing")
    args = parser.parse_args(argv)
    for line in move(args.dry_run):
        print(line)
    if args.dry_run:
        return 0
    changed = set()
    for path in sorted((ROOT / "workbench").rglob("*.py")):
        if rewrite_imports(path):
            changed.add(path)
    for path in _text_files():
        if rewrite_text(path):
            changed.add(path)
    for path in sorted(changed):
        print(f"rewrote {path.relative_to(ROOT)}")
    for path in sorted(changed):  # a longer dotted name can push a line over the limit
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if len(line) > 100:
                print(f"{path.relative_to(ROOT)}:{number}: over 100 characters, wrap it")
    python = [str(p) for p in sorted(changed) if p.suffix == ".py"]
    if python:
        ruff = Path(sys.executable).with_name("ruff")
        subprocess.run([str(ruff) if ruff.exists() else "ruff", "check", "--quiet",
                        "--select", "I", "--fix", *python], cwd=ROOT, check=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
