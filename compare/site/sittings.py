"""A report's rows beside the same rows measured in another sitting (issue 57, item 3).

A figure's 95 % interval says how far it moves between the processes of one run; a lent machine's
next session (a *sitting*) can move it further (docs/measurement.md, "The sitting check"). So a
machine's folder may hold later sittings of its rows: ``DIR/sittings/<label>/`` (any store:
results.json, sweep.json), each a re-measurement of some rows on another machine of the kind or
another day, never merged into the report's own records. The row pages set each figure's range
across the sittings beside its within-run interval, and the machine page counts how many figures
of the other sittings fall inside the report's stated interval. A sitting's rows are read by the
same rules as the report's (compare/site/matrix.py), so the two name the same variant-picking.
"""
from __future__ import annotations

import dataclasses
import statistics
from pathlib import Path
from typing import Any, Iterable

from compare.site.render import H, P, Table
from compare.site import data, fmt, matrix, questions
from compare.site.data import Machine, load
from compare.site.matrix import Row

FOLDER = "sittings"
# Rows whose figures travel between sittings in launch floors (docs/measurement.md, "Per-call
# figures in launch floors"): the regime each divides by its cell's own floor, else its run's.
TRAVEL = {"latency": "latency", "pipelined": "throughput", "particles-small": "throughput"}


@dataclasses.dataclass(frozen=True)
class Between:
    """One framework's figure of one row in the report and in another sitting."""
    row: str                      # the rule's key
    question: str
    framework: str
    variant: str                  # the variant the row picked in both (another pick is not compared)
    unit: str
    first: float                  # the report's figure
    ci: tuple[float, float] | None    # its 95 % interval across processes (None: no interval)
    sitting: str                  # the other sitting's label (its folder's name)
    other: float
    processes: int                # the other sitting's processes for this figure
    exact: bool = False           # a deterministic figure (bytes, error shares): no interval, no processes
    # the two figures in the unit that travels between sittings (launch floors, ``TRAVEL``); None
    # where the row has none or a record no floor
    first_floors: float | None = None
    other_floors: float | None = None

    @property
    def spread(self) -> float:
        """The larger figure over the smaller: how far the sittings disagree."""
        return _apart(self.first, self.other)

    @property
    def floors_spread(self) -> float | None:
        """The same in launch floors (None without a floor on both sides)."""
        return _apart(self.first_floors, self.other_floors) if self.first_floors and self.other_floors else None

    @property
    def ratios(self) -> tuple[float, float]:
        """The sitting's figure over the report's, in launch floors and in seconds (callers keep
        the figures with a floor on both sides: ``_floored``)."""
        return (self.other_floors or 0.0) / (self.first_floors or 1.0), self.other / self.first

    @property
    def inside(self) -> bool | None:
        """Whether the other sitting's figure lies inside the report's interval (None: no interval)."""
        return None if self.ci is None else self.ci[0] <= self.other <= self.ci[1]


def _apart(a: float, b: float) -> float:
    lo, hi = sorted((a, b))
    return hi / lo if lo > 0 else float("inf")


def folders(inputs: Iterable[Path]) -> list[tuple[str, Path]]:
    """(label, folder) of every later sitting beside the report's stores, in name order."""
    out = []
    for p in inputs:
        root = Path(p) / FOLDER
        if Path(p).is_dir() and root.is_dir() and not root.is_symlink():
            out += [(d.name, d) for d in sorted(root.iterdir()) if d.is_dir() and not d.is_symlink()]
    return out


def compare(rows: list[Row], sittings: list[tuple[str, Machine]], report: Machine | None = None) -> list[Between]:
    """Every figure a row of the report (``report``'s stores: for the figures in floors) and the
    same row of another sitting both have, where the row picked the same variant in both (a
    sitting that timed fewer variants may pick another)."""
    out = []
    for label, other in sittings:
        # a sitting of the busy row alone holds only busy records, which devices() does not read
        have = set(other.devices()) | {r.device for r in other.busy if r.status == "ok" and r.time}
        for row in rows:
            if row.rule.device and row.rule.device not in have:
                continue
            theirs = matrix.evaluate(row.rule, other, fmt.value)
            # the same cells only: the same sizes read (a row that picks the largest size would
            # read a smaller one in a sitting without it) and, for a row that aggregates
            # scenarios, every one of them
            if theirs.device != row.device or theirs.scope != row.scope:
                continue
            mine, yours = _floors(row, report), _floors(row, other)
            for fw, c in row.cells.items():
                o = theirs.cells.get(fw)
                if (c.value is None or o is None or o.value is None or c.reference != o.reference
                        or o.variant != c.variant):
                    continue
                out.append(Between(row.rule.key, row.rule.question, fw, c.variant, row.rule.unit, c.value, c.ci,
                                   label, o.value, o.processes, row.rule.exact,
                                   mine.get((fw, c.variant, c.value)), yours.get((fw, o.variant, o.value))))
    return out


