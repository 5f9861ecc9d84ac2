"""``python -m workbench.experiment.cli``: the ``workbench`` command."""

from . import main

raise SystemExit(main())
