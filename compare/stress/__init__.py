"""The numerical stability stress suite (docs/stress.md): compare/suites/stress.py runs it (``python -m compare
stress``), ``registry`` lists the experiments (each scenario's, registered by name, and
``generic``'s), ``numerics`` holds what they share, ``page`` and ``plots`` write stress.md and the
PNGs. Nothing is imported here, so a reader of stress.json (compare/results/records.py) can use the
registry without loading the suite."""
