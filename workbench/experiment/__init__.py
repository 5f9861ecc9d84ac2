"""The experiment layer: configs, evaluation and the ``workbench`` command.

It depends on the core (:mod:`workbench`); the core never imports it.
"""
