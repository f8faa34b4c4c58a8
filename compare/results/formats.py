"""Each suite's results-file format, registered by name: the store reads a file through the
format its ``suite`` names (``compare.results.store``).

A format is data (``compare.results.records.Format``): the upgrade of a format-1 record to today's
shape and the suite's own checks on top of the common schema. The run suite's is this stage's own
(``run_format``). The sweep's and the stress suite's live with their suites (compare/sweep/format.py,
compare/stress/format.py: their checks read the sweep tables and the stress experiments' page
hooks, stages above this one), so this registry never imports them: they are handed in through
``register``, an explicit call at start-up (``compare.suites.formats.register``, which the command
line, ``compare.cli.main``, makes before anything else; so does the tests' conftest). Until then
the registry knows their names and files, and reading one of their files raises
``NotRegistered`` rather than loading it unchecked or unupgraded.
"""
from __future__ import annotations

from typing import Any, NoReturn

from compare.results.records import Format
from compare.results.run_format import FORMAT as RUN

# suite -> its file's name, for the suites whose format is registered at start-up
REGISTERED_LATER = {"sweep": "sweep.json", "stress": "stress.json"}


class NotRegistered(RuntimeError):
    """A suite's file read before its format was registered: a program's start-up lacks the call."""


def pending(suite: str, file: str) -> Format:
    """The stand-in of a format not registered yet: every hook refuses."""
    def refuse(data: dict[str, Any]) -> NoReturn:     # the stored JSON it was handed
        raise NotRegistered(f"the {suite} suite's results-file format is not registered: call "
                            "compare.suites.formats.register() at start-up (compare.cli.main does)")
    return Format(suite, file, upgrade=refuse, record_problem=refuse, store_problem=refuse)


STAND_INS = {s: pending(s, f) for s, f in REGISTERED_LATER.items()}
FORMATS: dict[str, Format] = {RUN.suite: RUN, **STAND_INS}


def register(*formats: Format) -> None:
    """Hand in suites' formats (each replaces its stand-in; registering one again is harmless).
    A suite or file name this registry does not know is a programming error."""
    for f in formats:
        known = FORMATS.get(f.suite)
        if known is None or known.file != f.file:
            raise ValueError(f"unknown format {f.suite!r} ({f.file}): known {', '.join(FORMATS)}")
        FORMATS[f.suite] = f


def registered(suite: str) -> bool:
    """Whether ``suite``'s own format (not its stand-in) is in the registry."""
    return suite in FORMATS and FORMATS[suite] is not STAND_INS.get(suite)


__all__ = ["FORMATS", "Format", "NotRegistered", "register", "registered"]
