"""Which runs a matrix row's figures come from (``Record.run``), in words for its page.

A row is ranked only when every figure it reads comes from one run: one machine, one commit, one
sitting, with that run's own yardstick, made from a committed tree (a figure must name a commit
someone can check out). Records made before runs were stamped carry no run; a row that reads any
of them, records of several runs, or one run of an uncommitted tree (or one whose tree state is
not known), shows its figures and names no best.
"""
from __future__ import annotations

import re
from typing import Callable, Iterable

from compare.results.environment import tree_state
from compare.results.record import Record
from compare.results.stamps import is_unknown

UNSTAMPED = "records without a run stamp (made before runs were recorded)"
RUN_UNKNOWN = "run unknown"     # a record stamped as of a run its store's evidence could not tell
NOISY = " (noisy sitting)"     # beside a run publish let through a noisy sitting (compare.measuring.sitting)


def short(sha: object) -> str:
    """A commit as pages name it: a full 40-digit hash (a lent machine's COMPARE_GIT_COMMIT)
    shortened to git's 7, anything else as given."""
    text = str(sha)
    return text[:7] if re.fullmatch(r"[0-9a-f]{40}", text) else text


def label(rec: Record) -> str:
    """A run in words: its start (to the minute), commit and a dirty tree; '' when unstamped,
    "run unknown" where the stamp says the run could not be told (compare.results.stamps)."""
    run = rec.run or {}
    if is_unknown(run):
        return RUN_UNKNOWN
    return (run_words(run.get("created"), run.get("commit"), run.get("dirty"), run.get("noisy_sitting"))
            if run.get("created") else "")


def run_words(created: object, commit: object, dirty: object, noisy: object = False) -> str:
    """'run START UTC, commit C' (START to the minute where it is ISO), with a noisy sitting
    (``NOISY``) and the tree's state."""
    when = str(created or "?")
    if re.match(r"\d{4}-\d\d-\d\dT\d\d:\d\d", when):
        when = f"{when[:16].replace('T', ' ')} UTC"
    state = f" ({words})" if (words := tree_state(dirty)) else ""
    return f"run {when}{NOISY if noisy else ''}, commit {short(commit) if commit else 'unknown commit'}{state}"


def runs_of(recs: Iterable[Record]) -> tuple[str, ...]:
    """The distinct runs of ``recs`` in first-seen order ('' for unstamped records)."""
    return tuple(dict.fromkeys(label(r) for r in recs))


def one_run(runs: tuple[str, ...]) -> bool:
    """One stamped run, of a committed tree: the only figures a row ranks."""
    not_clean = tuple(f" ({tree_state(d)})" for d in (True, None))
    return len(runs) == 1 and runs[0] not in ("", RUN_UNKNOWN) and not runs[0].endswith(not_clean)


def uncommitted(runs: tuple[str, ...]) -> bool:
    """One stamped run, of an uncommitted tree or one whose state is not known."""
    return len(runs) == 1 and runs[0] not in ("", RUN_UNKNOWN) and not one_run(runs)


def mark(runs: tuple[str, ...]) -> str:
    """The matrix's best column where ``runs`` are not one committed run: why it names no best."""
    return "not a commit" if uncommitted(runs) else "not one run" if "" in runs else f"{len(runs)} runs"


def words(runs: tuple[str, ...]) -> str:
    """The provenance sentence a row's page prints."""
    if not runs:
        return "No records."
    if one_run(runs):
        return f"Every figure of this row comes from one {runs[0]}."
    if uncommitted(runs):
        return (f"Not ranked: this row's figures come from one {runs[0]}, not a commit someone can "
                "check out. Ratios are to the leading figure; no best is named until it is measured "
                "again from a commit.")
    named = [r for r in runs if r]
    parts = named + ([UNSTAMPED] if "" in runs else [])
    return (f"Not ranked: this row's figures come from {len(named) or 'an unknown number of'} run(s)"
            f"{' and ' + UNSTAMPED if '' in runs and named else ''}: {'; '.join(parts)}. Ratios are "
            "to the leading figure; no best is named across runs.")


def one_run_of(recs: list[Record], exact: Callable[[Record], bool],
               processes: Callable[[Record], int]) -> list[Record]:
    """A row's records (all its candidates, before one is kept per cell) read from one run where
    they span several and one committed run measured every framework that any of them measured ok:
    the run with the most exact (framework, variant) cells, then the most processes a cell, then
    the later. Its records, and the other runs' records of frameworks it has none of (a skip, a
    failure), are the row's; where no run covers every framework, all of them are (and the row
    names no best: ``words``)."""
    by_run: dict[str, list[Record]] = {}
    for r in recs:
        by_run.setdefault(label(r), []).append(r)
    if len(by_run) < 2:
        return recs
    measured = {r.backend for r in recs if r.status == "ok"}

    def weight(item: tuple[str, list[Record]]) -> tuple[int, int, str]:
        ok = [r for r in item[1] if r.status == "ok"]
        return (len({(r.backend, r.variant) for r in ok if exact(r)}),
                max((processes(r) for r in ok), default=0), str((ok[0].run or {}).get("created", "")) if ok else "")
    whole = [kv for kv in by_run.items() if one_run((kv[0],))
             and {r.backend for r in kv[1] if r.status == "ok"} >= measured]
    if not whole:
        return recs
    run, mine = max(whole, key=weight)
    has = {r.backend for r in mine}
    return [r for r in recs if label(r) == run or r.backend not in has]
