"""A later sitting's README: what its folder shows, generated from the stores (issue 57, item 5).

A sitting folder (``docs/results/<machine>/sittings/<label>/``, compare/site/sittings.py) holds a
README that says by hand what was run and why; its figures (each run's sitting check, how far the
figures moved from the report's, how many fall inside the report's intervals) are a generated
block, ``<!-- BEGIN generated: sitting -->`` (compare/site/readme.py), which ``python -m compare.site.readme`` rewrites and
the test suite holds to the stores, so that no quoted figure drifts from the records.
"""
from __future__ import annotations

import functools
import json
from pathlib import Path

from compare.site import agreement, assemble, pages
from compare.site import sittings as second
from compare.site.data import Machine, load
from compare.site.render import Block, P, Table, block_md


def readmes(results: Path) -> list[Path]:
    """Every sitting folder's README under ``results`` (docs/results), in name order."""
    return sorted(p for p in results.glob(f"*/{second.FOLDER}/*/README.md")
                  if not p.is_symlink() and not p.parent.is_symlink())


@functools.lru_cache(maxsize=None)
def _report(machine: Path) -> tuple[Path, Machine, dict[str, Machine], tuple[second.Between, ...],
                                   tuple[second.Landed, ...]]:
    """A machine folder's report (its site.json names the stores) and its stores, its later
    sittings' stores by label, their figures against its rows, and where each sitting's figures
    land against the earlier ones."""
    report = machine / "report"
    inputs = json.loads((report / "site.json").read_text(encoding="utf-8"))["inputs"]
    root = machine.parents[2]                    # site.json's paths are from the repository root
    m = load([root / p for p in inputs])
    rows, _ = pages.evaluate(m)
    later = second.load_all([machine])
    between = second.compare(rows, later, m)
    return report, m, dict(later), tuple(between), tuple(second.landed(between, [label for label, _ in later]))


def block(folder: Path) -> str:
    """The generated block of the sitting in ``folder``: its runs' sitting checks, then its figures
    against the report's, by row (the machine page's table, for this sitting alone), where
    they land in launch floors against the report's and the earlier sittings' range, and its
    orderings held against the report's (``compare agree``)."""
    report, m, stores, every, landed = _report(folder.parent.parent)
    mine = stores[folder.name]
    between = [b for b in every if b.sitting == folder.name]
    checks = assemble.sittings(list(mine.runs), report)[2:]       # the table, without the page's heading and words
    figures = [*second.summary(between, [folder.name])[1:], *_orders(between),
               *second.landing([x for x in landed if x.sitting == folder.name]), *_held(m, mine)]
    words = [P("Its runs' sitting checks (compare/measuring/sitting.py; quiet or noisy against the kind's "
               "quiet sittings):"), *checks] if checks else [P("Its runs took no sitting check.")]
    return "\n\n".join(block_md(b) for b in [*words, *figures]) + "\n"


def _orders(between: list[second.Between]) -> list[Block]:
    """Per row: whether the frameworks this sitting compared stand in the report's order (by
    value, so the same for a time and a rate), or which pairs swap."""
    by_row: dict[str, list[second.Between]] = {}
    for b in between:
        by_row.setdefault(b.question, []).append(b)
    rows = []
    for q, bs in by_row.items():
        if len(bs) < 2 or all(b.exact for b in bs):
            continue
        first = [b.framework for b in sorted(bs, key=lambda b: b.first)]
        other = [b.framework for b in sorted(bs, key=lambda b: b.other)]
        swaps = [f"{x} and {y}" for i, x in enumerate(first) for y in first[i + 1:]
                 if other.index(x) > other.index(y)]
        rows.append((q, str(len(bs)), "the same" if not swaps else f"{len(swaps)} pair{'s' if len(swaps) > 1 else ''} swap: {'; '.join(swaps)}"))
    return [Table(("row", "frameworks", "their order here against the report's (a swap may lie inside a tie)"), tuple(rows))] if rows else []


def _held(report: Machine, mine: Machine) -> list[Block]:
    """Its orderings against the report's on the cells both measured (compare/site/agreement.py)."""
    held = agreement.hold(report, mine)
    got = [r for r in held.rows if r.significant - r.missing]
    if not got:
        return [P(f"Held against the report ordering by ordering (`python -m compare agree`), {held.words(alone=False)}: "
                  "no pair of frameworks is separated in either.")]
    which = "; ".join(f"{r.question}: {', '.join(r.reversed_pairs)}" for r in got if r.reversed_pairs)
    return [P(f"Held against the report ordering by ordering (`python -m compare agree`), {held.words(alone=False)}: "
              f"**{agreement.summary(got)}**" + (f" Reversed: {which}." if which else ""))]


__all__ = ["block", "readmes"]
