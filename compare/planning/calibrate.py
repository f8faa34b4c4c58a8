"""Big cells are timed in miniature first: one whose protocol would outlast ``--timeout`` is
skipped with the prediction (and the ``--timeout`` that lets it run) rather than killed after it.

A single CPU call of the B = 2^20 projectile takes minutes where its framework runs one thread,
and the protocol (``compare.measuring.timing``) makes at least five calls. A cell is big when its scenario
says so (``Scenario.scaled``: the same parameters at 1/``FACTOR`` of the size, or None for a cell
too small to matter). Its miniature runs like any cell (own process, empty kernel caches) with two
timed calls; one call of the big cell is predicted as the miniature's median times the ratio of
their work (``Scenario.work``), its compilation as the miniature's, and the number of calls from
the protocol's rules. Miniatures run before any timed cell, one at a time like the cells: side by
side, frameworks that start a thread per core oversubscribe the host (PyTorch's CPU particles ran
300x slower four at once on 16 cores), and a prediction that decides whether a cell runs must come
from the conditions it will run in. Their figures stay out of the results except in a skipped
cell's reason.
"""
from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import sys
import threading
from typing import Any, Callable, Iterator, NamedTuple

import scenarios
from compare.running import cells
from compare.measuring.timing import BATCH_S
from compare.results.record_parts import Timing
from compare.spec import Cell
from scenarios.base import Precision

FACTOR = 64
# A miniature's own timeout: a small share of --timeout, not under MINIATURE_MIN_S (an interpreter,
# a framework's import and its first compilation: up to 30 s a CPU first call in the CPU store)
# nor over --timeout. One that runs out predicts nothing; its cell then decides for itself.
MINIATURE_SHARE = 1 / 8
MINIATURE_MIN_S = 120.0
Refusal = Callable[[Cell], "tuple[str, str] | None"]


def protocol_calls(per_call: float, cell: Cell) -> float:
    """Calls the timing protocol makes after the first, for calls of ``per_call`` seconds
    (``timing.steady_state``, ``timing.pipelined``, the graph regime on a GPU)."""
    per_call = max(per_call, 1e-9)
    warm = min(cell.warmup, max(1, math.ceil(cell.max_time / per_call)))
    steady = max(min(3, cell.repeat), min(max(cell.repeat, math.ceil(cell.min_time / per_call)),
                                          math.ceil(cell.max_time / per_call)))
    regime = 0.0
    if cell.throughput:
        # the doubling probe and 5 batches of at least BATCH_S; none where one call fills a batch
        regime = 0.0 if per_call >= BATCH_S else min(8 * BATCH_S, cell.max_time) / per_call
        if cell.device != "cpu":                                            # graph replays
            regime += min(6.0, 1.0 + cell.max_time / per_call)
    return warm + steady + regime


def _items(sc: Any, params: Any, precision: Precision) -> float:
    w = sc.work(params, precision)
    for k in ("items", "flops", "bytes"):
        if w.get(k):
            return float(w[k])
    return 0.0


def items(cell: Cell) -> float:
    """The cell's size in its scenario's work units (what a miniature scales down)."""
    return _items(scenarios.get(cell.scenario), cell.params, cell.precision)


def predict(cell: Cell, small: Cell, t: Timing) -> tuple[float, float]:
    """(seconds the big cell's protocol takes, seconds of one of its calls) from its miniature's
    ``time`` block."""
    sc = scenarios.get(cell.scenario)
    ratio = _items(sc, cell.params, cell.precision) / max(_items(sc, small.params, small.precision), 1e-300)
    per_call = t.median_s * ratio
    compile_s = max(0.0, t.first_call_s - t.median_s)
    return compile_s + per_call * (1 + protocol_calls(per_call, cell)), per_call


def miniature(cell: Cell, factor: int = FACTOR) -> Cell | None:
    """The cell at 1/``factor`` of its size, timed with two calls and not checked; None for a
    cell not big."""
    params = scenarios.get(cell.scenario).scaled(cell.params, factor)
    if params is None:
        return None
    return dataclasses.replace(cell, params=params, warmup=0, repeat=2, min_time=0.0, throughput=False,
                               host_profile=0, save_outputs=False, save_inputs=False, tags={},
                               check=False)     # its timing alone: the oracle is no clock's business


