"""File and function sizes are a review signal, not a test that cuts code.

``benchmarks/house.py`` (``make house``) prints the modules over 400 lines and the functions
over 80; nothing fails on them. The design rules about concerns that do hold as tests (no
import circle, type-only imports included; the core below the experiment layer; rooms
importing one way; Optuna's private names in one package) are in ``tests/test_layering.py``.
These tests check the script itself.
"""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _house():
    spec = importlib.util.spec_from_file_location("bench_house", ROOT / "benchmarks" / "house.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_house_script_lists_long_modules_and_functions(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(6))
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "long.py").write_text(
        f"class A:\n  def method(self):\n{body}\n\n\ndef short():\n    pass\n")
    (tmp_path / "pkg" / "small.py").write_text("def f():\n    return 1\n")
    modules, functions = _house().sizes(tmp_path / "pkg", module_lines=8, function_lines=5)
    assert modules == {"long.py": 12}
    assert functions == {"long.py:A.method": 7}


def test_the_house_script_prints_what_it_finds_and_never_fails(capsys):
    house = _house()
    house.main(["--module-lines", "100", "--function-lines", "30"])  # returns: no exit code
    out = capsys.readouterr().out
    modules, functions = house.sizes(house.PACKAGE, 100, 30)
    assert modules  # it read the package: the package has modules over 100 lines
    assert f"{len(modules)} module(s) over 100 lines" in out
    assert f"{len(functions)} function(s) over 30 lines" in out
    assert all(f"{n:5d}  {name}" in out for name, n in {**modules, **functions}.items())
