"""The package's longest modules and functions: a review signal, not a test.

    python benchmarks/house.py [--module-lines 400] [--function-lines 80] [PATH ...]

Prints every module of ``workbench/`` (or of the given paths) over ``--module-lines`` lines
and every function or method over ``--function-lines``, longest first, and exits 0. A long
module or function is a question for a reviewer (one concern? one step?), not a reason to
cut: a module with one concern reads better whole than as two halves joined by a re-export.
The design rules that do hold as tests (no import circle, the core below the experiment
layer) are in ``tests/test_layering.py``. ``make house`` runs this script.
"""

from __future__ import annotations

import argparse
import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "workbench"
MODULE_LINES, FUNCTION_LINES = 400, 80


def sizes(root: Path, module_lines: int = MODULE_LINES, function_lines: int = FUNCTION_LINES
          ) -> tuple[dict[str, int], dict[str, int]]:
    """The modules under ``root`` over ``module_lines`` lines and the functions over
    ``function_lines``, each name -> its length in lines, longest first (a function named
    ``path:qualified.name``)."""
    files = [root] if root.is_file() else sorted(root.rglob("*.py"))
    base = root.parent if root.is_file() else root
    modules, functions = {}, {}
    for path in files:
        text = path.read_text(encoding="utf-8")
        name = path.relative_to(base).as_posix()
        if (n := len(text.splitlines())) > module_lines:
            modules[name] = n
        for qualname, node in _functions(ast.parse(text)):
            if (n := node.end_lineno - node.lineno + 1) > function_lines:
                functions[f"{name}:{qualname}"] = n
    return (dict(sorted(modules.items(), key=lambda kv: -kv[1])),
            dict(sorted(functions.items(), key=lambda kv: -kv[1])))


def _functions(tree: ast.AST, prefix: str = ""):
    """Every function and method of ``tree`` with its qualified name (``Class.method``)."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            yield prefix + node.name, node
            yield from _functions(node, f"{prefix}{node.name}.")
        elif isinstance(node, ast.ClassDef):
            yield from _functions(node, f"{prefix}{node.name}.")
        else:
            yield from _functions(node, prefix)


def main(argv: list[str] | None = None) -> None:
    """Print the modules and functions over the marks (always exits 0)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("paths", nargs="*", type=Path, default=[PACKAGE])
    parser.add_argument("--module-lines", type=int, default=MODULE_LINES)
    parser.add_argument("--function-lines", type=int, default=FUNCTION_LINES)
    args = parser.parse_args(argv)
    for root in args.paths:
        modules, functions = sizes(root, args.module_lines, args.function_lines)
        print(f"{root}: {len(modules)} module(s) over {args.module_lines} lines")
        for name, n in modules.items():
            print(f"  {n:5d}  {name}")
        print(f"{root}: {len(functions)} function(s) over {args.function_lines} lines")
        for name, n in functions.items():
            print(f"  {n:5d}  {name}")


if __name__ == "__main__":
    main()
