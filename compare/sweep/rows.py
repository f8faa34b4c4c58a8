"""A sweep's records found by their tags (``rec.tags``: sweep kind, role, knob) and read: the
helpers the page, the horizon section and the plots share (compare/sweep/page.py, horizon.py,
plots.py), kept apart so that none of those imports another only for these."""
from __future__ import annotations

from typing import Any, Iterable, Literal

import scenarios
from compare.results.record import Block, Check, Converged, Record, Timing
from compare.measuring.timing import events_of
from compare.sweep.points import Knob, sweeps


def tag(rec: Record, name: str) -> Any:
    return (rec.tags or {}).get(name)


def knob(rec: Record) -> Knob:
    """The knob a sweep record's cell set (its ``tags.knob``, stored from ``Knob.to_json``);
    ``Knob("")`` where it set none."""
    k = tag(rec, "knob") or {}
    return Knob(k.get("name", ""), k.get("value"))


def knob_value(rec: Record) -> float:
    """The knob's value where a reader computes with it (sorts, divides, draws it on a log axis):
    a number in an ok sized record (``compare.sweep.format`` refuses one without on load)."""
    v = knob(rec).value
    if not isinstance(v, (int, float)):
        raise TypeError(f"{rec.key}: a sweep record without a numeric knob value, where one is read")
    return v


def need(rec: Record, block: Literal["params", "time", "error", "work", "memory"]) -> Block:
    """``rec``'s ``block`` where a sweep reader indexes it directly: an ok, timed sweep record has
    it (``compare.results.records`` refuses one without it on load; the callers filter on what they
    read), so a missing one is a bug upstream, raised here by name."""
    b = getattr(rec, block)
    if b is None:
        raise TypeError(f"{rec.key}: a sweep record without its {block} block, where one is read")
    return b


def converged(rec: Record) -> Converged:
    """``rec``'s converged error where a sweep reader reads it (an error point has one; ``need``)."""
    c = rec.converged
    if c is None:
        raise TypeError(f"{rec.key}: a sweep record without its converged block, where one is read")
    return c


def ok(records: Iterable[Record], sweep: str | None = None, role: str | None = None,
       **match: Any) -> list[Record]:
    """ok records with timings, of one sweep kind / role (tags) and matching fields."""
    return [r for r in records if r.status == "ok" and r.time
            and (sweep is None or tag(r, "sweep") == sweep) and (role is None or tag(r, "role") == role)
            and all(getattr(r, k) == v for k, v in match.items())]


def label(scenario: str, what: str, default: str = "") -> str:
    """A scenario's word for the sweep page (``points.Sweeps.labels``); 'name' defaults to its
    name, 'items' to what the scenario calls one item (``Scenario.item``)."""
    if what == "items" and what not in sweeps(scenario).labels:
        default = scenarios.get(scenario).item or default
    return sweeps(scenario).labels.get(what, scenario if what == "name" else default)


def timed(rec: Record) -> Timing:
    """``rec.time`` where a sweep reader reads it directly (as ``need``)."""
    if rec.time is None:
        raise TypeError(f"{rec.key}: a sweep record without its time block, where one is read")
    return rec.time


def checked(rec: Record) -> Check:
    """``rec.error`` where a sweep reader reads it directly (as ``need``)."""
    if rec.error is None:
        raise TypeError(f"{rec.key}: a sweep record without its error block, where one is read")
    return rec.error


def checked_items(rec: Record) -> str:
    """What the oracle checked ('all', or a sample: '4096 of 16777216 (evenly spaced)')."""
    c = checked(rec).checked_items
    return c if c is not None else "all"


def wall_s(rec: Record) -> float:
    t = timed(rec)
    return float(t.wall.median_s if t.wall and t.wall.median_s is not None else t.median_s)


def event_s(rec: Record) -> float | None:
    ev = events_of(rec.time)
    return float(ev.median_s) if ev and ev.median_s else None


def throughput_s(rec: Record) -> float | None:
    """Per-call time in the throughput regime (k calls, one synchronise), where measured."""
    thr = rec.time.throughput if rec.time else None
    return float(thr.median_s) if thr and thr.median_s else None
