"""A command's work on a config, whatever the model family.

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
