"""What every command's process has: the bottom of the experiment layer.

* :mod:`.errors` -- the errors reported as one line (``ConfigError``, ``UsageError``,
  ``StorageError``, ``TrackingError``, ``SweepTimedOut``) and the helpers that shorten,
  list and redact what they say;
* :mod:`.startup` -- what a command sets up first: its progress logging;
* :mod:`.signals` -- SIGINT and SIGTERM: one line, runs ended ``KILLED``;
* :mod:`.outputs` -- the files a command writes, checked before work, written all or nothing.

May import: nothing of the experiment layer (the core and the standard library only).
"""
