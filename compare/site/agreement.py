"""Does a second independent run agree with the first? Ordering by ordering, row by row.

For every matrix row and every pair of frameworks that one store's figures separate (the rule of
``compare.site.ranking``: intervals across processes apart and 5 % apart, or 1.6x for one-process
figures), the other store's row is asked: the same order, separated too (agrees); not separated
(a tie there: allowed to move); or the opposite order, separated (disagrees: the ranking did not
survive a rerun). Both directions are counted, each pair once.

Only the cells both runs measured are compared (``hold``): a row ranks each framework's fastest
variant, and a second run that timed fewer variants (a sitting of the default variants alone, a
rerun from before a variant existed) would otherwise set one variant against another and call
the difference a reversal.
"""
from __future__ import annotations

import dataclasses
from itertools import combinations

from compare.site import ranking
from compare.site.data import Machine
from compare.site.matrix import Cell, Row


@dataclasses.dataclass(frozen=True)
class RowAgreement:
    question: str
    significant: int            # pairs separated in at least one of the two stores
    agree: int                  # separated in both, same order
    tie: int                    # separated in one, not in the other
    disagree: int               # separated in both, opposite orders
    missing: int                # separated in one, the other lacks a figure
    reversed_pairs: tuple[str, ...] = ()


def _ranked(c: Cell) -> bool:
    return c.value is not None and c.value > 0 and not c.reference


def orderings(row: Row) -> dict[tuple[str, str], int | None]:
    """(a, b) with a < b -> +1 where a is separated ahead of b, -1 behind, None where tied."""
    cells = {f: c for f, c in row.cells.items() if _ranked(c)}
    out: dict[tuple[str, str], int | None] = {}
    for a, b in combinations(sorted(cells), 2):
        ca, cb = cells[a], cells[b]
        sep = ranking.separated(ca, cb, exact=row.rule.exact)
        if not sep.apart:
            out[(a, b)] = None
            continue
        ahead = ca.value < cb.value if row.rule.better == "lower" else ca.value > cb.value   # type: ignore[operator]
        out[(a, b)] = 1 if ahead else -1
    return out


def compare_rows(first: list[Row], second: list[Row]) -> list[RowAgreement]:
    """Per row both stores read at the same sizes, the pairs either separates and what the
    other says of them."""
    theirs = {r.rule.key: r for r in second}
    out = []
    for r in first:
        if r.rule.key not in theirs or theirs[r.rule.key].scope != r.scope:
            continue                        # not measured in both, or at other sizes
        a, b = orderings(r), orderings(theirs[r.rule.key])
        agree = tie = disagree = missing = 0
        rev = []
        for pair in sorted(set(a) | set(b)):
            x, y = a.get(pair, "absent"), b.get(pair, "absent")
            if x in (None, "absent") and y in (None, "absent"):
                continue                       # separated by neither
            if "absent" in (x, y):
                missing += 1
            elif x is None or y is None:
                tie += 1
            elif x == y:
                agree += 1
            else:
                disagree += 1
                rev.append(" vs ".join(pair))
        total = agree + tie + disagree + missing
        out.append(RowAgreement(r.rule.question + (f" ({r.device})" if r.device else ""), total, agree, tie,
                                disagree, missing, tuple(rev)))
    return out


def summary(rows: list[RowAgreement]) -> str:
    sig = sum(r.significant - r.missing for r in rows)
    agree = sum(r.agree for r in rows)
    dis = sum(r.disagree for r in rows)
    ties = sum(r.tie for r in rows)
    return (f"{agree} of {sig} significant orderings agree between the two runs; {ties} became a tie in "
            f"one of them (allowed), {dis} reversed" + ("." if not dis else " (a ranking that did not survive a rerun)."))


@dataclasses.dataclass(frozen=True)
class Held:
    """Two runs held against each other on the cells both measured (``hold``)."""
    cells: int                  # cells (framework, variant, precision, device, sizes) both measured
    only_first: int             # ... measured by the first alone (not compared)
    only_second: int
    rows: tuple[RowAgreement, ...]

    @property
    def reversed(self) -> int:
        return sum(r.disagree for r in self.rows)

    def words(self, alone: bool = True) -> str:
        """The cells compared, in words: what a reader needs to know the orderings are like for like
        (``alone``: and how many cells one run measured alone)."""
        left = [f"{n} {who} alone measured" for n, who in ((self.only_first, "the first"), (self.only_second, "the second"))
                if n]
        return (f"on the {self.cells} cells both runs measured (the same framework, variant and sizes; a row's "
                f"figure is a framework's best of those)" + (f"; not compared: {', '.join(left)}" if left and alone else ""))


def _keys(m: Machine) -> set[str]:
    return {r.key for r in (*m.records, *m.busy)}


def common(first: Machine, second: Machine) -> tuple[Machine, Machine, Held]:
    """Both stores cut to the cells both measured (``Record.key``: scenario, framework, device,
    precision, variant, parameters and tags), and how many each had alone (``Held``, no rows yet)."""
    a, b = _keys(first), _keys(second)
    both = a & b

    def cut(m: Machine) -> Machine:
        return dataclasses.replace(m, run=tuple(r for r in m.run if r.key in both),
                                   sweep=tuple(r for r in m.sweep if r.key in both),
                                   busy=tuple(r for r in m.busy if r.key in both))
    return cut(first), cut(second), Held(len(both), len(a - b), len(b - a), ())


def hold(first: Machine, second: Machine) -> Held:
    """``compare_rows`` of the two stores' matrices, each evaluated on the cells both measured."""
    from compare.site import pages
    a, b, held = common(first, second)
    return dataclasses.replace(held, rows=tuple(compare_rows(pages.evaluate(a)[0], pages.evaluate(b)[0])))