def _when(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h"


class Miniature(NamedTuple):
    """A big cell's miniature and what its one run found (its status, time block and peak RSS)."""
    cell: Cell
    status: str
    time: Timing | None
    peak_host_rss_bytes: float | None

    @classmethod
    def of(cls, cell: Cell, got: cells.Result) -> Miniature:
        """From the worker's record (its JSON) of the miniature ``cell``."""
        rec = got[0]
        peak = (rec.get("memory") or {}).get("peak_host_rss_bytes")
        return cls(cell, str(rec.get("status")), Timing.from_json(rec["time"]) if rec.get("time") else None,
                   float(peak) if peak else None)


Miniatures = dict[tuple[Any, ...], Miniature]


def miniature_timeout(timeout: float | None) -> float | None:
    """A miniature's timeout under the cells' ``timeout`` (None: none)."""
    return None if timeout is None else min(timeout, max(MINIATURE_MIN_S, MINIATURE_SHARE * timeout))


@contextlib.contextmanager
def _progress(total: int, factor: int, limit: float | None) -> Iterator[Callable[[str | None], None]]:
    """A progress bar on stderr while miniatures run, its clock ticking each second: on a terminal
    only, erased when done (a refusal stays one line; CI logs and pipes get nothing: the cells'
    records say it). Yields ``step``: a cell's name as its miniature starts, None as it ends."""
    if not total or os.environ.get("CI") or not sys.stderr.isatty():
        yield lambda name: None
        return
    from tqdm import tqdm
    cap = f", at most {limit:g} s each" if limit is not None else ""
    bar = tqdm(total=total, unit="run", leave=False, file=sys.stderr,
               desc=f"big cells at 1/{factor} of their size{cap}")
    stop = threading.Event()

    def tick() -> None:
        while not stop.wait(1.0):
            bar.refresh()
    ticker = threading.Thread(target=tick, daemon=True)
    ticker.start()
    try:
        yield lambda name: bar.set_postfix_str(name) if name is not None else bar.update(1)
    finally:
        stop.set()
        ticker.join()
        bar.close()


def run_miniatures(plan: list[Cell], timeout: float | None, factor: int = FACTOR,
                   run: Callable[[Cell], cells.Result] | None = None) -> Miniatures:
    """(miniature, its record) of every big cell of ``plan`` at 1/``factor`` of its size, by
    the big cell's key (``key``), one at a time, each within ``miniature_timeout(timeout)``."""
    pairs = [(c, m) for c in plan if (m := miniature(c, factor)) is not None]
    limit = miniature_timeout(timeout)
    run = run or (lambda c: cells.run(c, limit))
    got = {}
    with _progress(len(pairs), factor, limit) as step:
        for cell, small in pairs:
            step(f"{cell.backend} {cell.device} {cell.precision} {cell.scenario}")
            got[key(cell)] = Miniature.of(small, run(small))
            step(None)
    return got


def time_refusal(plan: list[Cell], timeout: float | None,
                 run: Callable[[Cell], cells.Result] | None = None,
                 minis: Miniatures | None = None) -> Refusal:
    """A ``refuse`` for ``engine.run_cells``: the big cells of ``plan`` (those not refused
    otherwise: pass only runnable cells) whose predicted protocol outlasts ``timeout``.
    ``minis``: their miniatures already run (``run_miniatures``), else run here."""
    if timeout is None:
        return lambda cell: None
    minis = run_miniatures(plan, timeout, run=run) if minis is None else minis
    verdicts: dict[tuple[Any, ...], tuple[str, str]] = {}
    for cell in plan:
        if key(cell) not in minis:
            continue
        mini = minis[key(cell)]
        if mini.status not in ("ok", "mismatch") or not mini.time:
            continue                  # the cell itself will say what is wrong
        total, per_call = predict(cell, mini.cell, mini.time)
        if total > timeout:
            verdicts[key(cell)] = ("skipped", (
                f"predicted to take about {_when(total)} here (one call about {_when(per_call)}, from a "
                f"1/{FACTOR}-size run), over --timeout {timeout:g} s; --timeout {math.ceil(total * 1.5)} runs it"))
    return lambda cell: verdicts.get(key(cell))


def key(cell: Cell) -> tuple[Any, ...]:
    return (cell.scenario, cell.backend, str(cell.device), str(cell.precision), cell.variant, repr(cell.params))
