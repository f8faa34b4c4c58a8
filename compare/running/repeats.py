"""Repeats across processes: one published figure from several independent worker processes.

Within one process the timed calls agree (that is what ``time.noise`` judges); between processes
they do not (fresh address space, allocator, clocks, a different physical page layout: up to 1.6x on
the lent GPUs with 1 % spread inside each, as first seen; the stores' spans: docs/measurement.md).
So a cell whose figure is published runs in ``processes`` worker processes: the first is the
ordinary run (checked against the oracle); the others time the same cell again without the check
(``Cell.check``), in rounds, every round over every cell still open in a seeded shuffle, so that
drift of the host reaches every framework alike.

Per figure (latency, throughput, graph, device events, time to first result = set-up + first
call, from the cold processes alone) the record keeps every process's value and the median with its distribution-free interval
(order statistics of the binomial: the narrowest ``[x_(j), x_(n+1-j)]`` whose coverage is at least
``CONFIDENCE``; with fewer than 6 processes no such pair exists, the interval is the range and its
coverage, below 95 %, is stored). ``auto``: processes are added until every figure's interval
lies within ``TARGET`` of its median, from ``AUTO_MIN`` to ``AUTO_MAX`` processes.

Time to first result needs cold kernel caches, the other figures do not: a first call that
compiles for a minute (MLX's) would otherwise fill every repeat process. So the first processes of
a cell start from empty caches, the last of them keeps its caches in a directory
(``Cell.cache_dir``) that the later processes start from (their ``time.cache`` says ``kept``), and
the first-result figure is the cold processes' (it does not keep a round open after them). How
many are cold is the caller's, per cell (``run_rounds``' ``cold``, default ``COLD``): the driver
gives the default variant ``COLD``, whose first result the first-call row and the compile page
publish, and every other variant 1, its first process (no page reads a non-default variant's first
result; what their cold compiles cost: docs/measurement.md, the matrix part of publish).

A cell may stop before the others (``run_rounds``' ``most``, per cell): the driver stops a cell
whose timings no row ranks on its device after the processes its first result needs; its block
says so (``capped``), one with a single process carries no figures (its record's own are it).
"""
from __future__ import annotations

import math
import random
import statistics
import sys
import time
from typing import Callable, Mapping, Sequence

from compare.results.record_parts import Figure, Processes, Timing

CONFIDENCE = 0.95
TARGET = 0.05            # stop when the interval is within +-5 % of the median
AUTO_MIN, AUTO_MAX = 6, 10
COLD = 3                 # processes with cold caches (a default variant's): the first-result figure's
FIGURES = Processes.FIGURES


