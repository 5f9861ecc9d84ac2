"""The README's Python example runs as written; its benchmark tables are the JSON's."""

import json
import re
from pathlib import Path

import pandas as pd

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_example_runs(google_5q_dir, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DATA_DIR", str(google_5q_dir))
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "the README has no Python example"
    namespace: dict = {}
    exec(compile(blocks[0], str(README), "exec"), namespace)
    assert namespace["model"].selected_ in ("prior", "boosted")
    pred = namespace["multi"].predict(namespace["X_test"])
    assert isinstance(pred, pd.DataFrame) and list(pred.columns) == namespace["ds"].target_names


def test_readme_benchmark_tables_are_made_from_the_json():
    """README's Speed tables are benchmarks/tables.py's rendering of benchmarks/results/*.json
    (make bench writes both): no number in them is typed by hand or left stale."""
    import importlib.util

    path = README.parent / "benchmarks" / "tables.py"
    spec = importlib.util.spec_from_file_location("bench_tables", path)
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    text = README.read_text()
    for name in tables.TABLES:
        assert f"<!-- bench:{name} -->" in text, f"README has no {name} table"
        assert (tables.RESULTS / f"{name}.json").is_file()
    assert tables.render(text) == text, "run python benchmarks/tables.py (or make bench)"
    # the rendering is the JSON's: a changed figure changes the table
    data = json.loads((tables.RESULTS / "scaling.json").read_text())
    point = next(p for p in data["points"] if "per_1k_rows" in p)
    point["per_1k_rows"] += 1.0
    assert tables.scaling(data) != tables.scaling(
        json.loads((tables.RESULTS / "scaling.json").read_text()))
