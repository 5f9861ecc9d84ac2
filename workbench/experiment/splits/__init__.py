"""How the rows are split: the columns that group and order them, and the CV folds.

* :mod:`.columns` -- what ``workbench init`` reads off a CSV's columns (the features, the
  columns that group the rows, the column that orders them in time);
* :mod:`.folds` -- every CV fold of a command, following the rows' groups or order.

May import: process, config.
"""
