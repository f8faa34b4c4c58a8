"""The one timing protocol every backend is measured with.

1. first call: build + compile + run, synchronised (reported as ``first_call_s``, never mixed
   into the steady state);
2. ``warmup`` more calls, untimed;
3. timed calls, each ``run(); synchronize()`` on a monotonic wall clock (time.perf_counter),
   until at least ``repeat`` calls *and* ``min_time`` seconds have been measured, stopping early
   only when ``max_time`` is exceeded with at least 3 calls;
4. median, inter-quartile range and min of the per-call times.
Host<->device transfers are outside the timed calls (uploads in the kernel's constructor,
downloads in ``outputs()``); both are timed separately.
"""
from __future__ import annotations

import time
from typing import Any, Callable

import numpy as np

CLOCK = "wall clock (time.perf_counter) around run() + backend synchronize"


def call(run: Callable[[], Any], sync: Callable[[Any], None]) -> float:
    t0 = time.perf_counter()
    sync(run())
    return time.perf_counter() - t0


def steady_state(run: Callable[[], Any], sync: Callable[[Any], None], repeat: int = 10,
                 warmup: int = 2, min_time: float = 0.2, max_time: float = 10.0,
                 max_calls: int = 100_000) -> dict[str, Any]:
    for _ in range(warmup):
        call(run, sync)
    times: list[float] = []
    total = 0.0
    while len(times) < max_calls:
        t = call(run, sync)
        times.append(t)
        total += t
        enough = len(times) >= repeat and total >= min_time
        if enough or (total >= max_time and len(times) >= min(3, repeat)):
            break
    return summarise(times)


def summarise(times: list[float]) -> dict[str, Any]:
    a = np.asarray(times)
    q1, med, q3 = np.percentile(a, [25, 50, 75])
    return {"median_s": float(med), "iqr_s": float(q3 - q1), "min_s": float(a.min()),
            "repeats": int(a.size)}
