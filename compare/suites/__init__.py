"""Suites: the commands that run cells. ``driver`` is the one driver (probe -> what can run ->
preflight -> claim -> lock -> run -> render) and the ``Suite`` and ``Command`` shapes; ``run``
(``all``, ``run``, ``<scenario>``), ``sweep``, ``stress`` (with ``stress_context``, what its
experiments are handed) are suites on it; ``publish`` (with ``publish_log``) runs a machine's
parts end to end; ``listing`` (``list``) and ``report`` are commands that run no cell; ``formats``
hands the sweep's and stress suite's results-file formats to the store's registry at start-up. The top stage below the command line (compare/cli.py)."""
