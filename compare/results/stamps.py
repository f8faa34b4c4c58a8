"""Which run measured each record: a record's ``run`` stamp (``compare.measuring.environment.run_stamp``:
``created``, ``commit``, ``dirty``) names an entry of its store's ``runs`` by its start time.

Every suite's hook that appends its run to the store stamps each record it keeps (run, sweep and
stress suites alike); a merge keeps the entries its records name. A record stored before stamps
existed, whose run could not be told from the evidence the store keeps, carries the explicit
``UNKNOWN`` stamp (``created`` "unknown" and a ``note`` saying why): its pages say "run unknown".
"""
from __future__ import annotations

from typing import Mapping

from compare.results.environment import RunEnvironment
from compare.results.record import Record
from compare.results.store import run_environments

UNKNOWN = "unknown"       # a stamp's ``created`` where the run could not be told


def unknown_stamp(why: str) -> dict[str, object]:
    """The stamp of a record whose run is not known: says so, and why."""
    return {"created": UNKNOWN, "commit": None, "dirty": None, "note": f"run unknown: {why}"}


def is_unknown(run: Mapping[str, object] | None) -> bool:
    """Whether a record's stamp says its run is unknown (as opposed to naming one)."""
    return run is not None and run.get("created") == UNKNOWN


def flat_runs(runs: list[RunEnvironment]) -> list[RunEnvironment]:
    """The run environments a store's ``runs`` stand for, a merged entry's ``environments``
    flattened in order (``compare.results.store.run_environments``)."""
    return [e for entry in runs for e in run_environments(entry)]


def names_a_run(rec: Record, runs: list[RunEnvironment]) -> bool:
    """Whether the record's stamp names an entry of ``runs`` (by start time, with the same commit
    where the entry records one)."""
    run = rec.run
    if not run or is_unknown(run):
        return False
    for e in flat_runs(runs):
        if str(e.get("created")) == str(run.get("created")) and \
                (not e.get("git_commit") or not run.get("commit") or e.get("git_commit") == run.get("commit")):
            return True
    return False


def unstamped(records: list[Record], runs: list[RunEnvironment]) -> list[str]:
    """The cell keys of records that neither name a run of ``runs`` nor say their run is unknown."""
    return [r.key for r in records if not names_a_run(r, runs) and not is_unknown(r.run)]


__all__ = ["UNKNOWN", "flat_runs", "is_unknown", "names_a_run", "unknown_stamp", "unstamped"]
