"""The recommendation matrix: one row per user question, one column per framework.

Each row is a ``Rule``: which records it reads (scenario, device, precision, sizes), which figure
of a record it compares (a regime's per-call time, a rate, device memory, an error, a first-call
time) and whether lower or higher is better. A framework's cell is its best figure over its
variants (the variant named), and its ratio to the best framework on the row: 1.0 for the best,
2.0 for twice as slow (or half the rate, twice the memory). The rule's text is printed on the
pages beside the row, and each row's verdict is derived here from the cells, never written by
hand.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Callable

import scenarios
from compare.record import Record
from compare.site import data
from compare.site.data import Machine, Timing

WITHIN = 1.10                     # "within 10 % of the best"
# Variants that change the arithmetic (not the same work): never a row's figure, shown on pages.
NOT_SAME_WORK = ("fastmath",)
BANDS = ((1.10, "best"), (2.0, "near"), (5.0, "far"))   # ratio upper bounds; beyond: "poor"


@dataclasses.dataclass(frozen=True)
class Cell:
    framework: str
    value: float | None           # the figure, in the row's unit; None when not ok or not measured
    lo: float | None = None       # spread (quartiles) where timed
    hi: float | None = None
    variant: str = ""
    status: str = "absent"        # ok | mismatch | error | skipped | absent (no such record)
    reason: str = ""
    noisy: str = ""
    ratio: float | None = None    # to the row's best: >= 1, 1 is the best

    @property
    def band(self) -> str:
        if self.ratio is None:
            return "none"
        return next((name for bound, name in BANDS if self.ratio <= bound), "poor")


@dataclasses.dataclass(frozen=True)
class Rule:
    key: str                      # stable id; also the anchor on its page
    question: str                 # the row's label in the matrix
    page: str                     # the page (stem) that answers it in full
    unit: str                     # 's', 'B', '1/s', 'x' (a plain ratio)
    better: str                   # 'lower' | 'higher'
    text: str                     # the rule in words, printed on the pages
    pick: Callable[[Machine, str], list[Record]]     # the records the row reads
    figure: Callable[[Record], Timing | float | None]  # one record's figure
    device: str = ""              # '' the report's device; else this one


@dataclasses.dataclass(frozen=True)
class Row:
    rule: Rule
    device: str
    cells: dict[str, Cell]
    best: str | None
    verdict: str
    scope: str                    # the sizes the row ended up reading, in words


# ---- record selection -------------------------------------------------------------------------
def latest(recs: list[Record]) -> list[Record]:
    """One record per framework, variant and size: the last stored (stores merge oldest first).
    A parameter an older record lacks was added to its scenario since and the record ran at its
    default, so its size is read with the scenario's defaults filled in (projectile's ``batch``)
    and a newer record of the same cell replaces it."""
    seen: dict[tuple[Any, ...], Record] = {}
    for r in recs:
        d = data.defaults(r.scenario)
        full = r if all(k in (r.params or {}) for k in d) else r.replace(params={**d, **(r.params or {})})
        seen[(r.backend, r.scenario, r.device, r.precision, r.variant,
              data.size(full), data.at_defaults(r))] = r
    return list(seen.values())


def _pool(m: Machine, device: str, scenario: str, precision: str = "float32",
          sweep: tuple[str | None, ...] = (None, "bandwidth", "scaling")) -> list[Record]:
    return latest([r for r in m.records if r.device == device and r.scenario == scenario
                   and r.precision == precision and data.tag(r, "sweep") in sweep
                   and r.variant not in NOT_SAME_WORK])


def _largest(recs: list[Record]) -> list[Record]:
    """The records at the largest size that at least two frameworks ran ok (else any)."""
    sizes: dict[float, set[str]] = {}
    for r in recs:
        if r.status == "ok":
            sizes.setdefault(data.size(r), set()).add(r.backend)
    good = [s for s, bs in sizes.items() if len(bs) >= 2] or list(sizes)
    if not good:
        return []
    top = max(good)
    return [r for r in recs if data.size(r) == top]


def defaults_of(scenario: str, precision: str = "float32") -> Callable[[Machine, str], list[Record]]:
    def pick(m: Machine, device: str) -> list[Record]:
        return [r for r in _pool(m, device, scenario, precision, (None,)) if data.at_defaults(r)]
    return pick


def largest_of(scenario: str, sweep: tuple[str | None, ...] = (None, "bandwidth", "scaling")
               ) -> Callable[[Machine, str], list[Record]]:
    def pick(m: Machine, device: str) -> list[Record]:
        return _largest(_pool(m, device, scenario, "float32", sweep))
    return pick


def all_defaults(m: Machine, device: str) -> list[Record]:
    return latest([r for r in m.run if r.device == device and r.precision == "float32"
                   and r.variant == "default" and data.at_defaults(r)
                   and data.tag(r, "sweep") is None])


# ---- row figures ------------------------------------------------------------------------------
def regime(name: str) -> Callable[[Record], Timing | None]:
    return lambda r: data.per_call(r, name)


def rate(r: Record) -> float | None:
    return data.item_rate(r)


ERROR_FLOOR = 1e-3                # a share of the bound below this counts as this (exact results)


def error_share(r: Record) -> float | None:
    """A record's error against the float64 oracle as a share of its derived tolerance."""
    e = r.error or {}
    err, tol = data.num(e.get("vs_oracle")), data.num(e.get("tolerance"))
    return err / tol if err is not None and tol else None


def _error_geomean(recs: list[Record]) -> float | None:
    shares = [error_share(r) for r in recs]
    if not shares or any(s is None for s in shares):
        return None
    return math.exp(sum(math.log(max(s, ERROR_FLOOR)) for s in shares) / len(shares))


