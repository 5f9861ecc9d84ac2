"""The README's Python example runs as written and it stays short; the benchmark tables of
docs/benchmarks.md are the JSON's."""

import json
import re
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
BENCHMARKS_PAGE = ROOT / "docs" / "benchmarks.md"


def test_readme_example_runs(google_5q_dir, monkeypatch):
    monkeypatch.setenv("WORKBENCH_DATA_DIR", str(google_5q_dir))
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "the README has no Python example"
    namespace: dict = {}
    exec(compile(blocks[0], str(README), "exec"), namespace)
    assert namespace["model"].selected_ in ("prior", "boosted")
    pred = namespace["multi"].predict(namespace["X_test"])
    assert isinstance(pred, pd.DataFrame) and list(pred.columns) == namespace["ds"].target_names


def test_readme_is_a_short_guide_without_timings():
    """At most 150 lines; measured seconds belong to docs/benchmarks.md, where each table
    says when and on what machine it was measured."""
    text = README.read_text()
    assert len(text.splitlines()) <= 150
    assert not re.search(r"\d+(\.\d+)? ?(s|seconds|minutes)\b", text), "a timing in README"
    for target in re.findall(r"\]\(((?:docs/|CHANGES)[^)#]*)", text):
        assert (ROOT / target).exists(), f"README links to a missing {target}"


def test_benchmark_tables_are_made_from_the_json():
    """docs/benchmarks.md's tables are benchmarks/tables.py's rendering of
    benchmarks/results/*.json (make bench writes both): no number in them is typed by hand
    or left stale."""
    import importlib.util

    path = ROOT / "benchmarks" / "tables.py"
    spec = importlib.util.spec_from_file_location("bench_tables", path)
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    assert tables.PAGE == BENCHMARKS_PAGE
    text = BENCHMARKS_PAGE.read_text()
    for name in tables.TABLES:
        assert f"<!-- bench:{name} -->" in text, f"docs/benchmarks.md has no {name} table"
        # measured, or the block says it is not (a table added before its first make bench)
        assert (tables.RESULTS / f"{name}.json").is_file() or \
            tables.NOT_MEASURED.format(name=name) in text, name
    assert tables.render(text) == text, "run python benchmarks/tables.py (or make bench)"
    # the rendering is the JSON's: a changed figure changes the table
    data = json.loads((tables.RESULTS / "scaling.json").read_text())
    point = next(p for p in data["points"] if "per_1k_rows" in p)
    point["per_1k_rows"] += 1.0
    assert tables.scaling(data) != tables.scaling(
        json.loads((tables.RESULTS / "scaling.json").read_text()))


def _rows(text):
    """``{first cell: other cells}`` of every Markdown table row in ``text``."""
    return {cells[0]: cells[1:] for line in text.splitlines() if line.startswith("| ")
            for cells in [[c.strip() for c in line.strip("|").split("|")]]}


def test_readme_results_are_make_run_s():
    """README.md's results block is benchmarks/tables.py's rendering of ``make run``'s
    reports/results.json, when a full run's is there (tests/test_reproduce.py checks the rows
    ``reproduce --quick`` computes against its own)."""
    import importlib.util

    results = ROOT / "reports" / "results.json"
    res = json.loads(results.read_text()) if results.is_file() else None
    if res is None or res.get("quick"):
        pytest.skip("no full run's reports/results.json (make run)")
    spec = importlib.util.spec_from_file_location("bench_tables", ROOT / "benchmarks" /
                                                  "tables.py")
    tables = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tables)
    text = README.read_text()
    assert tables.render_readme(text, res) == text, \
        "run python benchmarks/tables.py --readme reports/results.json"


def test_readme_results_are_the_benchmarks_page_s():
    """The README's headline table repeats docs/benchmarks.md's numbers, row for row."""
    readme, page = _rows(README.read_text()), _rows(BENCHMARKS_PAGE.read_text())
    same = {"control program (prior)": "control program (prior)",
            "reference implementation, paper settings (mean of 8 runs)":
                "reference implementation, paper settings (mean of 8 runs)",
            "workbench, paper settings": "workbench, paper settings, seed 0",
            "workbench, parameter-space model (`hamiltonian.toml`)": "test MAE (41 rows, once)"}
    for ours, theirs in same.items():
        assert readme[ours] == page[theirs], ours
    assert readme["workbench, paper settings"] == ["1.734", "1.027", "0.794", "0.801", "1.013",
                                                   "1.074"]
