"""Where a run's time goes: each cell's parts (``time.phases`` of its record) and the run's own.

A worker splits its cell's life into the parts below (seconds, wall clock); the driver adds the
run's parts (probing the frameworks, the yardstick, the cells, writing tables and pictures) and
prints one summary line, so a slow run says which part to cut. Only the timed parts (warm-up and
latency, throughput, graph, host profile, null call, own timer) are measurement; the rest is what a run pays to get there.
"""
from __future__ import annotations

import os
import time
from typing import Iterable

from compare.results.record_parts import Timing

LAUNCHED_ENV = "COMPARE_LAUNCHED_AT"     # the driver's time.time() when it started the worker

# a cell's parts, in the order they happen, with the words the summary uses
CELL_PARTS = {
    "start": "process start and imports",
    "inputs": "inputs",
    "framework": "framework set-up",
    "floor": "the cell's own launch floor (two probes, CUDA)",
    "wait": "waiting for its turn (an overlapped run)",
    "build": "kernel build",
    "first_call": "compile and first call",
    "steady": "warm-up and latency",
    "throughput": "throughput",
    "memory_pass": "memory pass (NVML sampled, untimed)",
    "download": "download",
    "graph": "graph",
    "host_profile": "host profile",
    "null": "null call",
    "own_timer": "the framework's own timer (cross-check)",
    "check": "oracle and check",
    "record": "the record (kernel facts, versions, memory)",
    "save": "saving arrays",
}
TIMED = ("steady", "throughput", "graph", "host_profile", "null", "own_timer")


class Laps:
    """A stopwatch whose laps are named parts: ``lap("build")`` ends the part begun at the last lap."""

    def __init__(self, start_s: float = 0.0) -> None:
        self.spent: dict[str, float] = {"start": start_s} if start_s > 0 else {}
        self._t = time.perf_counter()

    def lap(self, part: str) -> None:
        now = time.perf_counter()
        self.spent[part] = self.spent.get(part, 0.0) + now - self._t
        self._t = now


def since_launch() -> float:
    """Seconds since the driver started this worker (0 when it did not say: a Dask task)."""
    try:
        return max(0.0, time.time() - float(os.environ.get(LAUNCHED_ENV, "")))
    except ValueError:
        return 0.0


def cell_parts(times: Iterable[Timing | None]) -> dict[str, float]:
    """The cells' parts summed over their processes' ``time`` blocks (None: a process that timed nothing)."""
    total: dict[str, float] = {}
    for t in times:
        for part, s in ((t.phases if t is not None else None) or {}).items():
            total[part] = total.get(part, 0.0) + float(s)
    return total


def summary_line(run: dict[str, float], cells: dict[str, float], n_cells: int) -> str:
    """One line: the run's wall time and its parts, then the cells' time by part: shares of the
    cells' wall time, or, where workers overlapped (``compare.running.overlap``), of the workers' summed
    time with waits at the gate left out; what no worker accounts for is the driver's and the
    processes' exits."""
    wall = sum(run.values())
    head = ", ".join(f"{name} {s:.3g} s" for name, s in run.items() if s >= 0.05)
    line = f"time: {n_cells} cells in {wall:.3g} s ({head})"
    in_cells = run.get("cells", 0.0)
    if in_cells <= 0 or not cells:
        return line
    timed = sum(cells.get(p, 0.0) for p in TIMED)
    work = {p: s for p, s in cells.items() if p != "wait" and s > 0}
    total = sum(work.values())
    overlapped = total > 1.02 * in_cells
    parts = sorted(((s, CELL_PARTS.get(p, p)) for p, s in work.items()), reverse=True)
    shares = ", ".join(f"{name} {100 * s / (total if overlapped else in_cells):.0f} %" for s, name in parts[:6])
    if overlapped:
        return (f"{line}; the workers' {total:.3g} s overlapped into the cells' {in_cells:.3g} s, "
                f"{100 * timed / in_cells:.0f} % of them measurement; the workers' time: {shares}")
    other = max(0.0, in_cells - total)
    return (f"{line}; of the cells' time {100 * timed / in_cells:.0f} % is measurement; "
            f"{shares}; driver and exits {100 * other / in_cells:.0f} %")
