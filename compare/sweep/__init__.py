"""The measurement sweeps (docs/measurement.md): ``suite`` runs them (``python -m compare sweep``),
``points`` says what each scenario contributes, ``converged`` its converged references, ``page``,
``horizon`` and ``plots`` turn saved records into the page. Nothing is imported here, so a reader
of records (compare/records.py) can use ``points`` without loading the suite."""
