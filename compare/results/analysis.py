"""A results file's ``analysis``: what a suite derives from its records, kept beside them (today
the stress suite's findings: ``rows``, plot ``series`` and ``provenance``, docs/stress.md).

The stored JSON object is this type itself (``TypedDict``s), so it is written as it was read;
``analysis_of`` types it as soon as the store has read it, after ``compare.results.records.ANALYSIS``
checked its rows and provenance.
"""
from __future__ import annotations

from typing import Any, Mapping, TypedDict, cast

Value = str | int | float | bool | None         # a finding's figure, as JSON holds it
# an experiment's plot series: kept in stress.json's analysis.series and redrawn from the file
# (merged parts too), so its shape is the experiment's own JSON: a file boundary
Series = dict[str, Any]


class Finding(TypedDict):
    """One row of ``analysis.rows`` as stress.json stores it (the columns of stress.md;
    ``compare.results.records.ROW`` checks them as a file loads). The page and the experiments'
    page hooks read findings in this form, from the file."""
    experiment: str
    backend: str
    device: str
    precision: str
    setting: str
    figure: str
    value: Value                        # a string, number, boolean or null
    verdict: str
    detail: str


class RunInfo(TypedDict, total=False):
    """The run that produced an experiment's rows (its provenance); ``backends``: the ones it
    gave, where a merge took the experiment's other backends from another run. ``git_dirty``:
    the run's tree had uncommitted changes (None, or absent in a run kept before it was recorded:
    not known)."""
    command: str | None
    created: str | None
    git_commit: str | None
    git_dirty: bool | None
    noisy_sitting: bool                 # publish let a noisy sitting through (compare.running.sitting_run)
    backends: list[str]


Provenance = dict[str, RunInfo | list[RunInfo]]     # experiment -> the run(s) that produced its rows


class Analysis(TypedDict, total=False):
    """A results file's ``analysis`` (empty for the run and sweep suites)."""
    rows: list[Finding]
    series: dict[str, Series]
    provenance: Provenance


def analysis_of(obj: Mapping[str, object]) -> Analysis:     # a stored analysis, checked
    """A stored ``analysis`` object as the analysis it is (the object itself, its keys kept); the
    store checked it (``records.ANALYSIS``) first."""
    return cast(Analysis, obj)


__all__ = ["Analysis", "Finding", "Provenance", "RunInfo", "Series", "Value", "analysis_of"]
