"""The noise verdict of a timed cell (``time.noise``): can its figures be read as they stand?

A cell is noisy when any of these holds (the thresholds are the page's; docs/measurement.md):

- **spread**: a regime's quartile spread (IQR) above ``SPREAD`` of its median;
- **few repeats**: a regime timed fewer than ``MIN_REPEATS`` times;
- **host busy**: while the cell's clocks ran, other processes used more than ``IDLE_FLOOR`` cores
  (what an idle host's daemons use) and, with the cell's own use, all the cores but
  ``IDLE_FLOOR``: read from /proc/stat against the worker's own CPU time;
- **throughput slower than latency**: the pipelined per-call time above ``SLOW_THROUGHPUT`` times
  the synchronised call's wall time. Queuing calls can only hide host work, so this means the
  host was taken away between calls.

The verdict is stored in the record (``{"noisy", "reasons": [{"regime", "why"}], ...}``) with the
host figures it used; readers show ``~`` beside a noisy figure and the reasons beside the cell.
"""
from __future__ import annotations

import os
import time
from typing import Any, Mapping, NotRequired, TypedDict

from compare.results.record import Record
from compare.results.record_parts import Timing

MARK = "~"            # beside a figure whose cell is noisy, in every table and page
SPREAD = 0.10
MIN_REPEATS = 3
IDLE_FLOOR = 0.25
SLOW_THROUGHPUT = 2.0
REGIMES = ("latency", "throughput", "graph")


def regime_reasons(part: Any) -> list[str]:
    """Spread and repeat count of one regime's timings ({median_s, iqr_s, repeats})."""
    if not isinstance(part, Mapping):
        return []
    med, iqr, reps = part.get("median_s"), part.get("iqr_s"), part.get("repeats")
    why = []
    if isinstance(med, (int, float)) and med > 0 and isinstance(iqr, (int, float)) and iqr / med > SPREAD:
        why.append(f"spread {100 * iqr / med:.0f} % of the median")
    if isinstance(reps, int) and not isinstance(reps, bool) and reps < MIN_REPEATS:
        why.append(f"{reps} repeat{'s' if reps != 1 else ''}")
    return why


def _host_busy_s() -> float | None:
    """CPU seconds all processes of the host have used since boot (/proc/stat), or None."""
    try:
        with open("/proc/stat", "rb") as f:
            fields = f.readline().split()
    except OSError:
        return None
    if not fields or fields[0] != b"cpu" or len(fields) < 8:
        return None
    user, nice, system, _idle, _iowait, irq, softirq = (int(x) for x in fields[1:8])
    steal = int(fields[8]) if len(fields) > 8 else 0
    return (user + nice + system + irq + softirq + steal) / os.sysconf("SC_CLK_TCK")


def _own_cpu_s() -> float:
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


class HostLoad(TypedDict):
    """The host meter's figures: the cores, the seconds measured and, where /proc/stat is read,
    the cell's own use and other processes' use, in cores."""
    cores: int
    measured_s: float
    own_cores: NotRequired[float]
    others_cores: NotRequired[float]


class Reason(TypedDict):
    """One reason a cell's timings are noisy: the regime it concerns ('' for the whole cell) and why."""
    regime: str
    why: str


class Noise(HostLoad):
    """``time.noise``: whether the timings are noisy, why, and the host meter's figures."""
    noisy: bool
    reasons: list[Reason]


class HostMeter:
    """Other processes' CPU use while a cell's clocks run, in cores."""

    def __init__(self) -> None:
        self._start = (time.perf_counter(), _host_busy_s(), _own_cpu_s())

    def stop(self) -> HostLoad:
        wall = time.perf_counter() - self._start[0]
        host, own = _host_busy_s(), _own_cpu_s() - self._start[2]
        cores = os.cpu_count() or 1
        if host is None or self._start[1] is None or wall <= 0:
            return {"cores": cores, "measured_s": wall}
        others = max(0.0, (host - self._start[1]) - own) / wall
        return {"cores": cores, "measured_s": wall, "own_cores": own / wall, "others_cores": others}


def host_reason(host: HostLoad) -> str | None:
    """Busy: other processes used more than an idle host's daemons and, with the cell's own use,
    (nearly) every core. The cell's own use is what it got, not what it wanted: a starved cell
    uses less, so "others above the cores the cell left free" alone would miss it."""
    others, own, cores = host.get("others_cores"), host.get("own_cores"), host.get("cores")
    if others is None or own is None or not cores:
        return None
    if others > IDLE_FLOOR and others + own > cores - IDLE_FLOOR:
        return (f"host busy: other processes used {others:.2f} cores while the cell's clocks ran "
                f"(the cell {own:.2f}, of {cores})")
    return None


def verdict(t: Timing, host: HostLoad) -> Noise:
    """``time.noise`` from a record's ``time`` and the host meter's figures."""
    reasons = [Reason(regime=r, why=why) for r in REGIMES
               for why in regime_reasons(t if r == "latency" else t.get(r))]
    busy = host_reason(host)
    if busy:
        reasons.append(Reason(regime="", why=busy))
    lat, thr = (t.get("wall") or {}).get("median_s"), (t.get("throughput") or {}).get("median_s")
    if isinstance(lat, (int, float)) and isinstance(thr, (int, float)) and lat > 0 and thr > SLOW_THROUGHPUT * lat:
        reasons.append(Reason(regime="throughput", why=f"per call {thr / lat:.1f}x the synchronised call's "
                                                       "wall time (the host was taken between calls)"))
    return Noise(noisy=bool(reasons), reasons=reasons, **host)


def reasons_for(rec: Record, regime: str | None = None) -> list[str]:
    """The record's stored noise reasons that concern ``regime`` (all when None), as text."""
    noise = rec.time.noise if rec.time else None
    out = []
    for r in (noise.reasons if noise else None) or ():
        if regime is None or r.regime in ("", regime):
            out.append(f"{r.regime}: {r.why}" if regime is None and r.regime else r.why)
    return out