def _floors(row: Row, m: Machine | None) -> dict[tuple[str, str, float], float]:
    """The figures in launch floors (``data.floors``) of the records ``row`` reads in ``m``, by
    (framework, variant, figure), where the row travels in floors (empty where it does not)."""
    regime = TRAVEL.get(row.rule.key)
    if regime is None or m is None:
        return {}
    out = {}
    for r in row.rule.pick(m, row.device):
        t = data.per_call(r, regime) if r.status == "ok" else None
        if t is not None and (f := data.floors(r, regime, t)) is not None:
            out[(r.backend, r.variant, t.median)] = f
    return out


@dataclasses.dataclass(frozen=True)
class Landed:
    """How one sitting's figures of the rows that travel in floors land against the range of the
    report's and the earlier sittings' figures, and against their row's band (``Band``): in launch
    floors and, beside, in seconds."""
    sitting: str
    figures: int                  # its figures with a floor on both sides and an earlier range
    inside_floors: int            # inside the earlier range in floors
    inside_seconds: int           # inside the earlier range in seconds (the same figures)
    median_floors: float          # its median ratio to the report's figure (larger over smaller), in floors
    median_seconds: float         # ... and in seconds
    banded: int = 0               # its figures whose row had a band before it
    band_floors: int = 0          # inside the row's band, in floors
    band_seconds: int = 0         # ... in seconds (the same figures)


@dataclasses.dataclass(frozen=True)
class Band:
    """How far a row's figures moved between sittings: every later sitting's figure of the row
    over the report's, pooled across frameworks (the report's own, 1, included), in launch floors
    and in seconds. A figure's own range rests on two or three sittings; a fresh figure lies inside
    the range of ``n`` exchangeable earlier ones with probability (n - 1) / (n + 1), so one needs
    about 19 ratios for 90 %, which only a row's pool gives."""
    row: str                      # the rule's key
    floors: tuple[float, ...]     # the ratios in floors, 1 (the report) first
    seconds: tuple[float, ...]

    @property
    def n(self) -> int:
        return len(self.floors)

    @property
    def coverage(self) -> float:
        """The chance a fresh exchangeable ratio lies inside the band's range."""
        return (self.n - 1) / (self.n + 1)

    def holds(self, b: Between) -> tuple[bool, bool]:
        """Whether ``b``'s figure lies inside the band, in floors and in seconds."""
        floors, seconds = b.ratios
        return _within(floors, list(self.floors)), _within(seconds, list(self.seconds))


def _within(x: float | None, xs: list[float | None]) -> bool:
    """``x`` inside the range of ``xs`` (every one a figure: the callers keep only those with floors)."""
    got = [v for v in xs if v is not None]
    return x is not None and bool(got) and min(got) <= x <= max(got)


def _floored(between: list[Between], label: str) -> list[Between]:
    return [b for b in between if b.sitting == label and b.floors_spread is not None and b.first > 0]


def _pool(pooled: dict[str, tuple[list[float], list[float]]], figures: list[Between]) -> None:
    """Add ``figures``' ratios to each row's pool (the report's own 1 first)."""
    for b in figures:
        f, s = pooled.setdefault(b.row, ([1.0], [1.0]))
        f.append(b.ratios[0])
        s.append(b.ratios[1])


def _bands(pooled: dict[str, tuple[list[float], list[float]]]) -> dict[str, Band]:
    return {row: Band(row, tuple(f), tuple(s)) for row, (f, s) in pooled.items()}


def bands(between: list[Between], labels: list[str]) -> dict[str, Band]:
    """Each row's band from the sittings ``labels`` (rows in ``TRAVEL`` with a floor on both sides)."""
    pooled: dict[str, tuple[list[float], list[float]]] = {}
    for label in labels:
        _pool(pooled, _floored(between, label))
    return _bands(pooled)


