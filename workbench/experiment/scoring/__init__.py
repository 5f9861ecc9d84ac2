"""What is measured of a fitted model, and how it is written.

* :mod:`.scores` -- the score records (``Scores``, ``ModelScores``, ``CVEstimate``) and the
  per-target errors;
* :mod:`.results` -- the result dataclasses (``Result.to_json`` is what ``--json`` writes);
* :mod:`.bootstrap` -- bootstrap intervals of the test errors over the test rows;
* :mod:`.units` -- a unit beside a number;
* :mod:`.explain` -- SHAP values of a model's predictions.

May import: nothing of the experiment layer.
"""