def _sum_first(recs: list[Record]) -> float | None:
    ts = [data.timing(r, "first") for r in recs]
    return sum(t.median for t in ts) if ts and all(ts) else None


# Per-framework aggregates over several scenarios: (records of one framework) -> figure.
AGGREGATES: dict[str, Callable[[list[Record]], float | None]] = {
    "accuracy": _error_geomean, "compile": _sum_first}
IN_ALL = tuple(n for n, sc in scenarios.SCENARIOS.items() if sc.in_all)   # the scenarios of `all`


def _geomean_vs_best(m: Machine, device: str) -> dict[str, Cell]:
    """CPU-only use: per framework, the geometric mean over the scenarios of its throughput-regime
    time divided by the fastest framework's on that scenario."""
    recs = all_defaults(m, device)
    best: dict[str, float] = {}
    times: dict[tuple[str, str], float] = {}
    for r in recs:
        t = data.per_call(r, "throughput") if r.status == "ok" else None
        if t is not None:
            times[(r.backend, r.scenario)] = t.median
            best[r.scenario] = min(best.get(r.scenario, math.inf), t.median)
    cells = {}
    for fw in sorted({r.backend for r in recs}):
        mine = {r.scenario: r for r in recs if r.backend == fw}
        bad = next((r for r in mine.values() if r.status != "ok"), None)
        if bad is not None or any(s not in mine for s in best):
            cells[fw] = Cell(fw, None, status=bad.status if bad else "absent",
                             reason=(bad.reason if bad else "") or "not every scenario measured")
            continue
        logs = [math.log(times[(fw, s)] / best[s]) for s in best if (fw, s) in times]
        if len(logs) != len(best):
            cells[fw] = Cell(fw, None, status="absent", reason="a scenario has no timing")
            continue
        cells[fw] = Cell(fw, math.exp(sum(logs) / len(logs)), status="ok", variant="default")
    return cells


def _cells(rule: Rule, m: Machine, device: str) -> dict[str, Cell]:
    if rule.key == "cpu":
        return _geomean_vs_best(m, device)
    recs = rule.pick(m, device)
    cells: dict[str, Cell] = {}
    if rule.key in AGGREGATES:
        for fw in sorted({r.backend for r in recs}):
            mine = [r for r in recs if r.backend == fw]
            bad = next((r for r in mine if r.status != "ok"), None)
            missing = {r.scenario for r in recs} - {r.scenario for r in mine}
            v = None if bad or missing else AGGREGATES[rule.key](mine)
            cells[fw] = Cell(fw, v, status="ok" if v is not None else (bad.status if bad else "absent"),
                             reason="" if v is not None else (bad.reason if bad else "") or "not every scenario measured",
                             variant="default")
        return cells
    for r in recs:
        fw = r.backend
        fig = rule.figure(r) if r.status == "ok" else None
        val = fig.median if isinstance(fig, Timing) else fig
        if val is None:
            if fw not in cells:      # keep why a framework has no figure, unless it has one
                cells[fw] = Cell(fw, None, status=r.status if r.status != "ok" else "absent",
                                 reason=r.reason or "no figure of this kind in its record")
            continue
        cur = cells.get(fw)
        better = cur is None or cur.value is None or (
            val < cur.value if rule.better == "lower" else val > cur.value)
        if better:
            lo, hi, noisy = (fig.lo, fig.hi, fig.noisy) if isinstance(fig, Timing) else (None, None, "")
            cells[fw] = Cell(fw, val, lo, hi, r.variant, "ok", "", noisy)
    return cells


def _verdict(rule: Rule, cells: dict[str, Cell], best: str | None, fmt: Callable[[float, str], str]) -> str:
    if best is None:
        return "No framework has a figure for this row in these records."
    near = [c.framework for c in cells.values() if c.ratio is not None and c.ratio <= WITHIN]
    text = f"Best: {best} ({fmt(cells[best].value, rule.unit)})."
    others = [f for f in near if f != best]
    text += f" Within 10 % of it: {', '.join(others)}." if others else " No other framework within 10 %."
    failed = [c.framework for c in cells.values() if c.status in ("error", "mismatch")]
    if failed:
        text += f" Failed: {', '.join(failed)}."
    noisy = [c.framework for c in cells.values() if c.noisy]
    if noisy:
        text += f" Noisy: {', '.join(noisy)}."
    return text


def evaluate(rule: Rule, m: Machine, fmt: Callable[[float, str], str]) -> Row:
    device = rule.device or m.primary_device
    cells = _cells(rule, m, device)
    values = {f: c.value for f, c in cells.items() if c.value is not None and c.value > 0}
    best = (min if rule.better == "lower" else max)(values, key=values.get) if values else None
    if best is not None:
        b = values[best]
        cells = {f: dataclasses.replace(c, ratio=(c.value / b if rule.better == "lower" else b / c.value)
                                        if c.value is not None and c.value > 0 else None)
                 for f, c in cells.items()}
    recs = rule.pick(m, device) if rule.key != "cpu" else all_defaults(m, device)
    return Row(rule, device, cells, best, _verdict(rule, cells, best, fmt), scope(recs))


def scope(recs: list[Record]) -> str:
    """The sizes a row read, in words (``n = 268435456``)."""
    seen = []
    for r in recs:
        sc = r.scenario
        s = data.size(r)
        words = f"{sc} at defaults" if data.at_defaults(r) else f"{sc} {_size_words(r, s)}"
        if words not in seen:
            seen.append(words)
    return "; ".join(seen)


def _size_words(r: Record, s: float) -> str:
    p = r.params or {}
    k = "n" if "n" in p else "batch" if "batch" in p else "size"
    e = math.log2(s) if s > 0 else 0
    return f"{k} = 2^{e:.0f}" if s > 0 and e == int(e) else f"{k} = {s:g}"
