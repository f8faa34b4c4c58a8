"""When a matrix row may name a best: the separation rule (docs/measurement.md, "Ties: when a row
names a best").

A row ranks only what its figures separate. Two timed figures are separated when both carry a 95 %
interval of the median across independent worker processes, the intervals do not overlap and the
medians are at least SEPARATED_GAP apart; a figure from one process has no interval (between
processes such figures disagreed by up to 1.6x on the machines measured when the rule was set, with
1 % spread inside each; the stores' spans now: docs/measurement.md, the separation table), so it is
separated only at ONE_PROCESS_GAP. Deterministic figures (bytes, error shares) need SEPARATED_GAP
alone; exactly equal ones are always a tie. Everyone not separated from the best shares the top of
the row. A row may rank only figures repeated across processes (the busy row: ``unrepeated``): from
one process a cell it shows its ratios and ranks nothing.
"""
from __future__ import annotations

import dataclasses
from typing import Protocol, Sequence

from compare.running.repeats import AUTO_MIN

SEPARATED_GAP = 1.05       # medians at least 5 % apart (timings with intervals; deterministic figures)
ONE_PROCESS_GAP = 1.6      # a figure without an interval: the spread seen between processes


class Figure(Protocol):
    """What the rule reads of a cell: its figure and, where timed in several processes, the
    interval of its median."""
    @property
    def framework(self) -> str: ...
    @property
    def value(self) -> float | None: ...
    @property
    def ci(self) -> tuple[float, float] | None: ...


class Repeated(Figure, Protocol):
    """A figure with the number of worker processes behind it."""
    @property
    def processes(self) -> int: ...


def gap(a: float, b: float) -> float:
    """How far apart two positive figures are, as a ratio >= 1."""
    return max(a, b) / min(a, b)


# the test that decided a pair, as the verdicts name it
EQUAL, EXACT, INTERVALS, OVERLAP, ONE_PROCESS = (
    "equal figures", "deterministic figures", "95 % intervals apart", "95 % intervals overlap",
    "figures without a 95 % interval")


@dataclasses.dataclass(frozen=True)
class Separation:
    apart: bool
    kind: str                  # EQUAL | EXACT | INTERVALS | OVERLAP | ONE_PROCESS
    gap: float                 # the medians' ratio, >= 1

    @property
    def needed(self) -> float:
        """The gap this kind of pair needs to be separated."""
        return ONE_PROCESS_GAP if self.kind == ONE_PROCESS else SEPARATED_GAP

    def words(self) -> str:
        """Why the pair is (not) separated, e.g. ``2.08×; figures without a 95 % interval need 1.6×``."""
        if self.kind in (EQUAL, OVERLAP):
            return self.kind
        need = f"{self.needed:g}×" if self.kind == ONE_PROCESS else f"{100 * (self.needed - 1):.0f} %"
        return f"{self.gap:.3g}×; {self.kind} need {need}"


def separated(a: Figure, b: Figure, exact: bool = False) -> Separation:
    """Whether two figures are separated, and by which test."""
    if not (a.value and b.value):
        raise ValueError("only figures are ranked")
    g = gap(a.value, b.value)
    if a.value == b.value:
        return Separation(False, EQUAL, 1.0)
    if exact:
        return Separation(g >= SEPARATED_GAP, EXACT, g)
    if a.ci is not None and b.ci is not None:
        if a.ci[0] <= b.ci[1] and b.ci[0] <= a.ci[1]:
            return Separation(False, OVERLAP, g)
        return Separation(g >= SEPARATED_GAP, INTERVALS, g)
    return Separation(g >= ONE_PROCESS_GAP, ONE_PROCESS, g)


def tie(ranked: Sequence[Figure], exact: bool = False) -> tuple[str, ...]:
    """Who shares the top: ``ranked`` best first; the best and everyone not separated from it,
    in that order."""
    if not ranked:
        return ()
    top = ranked[0]
    return (top.framework,) + tuple(c.framework for c in ranked[1:] if not separated(top, c, exact).apart)


def why_tied(top: Figure, others: Sequence[Figure], exact: bool = False) -> str:
    """Why ``others`` share the top with ``top``, the tests grouped: ``one-process figures within
    1.22×, under the 1.6× they need`` (names before each group where the tests differ)."""
    groups: dict[str, list[tuple[str, float]]] = {}
    for c in others:
        s = separated(top, c, exact)
        groups.setdefault(s.kind, []).append((c.framework, s.gap))
    parts = []
    for kind, xs in groups.items():
        far = max(g for _, g in xs)
        if kind == ONE_PROCESS:
            text = f"{kind} within {far:.3g}×, under the {ONE_PROCESS_GAP:g}× they need"
        elif kind in (EXACT, INTERVALS):     # under 5 %: a percentage, as the rule states it
            text = (f"{'95 % intervals apart but' if kind == INTERVALS else kind} within "
                    f"{100 * (far - 1):.1f} %, under the {100 * (SEPARATED_GAP - 1):.0f} % they need")
        else:
            text = kind
        parts.append(text if len(groups) == 1 else f"{', '.join(n for n, _ in xs)}: {text}")
    return "; ".join(parts)


def shorten(names: Sequence[str], keep: int = 3) -> str:
    """A list of names for a narrow column: all up to ``keep``, else the first two and a count."""
    if len(names) <= keep:
        return ", ".join(names)
    return f"{', '.join(names[:2])} +{len(names) - 2}"


def than(ratio: float, unit: str) -> str:
    """A reference cell against the leader in words: ``13.6× faster``, ``2.81× more memory``."""
    worse = ratio > 1
    k = ratio if worse else 1 / ratio
    word = {"s": ("slower", "faster"), "1/s": ("slower", "faster"),
            "B": ("more memory", "less memory")}.get(unit, ("higher", "lower"))
    return f"{k:.3g}× {word[0] if worse else word[1]}"


def bare(figs: Sequence[Repeated]) -> str:
    """A row's figures without a 95 % interval, for its best column: 'one process' where none was
    repeated, else 'under 6 processes' (too few for the interval); '' where every figure has one."""
    no = [f for f in figs if f.value is not None and f.ci is None]
    if not no:
        return ""
    return "one process" if all(f.processes == 1 for f in no) else f"under {AUTO_MIN} processes"


def unrepeated(figs: Sequence[Repeated], command: str) -> str:
    """The verdict of a row that ranks only figures repeated across processes where some are not
    ('' where every figure has a 95 % interval, or no ``command``: the row ranks any figure): a
    one-process figure says little of the next process (up to ONE_PROCESS_GAP apart), so such a
    row shows its ratios and names no best."""
    why = bare(figs)
    if not why or not command:
        return ""
    shown = [f for f in figs if f.value is not None]
    no = [f.framework for f in shown if f.ci is None]
    every = why == "one process" and len(no) == len(shown)
    who = ("every figure here is from one process a cell" if every
           else f"{', '.join(no)}: no 95 % interval across processes")
    return (f"Not ranked: {who}; this row ranks only figures repeated across processes, each with a "
            f"95 % interval (`{command}`). Ratios are to the leading figure; no best is named.")
