"""``workbench sweep``, one room per concern.

* :mod:`~workbench.experiment.sweep.search`: nested CV over the family's study blocks, the
  outer folds' refits and the final evaluation (:func:`~.search.run_sweep`);
* :mod:`~workbench.experiment.sweep.scheduler`: samplers, pruners and the trial scheduler
  that leaves every study with exactly its budget of counted trials;
* :mod:`~workbench.experiment.sweep.workers`: the processes of ``--workers N``;
* :mod:`~workbench.experiment.sweep.report`: the studies' figures and tables.

Importing this package loads none of them (nor Optuna). The studies' storage (journal file or
database) is :mod:`workbench.experiment.storage`.

May import: process, config, splits, scoring, figures, families, tracking, storage, runs.
"""