def landed(between: list[Between], labels: list[str]) -> list[Landed]:
    """Each sitting after the first (``labels`` in order) against the range the report and the
    sittings before it give each figure of the rows in ``TRAVEL``, and against each row's band
    from the sittings before it: whether the figure lands inside, in launch floors and in seconds
    (issue 57: a unit that travels lands inside)."""
    out = []
    earlier: dict[tuple[str, str, str], list[Between]] = {}      # the figure's earlier sittings
    pooled: dict[str, tuple[list[float], list[float]]] = {}      # the rows' ratios so far
    for label in labels:
        mine = _floored(between, label)
        ranged = [(b, earlier[b.row, b.framework, b.variant]) for b in mine if (b.row, b.framework, b.variant) in earlier]
        before = _bands(pooled)
        held = [before[b.row].holds(b) for b in mine if b.row in before]
        if ranged:
            out.append(Landed(label, len(ranged),
                              sum(_within(b.other_floors, [b.first_floors, *(p.other_floors for p in past)])
                                  for b, past in ranged),
                              sum(_within(b.other, [b.first, *(p.other for p in past)]) for b, past in ranged),
                              statistics.median(b.floors_spread or 1.0 for b, _ in ranged),
                              statistics.median(b.spread for b, _ in ranged),
                              len(held), sum(f for f, _ in held), sum(s for _, s in held)))
        _pool(pooled, mine)
        for b in mine:
            earlier.setdefault((b.row, b.framework, b.variant), []).append(b)
    return out


def load_all(inputs: Iterable[Path]) -> list[tuple[str, Machine]]:
    """The later sittings' stores, loaded (an unreadable one is an error, as for the report's)."""
    return [(label, load([d])) for label, d in folders(inputs)]


def _inside_words(b: Between) -> str:
    if b.inside is None:
        return "exact figure" if b.exact else "no interval"
    return "inside" if b.inside else "**outside**"


def _interval(b: Between) -> str:
    return "-" if b.ci is None else f"{fmt.value(b.ci[0], b.unit)} – {fmt.value(b.ci[1], b.unit)}"


def row_blocks(rows: list[Row], between: list[Between]) -> list[Any]:
    """A page's rows in the other sittings: each figure's range across sittings beside its interval."""
    keys = {r.rule.key for r in rows}
    mine = [b for b in between if b.row in keys]
    if not mine:
        return []
    floored = any(b.first_floors for b in mine)
    return [H("The same rows in another sitting"),
            P("Each figure of these rows beside the same figure measured in another sitting (another "
              "machine of the kind, or another day: the folder `sittings/` beside the report's records). "
              "The 95 % interval is the report's, across its processes; the range across sittings is "
              "how far the machine's sessions move the figure, which no single run's interval shows."
              + (" A per-call figure is also given in launch floors (the report's → the sitting's): "
                 "the unit meant to travel between sittings." if floored else "")),
            Table(("row", "framework", "variant", "this report", "95 % interval", "other sitting", "its figure",
                   "range across sittings", "inside the interval", *(["in launch floors"] if floored else [])), tuple(
                (b.question, b.framework, b.variant or "default", fmt.value(b.first, b.unit), _interval(b), b.sitting,
                 fmt.value(b.other, b.unit) + ("" if b.exact or b.processes > 1 else " (1 process)"),
                 f"{b.spread:.3g}×", _inside_words(b), *([_in_floors(b)] if floored else []))
                for b in sorted(mine, key=lambda x: (x.question, x.sitting, x.framework))))]


def _in_floors(b: Between) -> str:
    """The two figures in launch floors and how far apart, where both have a floor."""
    if b.floors_spread is None:
        return "-"
    return f"{b.first_floors:.3g} → {b.other_floors:.3g} ({b.floors_spread:.3g}×)"


