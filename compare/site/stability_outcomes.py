"""What the stability pages answer first: each framework's outcome in each stress experiment
(pass, fails with all frameworks, fails with some, fails alone), and an experiment's rows
collapsed across the frameworks that gave the same finding, so that its page fits a screen's
worth of table (every row stays in the CSV the page links).

A row counts against its framework when its verdict is flagged (capitals: compare/stress/page.py)
or an ``error``, except a racy control that was caught (``RACE DETECTED``: the detector working;
a ``MISSED`` control counts). A failing row is shared when the other frameworks that ran the same
case (experiment, device, precision, setting, figure) fail it too: by all of them (the problem or
the arithmetic, not a port), by some, or by none (the framework alone; also where no other
framework ran that case).
"""
from __future__ import annotations

import dataclasses
from typing import Iterable

import backends
from compare.results.analysis import Finding
from compare.stress import generic, page

PASS, WITH_ALL, WITH_SOME, ALONE, ERROR, SKIPPED = ("pass", "fails with all", "fails with some",
                                                    "fails alone", "error", "skipped")
# the worse of two kinds, for a framework's cell: the one later here
ORDER = (SKIPPED, PASS, WITH_ALL, ERROR, WITH_SOME, ALONE)
MEANING = {PASS: "no flagged row",
           WITH_ALL: "flagged rows, each flagged for every other framework that ran the case too: "
                     "a limit of the problem or its precision, not of a port",
           WITH_SOME: "a flagged row that some other frameworks that ran the case pass",
           ALONE: "a flagged row that no other framework shares (or no other ran)",
           ERROR: "a cell that failed to run (`error`), no flagged row of its own",
           SKIPPED: "every row skipped (framework or device not there)"}


def control(r: Finding) -> bool:
    """A racy control's row (compare/stress/generic.py): flagged when it works."""
    return r.get("experiment") == "races" and generic.CONTROL in str(r.get("detail", ""))


def failing(r: Finding) -> bool:
    v = page.verdict(r)
    if control(r):
        return v.startswith("MISSED") or v == "error"
    return v == "error" or page.flagged(v)


def case(r: Finding) -> tuple[str, ...]:
    return tuple(str(r.get(k)) for k in ("experiment", "device", "precision", "setting", "figure"))


@dataclasses.dataclass(frozen=True)
class Outcome:
    kind: str
    failing: int          # rows that count against the framework
    rows: int             # rows it ran (not skipped)
    of_kind: int = 0      # failing rows of the outcome's kind


def frameworks(rows: Iterable[Finding]) -> list[str]:
    """The frameworks with rows, in the registry's order (the float64 oracle and the host-side
    predictions are none)."""
    got = {str(r["backend"]) for r in rows if r["backend"] in backends.BACKENDS}
    rank = {b: i for i, b in enumerate(backends.BACKENDS)}
    return sorted(got, key=lambda b: (rank.get(b, len(rank)), b))


def shared(r: Finding, peers: list[Finding]) -> str:
    """How a failing row is shared by the other frameworks' rows of its case."""
    if page.verdict(r) == "error":
        return ERROR
    others = [p for p in peers if p["backend"] != r["backend"] and p["backend"] in backends.BACKENDS
              and not page.skipped(p)]
    fails = sum(map(failing, others))
    if not others or fails == 0:
        return ALONE
    return WITH_ALL if fails == len(others) else WITH_SOME


def outcomes(rows: list[Finding]) -> dict[tuple[str, str], Outcome]:
    """(framework, experiment) -> its outcome, for every pair with rows."""
    cases: dict[tuple[str, ...], list[Finding]] = {}
    for r in rows:
        cases.setdefault(case(r), []).append(r)
    mine: dict[tuple[str, str], list[Finding]] = {}
    for r in rows:
        if r["backend"] in backends.BACKENDS:
            mine.setdefault((str(r["backend"]), str(r["experiment"])), []).append(r)
    out = {}
    for key, rs in mine.items():
        ran = [r for r in rs if not page.skipped(r)]
        bad = [r for r in ran if failing(r)]
        kinds = [shared(r, cases[case(r)]) for r in bad] or [PASS if ran else SKIPPED]
        kind = max(kinds, key=ORDER.index)
        out[key] = Outcome(kind, len(bad), len(ran), kinds.count(kind) if bad else 0)
    return out


def cell_text(o: Outcome | None) -> str:
    if o is None:
        return "-"
    if o.kind in (PASS, SKIPPED):
        return o.kind
    more = f"; {o.failing} flagged" if o.failing != o.of_kind else ""
    return f"{o.kind} ({o.of_kind} of {o.rows}{more})"


def collapsed(rows: list[Finding]) -> list[tuple[str, ...]]:
    """Rows as the page shows them: one line per finding, the frameworks that gave exactly the
    same one (device, precision, setting, figure, value, verdict and detail) named together."""
    groups: dict[tuple[str, ...], list[str]] = {}
    for r in rows:
        key = (str(r["device"]), str(r["precision"]), str(r["setting"]), str(r["figure"]),
               page.fmt_value(r.get("value")), page.verdict(r), str(r.get("detail", ""))[:200])
        names = groups.setdefault(key, [])
        if r["backend"] not in names:
            names.append(str(r["backend"]))
    return [(", ".join(names), *key) for key, names in groups.items()]
