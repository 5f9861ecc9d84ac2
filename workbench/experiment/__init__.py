"""The experiment layer: configs, evaluation and the ``workbench`` command.

It depends on the core (:mod:`workbench`); the core never imports it. One home (package)
per concern, each ``__init__`` saying what lives there and which homes it may import, from
the bottom up: :mod:`.process` and :mod:`.scoring`; :mod:`.config`, :mod:`.storage`,
:mod:`.tracking` and :mod:`.figures`; :mod:`.splits`; :mod:`.families`; :mod:`.runs`;
:mod:`.sweep`; :mod:`.paper`; :mod:`.cli`. :mod:`.api` holds the promised Python names.
"""