def summary(between: list[Between], labels: list[str]) -> list[Any]:
    """The machine page's count: how many figures of the other sittings fall inside the report's
    stated interval, by row; or that no row has a second sitting yet."""
    if not between:
        return [H("Second sittings"),
                P("No row of this report has been re-measured in a second sitting yet "
                  f"(`{FOLDER}/<label>/` beside the records; issue 57): its figures' intervals are "
                  "within one run, and how far the next session of the machine moves them is not known.")]
    by_row: dict[str, list[Between]] = {}
    for b in between:
        by_row.setdefault(b.question, []).append(b)
    with_ci = [b for b in between if b.inside is not None]
    inside = sum(1 for b in with_ci if b.inside)
    exact = sum(1 for b in between if b.inside is None and b.exact)
    few = len(between) - len(with_ci) - exact
    none = "; ".join([*([f"{few} timed in fewer than 6 processes"] if few else []),
                      *([f"{exact} exact figures, which need none"] if exact else [])])
    spreads = sorted(b.spread for b in between)
    mid = statistics.median(spreads)
    order = {r.question: i for i, r in enumerate(questions.RULES)}     # the matrix's row order
    return [H("Second sittings"),
            P(f"{len(between)} figure{'s' if len(between) != 1 else ''} of {len(by_row)} "
              f"row{'s' if len(by_row) != 1 else ''} measured again in {len(labels)} later "
              f"sitting{'s' if len(labels) != 1 else ''} ({', '.join(labels)}): "
              + (f"**{inside} of {len(with_ci)}** with an interval fall inside the report's stated "
                 "95 % interval" + (f" (without one: {none})" if none else "")
                 if with_ci else f"none has a 95 % interval in the report to hold it to ({none})")
              + f"; the sittings differ by {mid:.3g}× in the median figure, {spreads[-1]:.3g}× at most. "
              "Each row's page lists its figures; the machine's sittings, quiet or noisy, are above."),
            Table(("row", "figures", "inside the interval", "no interval", "exact", "median range",
                   "largest range"), tuple(
                (q, str(len(bs)), str(sum(1 for b in bs if b.inside)),
                 str(sum(1 for b in bs if b.inside is None and not b.exact)), str(sum(1 for b in bs if b.exact)),
                 f"{statistics.median(b.spread for b in bs):.3g}×", f"{max(b.spread for b in bs):.3g}×")
                for q, bs in sorted(by_row.items(), key=lambda kv: order.get(kv[0], len(order))))),
            *landing(landed(between, labels), bands(between, labels))]


def landing(got: list[Landed], current: dict[str, Band] | None = None) -> list[Any]:
    """Where each later sitting's per-call figures land against the range the report and the
    sittings before it give, and against each row's band, in launch floors and in seconds
    (nothing where none has a range); with ``current``, the bands a next sitting is held to."""
    if not got:
        return []
    rows = {r.key: r.question for r in questions.RULES if r.key in TRAVEL}
    named = ", ".join(f"“{q}”" for q in list(rows.values())[:-1]) + f" and “{list(rows.values())[-1]}”"
    out: list[Any] = [
        P(f"**Units that travel.** The rows {named} are also compared in launch "
          "floors (each figure over its cell's own empty-kernel launch, else its run's: "
          "docs/measurement.md). A sitting's figure *lands* where it lies inside the range that "
          "the report and the sittings before it give the same figure; the same figures in "
          "seconds beside. That range rests on two or three sittings, and a fresh figure lies "
          "inside the range of k alike earlier ones with probability (k − 1)/(k + 1) at best (a "
          "third for two), so each figure is also held to its row's *band*: every earlier "
          "sitting's figure of the row over the report's, pooled across frameworks (n ratios, the "
          "report's own 1 among them: (n − 1)/(n + 1) where the sittings are alike). Issue 57's "
          "target: 90 % of a fresh sitting's figures land, in floors."),
        Table(("sitting", "figures with an earlier range", "land in floors", "land in seconds",
               "median range to the report, floors", "... seconds", "in the row's band, floors",
               "... seconds"), tuple(
            (x.sitting, str(x.figures), _share(x.inside_floors, x.figures), _share(x.inside_seconds, x.figures),
             f"{x.median_floors:.3g}×", f"{x.median_seconds:.3g}×",
             _share(x.band_floors, x.banded), _share(x.band_seconds, x.banded)) for x in got))]
    if current:
        out += [P("The bands a next sitting is held to (every stored sitting's ratios): a figure of the "
                  "row should lie within these multiples of the report's figure."),
                Table(("row", "ratios", "band in floors", "band in seconds", "expected inside"), tuple(
                    (rows[k], str(b.n), _range(b.floors), _range(b.seconds), f"{100 * b.coverage:.0f} %")
                    for k, b in ((k, current[k]) for k in rows if k in current)))]
    return out


def _share(k: int, n: int) -> str:
    return f"{k} ({100 * k / n:.0f} %)" if n else "-"


def _range(xs: tuple[float, ...]) -> str:
    return f"{min(xs):.2f}–{max(xs):.2f}×"


__all__ = ["FOLDER", "TRAVEL", "Band", "Between", "Landed", "bands", "compare", "folders", "landed", "landing", "load_all", "row_blocks", "summary"]
