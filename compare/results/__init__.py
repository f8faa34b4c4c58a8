"""Results: what a cell produced, kept. ``record`` is the typed, immutable ``Record`` (its JSON
format's history at the top) made of the parts in ``record_parts`` (timings per regime, the
check, memory, gradient, hardware), ``records`` the schema every loaded record passes,
``formats`` each suite's file format registered by name (its upgrade and its own checks;
``run_format`` the run suite's; the sweep's and stress suite's handed in at start-up), ``store`` the per-machine results files (written atomically,
upgraded on read) and ``samecheck`` two result folders compared outside the measurements.

The lowest stage: it imports only the cell (``compare.spec``) and ``compare.files``; no later
stage, the sweep's and stress suite's format modules included (``formats.register``)."""
