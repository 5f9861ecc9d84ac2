"""``workbench sweep``, one room per concern.

* :mod:`~workbench.experiment.sweep.search`: nested CV over the family's study units, the
  outer folds' refits and the final evaluation (:func:`~.search.run_sweep`);
* :mod:`~workbench.experiment.sweep.scheduler`: samplers, pruners and the trial scheduler
  that leaves every study with exactly its budget of counted trials;
* :mod:`~workbench.experiment.storage`: the Optuna storage adapter (journal file or
  database, checked, repaired), the only module touching Optuna's private names;
* :mod:`~workbench.experiment.sweep.workers`: the processes of ``--workers N``.

Importing this package loads none of them (nor Optuna).
"""
