"""``workbench reproduce``: the paper's results and figures, and a second benchmark.

* :mod:`.reproduce` -- the command: runs every system, writes the figures, tables, JSON and
  report, logs to MLflow.
* :mod:`.compute` -- the reproduction's own fits: learning curves, SHAP of the correction,
  the tabula rasa MLPs, the parameter-space model's settings.
* :mod:`.gates` and :mod:`.peer` -- the IBM two-qubit gates against LightGBM boosted from
  the prior and tuned by CV.
* :mod:`.systems` -- the catalogue of systems in the metric schema of ``evaluate``;
  :mod:`.runs` logs them as MLflow runs.
* :mod:`.reproduction` -- what was computed (``results.json``); :mod:`.report` -- the
  Markdown report.

May import: process, config, splits, scoring, figures, families, tracking, runs, sweep.
"""

from .report import report
from .reproduce import experiments_dir, reproduce
from .reproduction import Reproduction

__all__ = ["Reproduction", "experiments_dir", "report", "reproduce"]
