"""The core never imports the experiment layer, MLflow, Optuna or matplotlib."""

import ast
import subprocess
import sys
from pathlib import Path

import workbench

PACKAGE = Path(workbench.__file__).parent
EXPERIMENT = PACKAGE / "experiment"
FORBIDDEN = ("mlflow", "optuna", "matplotlib", "shap")


def _core_files():
    files = [p for p in PACKAGE.rglob("*.py") if EXPERIMENT not in p.parents]
    assert len(files) >= 8, files  # the test must look at the real core
    return files


def test_importing_the_core_loads_no_experiment_dependencies():
    modules = sorted(f"workbench.{p.relative_to(PACKAGE).with_suffix('').as_posix().replace('/', '.')}"
                     .removesuffix(".__init__") for p in _core_files())
    code = ("import sys\n" + "".join(f"import {m}\n" for m in modules) +
            f"bad = [m for m in sys.modules if m.split('.')[0] in {FORBIDDEN!r} "
            "or m.startswith('workbench.experiment')]\nprint(bad)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_core_sources_do_not_import_the_experiment_layer():
    for path in _core_files():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [("." * node.level) + (node.module or "")]
            else:
                continue
            for name in names:
                assert "experiment" not in name, f"{path} imports {name}"
                assert name.split(".")[0] not in FORBIDDEN, f"{path} imports {name}"
