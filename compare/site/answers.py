"""README's answers: which framework for which job, one line per question, in words.

Each line is a matrix row of every machine's report, read from the row the site build derives
(compare/site/matrix.py's ``Row``): the leader or the tie, by how much (the runner-up's ratio, or
the tied spread and the next framework), and how sure (the separation test that decided it,
compare/site/ranking.py). The rows come from the stores a report's ``site.json`` names, so README
says what the report's matrix says; ``python -m compare.site.readme`` rewrites the block and the
test suite fails where it differs.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

from compare.running.repeats import AUTO_MIN
from compare.site import ranking, untimed
from compare.site.data import Machine
from compare.site.matrix import Cell, Row

# How sure a separation is, in words a chooser reads (the test that decided it)
SURE = {ranking.INTERVALS: "95 % intervals apart",
        ranking.ONE_PROCESS: f"under {AUTO_MIN} processes, no 95 % interval: past the {ranking.ONE_PROCESS_GAP:g}× that needs",
        ranking.EXACT: "exact figures"}
UNSURE = {ranking.OVERLAP: "95 % intervals overlap",
          ranking.ONE_PROCESS: f"under {AUTO_MIN} processes, no 95 % interval: under {ranking.ONE_PROCESS_GAP:g}×",
          ranking.INTERVALS: f"under {100 * (ranking.SEPARATED_GAP - 1):.0f} % apart",
          ranking.EXACT: f"under {100 * (ranking.SEPARATED_GAP - 1):.0f} % apart",
          ranking.EQUAL: "equal figures"}


def _ranked(row: Row) -> list[Cell]:
    """The row's ranked cells (no reference), leader first."""
    return sorted((c for c in row.cells.values() if c.ratio is not None and not c.reference),
                  key=lambda c: (c.ratio or 0.0, c.framework != row.top))


def _x(ratio: float | None) -> str:
    return f"{ratio:.3g}×" if ratio is not None else "?"


def _references(row: Row) -> str:
    """Hand-written adjoints that beat the best AD figure: the fastest of them, as a clause."""
    ahead = [c for c in row.cells.values() if c.reference and c.ratio is not None and c.ratio < 1]
    if not ahead or row.rule.reference is None:
        return ""
    best = min(ahead, key=lambda c: c.ratio or 1.0)
    return f"; hand-written {best.framework} {_x(1 / (best.ratio or 1.0))} better"


def _untimed(row: Row) -> str:
    """The frameworks with a variant never timed at the row's point (compare/site/untimed.py),
    as a short clause (the row's page names the variants): the answer ranks only those timed."""
    names = untimed.in_order(c.framework for c in row.cells.values() if c.untimed)
    return f"; variants not timed: {ranking.shorten(names)}" if names else ""


def answer(row: Row) -> str:
    """One row's answer: ``**numba**, 1.27× ahead of torch (95 % intervals apart)``, ``tie:
    **cupy**, **torch** (within 1.03×: 95 % intervals overlap; next warp 1.30×)``, or the leading
    figure of a row that is not ranked, with the reason; then the frameworks with a variant not
    timed there."""
    return _answer(row) + (_untimed(row) if row.top is not None else "")


def _answer(row: Row) -> str:
    if row.top is None:
        return "—"
    ranked = _ranked(row)
    ad = f"{row.rule.reference.ranked}: " if row.rule.reference else ""
    lead = row.cells[row.top]
    runner = next((c for c in ranked if c.framework != row.top), None)
    noisy = " ~noisy" if lead.noisy else ""
    if not row.tied:          # figures of several runs, unstamped, of an uncommitted tree or not repeated
        why = row.best_text().removeprefix("— (").removesuffix(")")
        ahead = "" if runner is None else (f", level with {runner.framework}" if _x(runner.ratio) == "1×"
                                           else f", {_x(runner.ratio)} ahead of {runner.framework}")
        return f"{ad}{row.top} leads{ahead}, not ranked ({why}){noisy}{_references(row)}"
    if len(row.tied) == 1:
        if runner is None:
            return f"{ad}**{row.top}**, the only one measured{noisy}"
        sep = ranking.separated(lead, runner, row.rule.exact)
        return (f"{ad}**{row.top}**, {_x(runner.ratio)} ahead of {runner.framework} "
                f"({SURE.get(sep.kind, sep.kind)}){noisy}{_references(row)}")
    tied = [row.cells[f] for f in row.tied]
    kinds = dict.fromkeys(ranking.separated(lead, c, row.rule.exact).kind for c in tied[1:])
    spread = max(c.ratio or 1.0 for c in tied)
    nxt = next((c for c in ranked if not c.tied), None)
    names = ", ".join(f"**{f}**" for f in row.tied)
    return (f"{ad}tie: {names} (within {_x(spread)}: {', '.join(UNSURE.get(k, k) for k in kinds)}"
            + (f"; next {nxt.framework} {_x(nxt.ratio)}" if nxt else "") + f"){_references(row)}")


def machine_of(report: Path) -> Machine:
    """The machine a report was built from: the stores its ``site.json`` names (the program
    registers the suites' formats at start-up: compare.site.readme.main)."""
    from compare.site import data
    how = json.loads((report / "site.json").read_text(encoding="utf-8"))
    root = Path(__file__).resolve().parents[2]
    return data.load([root / p for p in how["inputs"]])


def table(reports: list[Path], readme: Path) -> str:
    """The answers as a Markdown table: one line per question, one column per report (its
    machine, linked to its overview); ``—`` where a machine has no figure for that question."""
    from compare.site import pages, questions
    cols = []
    for rep in reports:
        m = machine_of(rep)
        rows, _ = pages.evaluate(m)
        link = Path(os.path.relpath(rep, readme.parent), "index.md").as_posix()
        cols.append((f"[{m.name()}]({link})", {r.rule.key: r for r in rows}))
    lines = ["| job | " + " | ".join(h for h, _ in cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for rule in questions.RULES:
        if not any(rule.key in rows for _, rows in cols):
            continue
        cells = [answer(rows[rule.key]) if rule.key in rows else "—" for _, rows in cols]
        lines.append(f"| {rule.question} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"
