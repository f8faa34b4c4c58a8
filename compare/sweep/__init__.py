"""The measurement sweeps (docs/measurement.md): compare/suites/sweep.py runs them (``python -m compare sweep``),
``points`` says what each scenario contributes, ``converged`` its converged references, ``page``,
``horizon`` and ``plots`` turn saved records into the page. Nothing is imported here, so a reader
of records (compare/results/records.py) can use ``points`` without loading the suite."""