def interval(values: Sequence[float], confidence: float = CONFIDENCE) -> tuple[float, float, float]:
    """(low, high, coverage) of the median of ``values``: order statistics, no distribution assumed."""
    x = sorted(values)
    n = len(x)
    if n == 0:
        raise ValueError("no values")
    best = (x[0], x[-1], 1.0 - 2.0 * 0.5 ** n if n > 1 else 0.0)
    for j in range(1, n // 2 + 1):       # [x_(j), x_(n+1-j)], 1-based
        tail = sum(math.comb(n, i) for i in range(j)) / 2 ** n
        cover = 1.0 - 2.0 * tail
        if cover < confidence:
            break
        best = (x[j - 1], x[n - j], cover)
    return best


def figures(t: Timing) -> dict[str, float]:
    """One process's figures from its record's ``time`` block."""
    out: dict[str, float] = {}
    for name in ("latency", "throughput", "graph", "events"):
        part = t.regime(name)
        v = part.median_s if part is not None else None
        if isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0:
            out[name] = float(v)
    first, setup = t.get("first_call_s"), t.get("setup_s")
    if kept(t):
        return out
    if isinstance(first, (int, float)) and isinstance(setup, (int, float)):
        out["first_result"] = float(first) + float(setup)
    return out


def kept(t: Timing) -> bool:
    """The process started from the kernel caches an earlier one of its cell left (not cold)."""
    return str(t.get("cache") or "").startswith("kept")


def summary(times: Sequence[Timing], failed: int = 0, capped: str = "") -> Processes:
    """``time.processes`` from the time blocks of every process of a cell (the first included);
    ``failed``: the repeat processes that failed (counted where any did); ``capped``: why the cell
    stopped before the others (kept where given)."""
    each = [figures(t) for t in times]
    found: dict[str, Figure] = {}
    for name in FIGURES:
        vals = [f[name] for f in each if name in f]
        if not vals:
            continue
        lo, hi, cover = interval(vals)
        found[name] = Figure.of(values=vals, median_s=statistics.median(vals), ci_lo_s=lo, ci_hi_s=hi,
                                confidence=round(cover, 4))
    return Processes.of(count=len(times), order="rounds, a seeded shuffle of the open cells in each",
                        interval="order statistics of the median (distribution-free)", **found,
                        **({"failed": failed} if failed else {}), **({"capped": capped} if capped else {}))


def settled(block: Processes, target: float = TARGET, confidence: float = CONFIDENCE,
            closed: Sequence[str] = ()) -> bool:
    """Every figure's interval (at ``confidence``) lies within ``target`` of its median; the
    ``closed`` figures (no further process adds to them) are not asked."""
    for name in FIGURES:
        f = block.figure(name)
        if f is None or name in closed:
            continue
        if f.confidence < confidence:
            return False
        m = f.median_s
        if f.ci_lo_s < (1 - target) * m or f.ci_hi_s > (1 + target) * m:
            return False
    return True


def plan(processes: int | str) -> tuple[int, int]:
    """(fewest, most) processes a cell runs in: a count N is (N, N); 'auto' (AUTO_MIN, AUTO_MAX)."""
    if processes == "auto":
        return AUTO_MIN, AUTO_MAX
    n = int(processes)
    return n, n


def run_rounds(first: Mapping[int, Timing], processes: int | str, seed: int,
               time_round: Callable[[list[int], int], Sequence[Timing | None]],
               on_round: Callable[[dict[int, Processes]], None],
               fits: Callable[[float], bool] | None = None,
               cold: Mapping[int, int] | None = None, most: Mapping[int, int] | None = None,
               capped: str = "") -> dict[int, Processes]:
    """More processes for the cells in ``first`` (index -> the first process's ``time`` block):
    rounds 2, 3, ..., each over the cells still open in a shuffle seeded by ``seed`` and the round.
    ``time_round(order, round)`` runs each cell of ``order`` once more, in that order (one after
    another, or with set-ups side by side: ``compare.running.overlap``; past the cell's cold
    processes with its kept caches, ``Cell.cache_dir``), and returns their time blocks in that order
    (None: it failed, counted). ``on_round`` gets ``{i: time.processes}`` of the cells the round
    changed. ``fits(seconds)``: whether a round of that length still fits the run's sitting
    (``--sitting``), asked before each round past the fewest with the last round's length.
    ``cold``: per cell, how many of its processes start from empty caches (default ``COLD``); its
    first-result figure is closed after them. ``most``: per cell, the most processes it runs in
    (default: the plan's); a cell stopped below the fewest keeps ``capped`` in its block, and one
    of a single process gets its block (no figures) before round 2. Returns the same for all."""
    fewest, top = plan(processes)
    last_s = 0.0
    times: dict[int, list[Timing]] = {i: [t] for i, t in first.items()}
    failed: dict[int, int] = {i: 0 for i in first}
    colds = {i: (cold or {}).get(i, COLD) for i in first}
    tops = {i: max(1, min(top, (most or {}).get(i, top))) for i in first}
    why = {i: capped if tops[i] < fewest else "" for i in first}
    blocks = {i: Processes.of(count=1, **({"capped": why[i]} if why[i] else {})) for i in first if tops[i] == 1}
    if blocks:
        on_round(dict(blocks))

    def still_open(i: int, rnd: int) -> bool:
        closed = ("first_result",) if rnd > colds[i] else ()     # a later process is not cold
        return rnd <= tops[i] and (rnd <= fewest or not settled(summary(times[i]), closed=closed))
    for rnd in range(2, top + 1):
        open_ = [i for i in times if still_open(i, rnd)]
        if not open_ or (rnd > fewest and fits is not None and not fits(last_s)):
            break
        random.Random(seed * 1000 + rnd).shuffle(open_)
        began = time.monotonic()
        got = list(time_round(open_, rnd))
        last_s = time.monotonic() - began
        if len(got) != len(open_):
            raise RuntimeError(f"repeats: {len(got)} time blocks for a round of {len(open_)} cells")
        for i, t in zip(open_, got):
            if t is None:
                failed[i] += 1
            else:
                times[i].append(t)
        changed = {}
        for i in open_:
            blocks[i] = changed[i] = summary(times[i], failed[i], why[i])
        on_round(changed)
    return blocks


def within(ends: float, sitting: float) -> Callable[[float], bool]:
    """``--sitting``: whether a round of so many seconds, started now, ends by ``ends``
    (time.perf_counter); says so on stderr when it would not."""
    def fits(round_s: float) -> bool:
        left = ends - time.perf_counter()
        if round_s <= left:
            return True
        print(f"  no more processes: a round takes about {round_s:.0f} s, {max(left, 0.0):.0f} s of "
              f"the {sitting:g} s sitting are left", file=sys.stderr, flush=True)
        return False
    return fits


def say_short(counts: Mapping[int, int], processes: int | str, most: Mapping[int, int]) -> int:
    """How many of the ok cells ``--resume`` keeps (``counts``: each one's processes) ran in fewer
    processes than ``processes`` asks (their cap, ``most``, where lower): a run cut off in its
    repeat rounds, or one that asked for fewer. Said on stderr: their figures keep the count they
    reached, because a process of another sitting added to a cell's interval would mix two
    sittings in one figure; the full count needs the run again without ``--resume``."""
    want = plan(processes)[0]
    short = [i for i, n in counts.items() if n < min(want, most.get(i, want))]
    if short:
        print(f"  --resume keeps {len(short)} cell{'s' if len(short) != 1 else ''} with fewer processes than asked (a run cut off in its "
              "repeat rounds, or one that asked for fewer): they keep the count they reached, since processes of another sitting would "
              "mix two sittings in one figure; run again without --resume for the full count",
              file=sys.stderr, flush=True)
    return len(short)
