"""The sweep's and the stress suite's results-file formats, handed to the registry the store reads
through (``compare.results.formats``). ``register`` is called once at start-up by the command line
(``compare.cli.main``), and by any other program that reads their files (the tests' conftest): an
explicit call, never an import's side effect, so no arrow runs back up from the results stage to
the suites' own format modules."""
from __future__ import annotations

from compare.results import formats
from compare.stress.format import FORMAT as STRESS
from compare.sweep.format import FORMAT as SWEEP


def register() -> None:
    """Every suite's format in the registry (idempotent)."""
    formats.register(SWEEP, STRESS)
