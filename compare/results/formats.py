"""Each suite's results-file format, registered by name: the store reads a file through the
format its ``suite`` names (``compare.results.store``), so no suite is imported for a side effect.

A format is data (``compare.results.records.Format``): the upgrade of a format-1 record to today's shape
and the suite's own checks on top of the common schema. The modules named here are leaves (they
import the schema and the scenario tables, never a suite's driver), so reading a file loads no
suite and no arrow runs back up from the schema.
"""
from __future__ import annotations

from compare.results.records import Format
from compare.results.run_format import FORMAT as RUN
from compare.stress.format import FORMAT as STRESS
from compare.sweep.format import FORMAT as SWEEP

FORMATS: dict[str, Format] = {f.suite: f for f in (RUN, SWEEP, STRESS)}

__all__ = ["FORMATS", "Format"]
