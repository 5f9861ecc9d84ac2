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


_LOADED = """
import sys
from workbench.experiment.cli import main
try:
    main(sys.argv[1:])
except SystemExit:
    pass
heavy = {"mlflow", "optuna", "shap", "sklearn", "lightgbm"}
print("LOADED:" + ",".join(sorted({m.split(".")[0] for m in sys.modules} & heavy)))
"""


def _loaded(*argv: str) -> set[str]:
    out = subprocess.run([sys.executable, "-c", _LOADED, *argv], capture_output=True,
                         text=True, check=True)
    line = [x for x in out.stdout.splitlines() if x.startswith("LOADED:")][-1]
    return {m for m in line.removeprefix("LOADED:").split(",") if m}


def test_the_command_imports_heavy_libraries_only_where_needed(tmp_path):
    """``workbench --help`` loads none of the heavy libraries; ``workbench simulate`` none of
    the experiment layer's (MLflow, Optuna, SHAP)."""
    assert _loaded("--help") == set()
    assert _loaded("sweep", "--help") == set()
    assert _loaded("predict", "--help") == set()
    simulated = _loaded("simulate", "--experiments", "10", "--out", str(tmp_path / "s.csv"))
    assert not simulated & {"mlflow", "optuna", "shap"}, simulated
    assert (tmp_path / "s.csv").is_file()  # the command did run
    # the guard can fail: a command that fits loads the estimators
    config = tmp_path / "c.toml"
    config.write_text('[data]\ndata_dir = "/nonexistent"\n[model]\nbasis = "ridge"\n')
    assert "sklearn" in _loaded("evaluate", str(config), "--no-track")


def test_import_workbench_is_light():
    out = subprocess.run([sys.executable, "-c", "import sys, workbench; print(sorted("
                          "{m.split('.')[0] for m in sys.modules} & {'sklearn', 'lightgbm', "
                          "'pandas', 'mlflow'}))"], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    assert workbench.BaseBoostCV.__name__ == "BaseBoostCV"  # names still load on first use
