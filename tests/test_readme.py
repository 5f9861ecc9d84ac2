"""The README's Python example runs as written."""

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
