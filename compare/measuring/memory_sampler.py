"""NVML sampled through the cell's calls: the device-memory peak between the worker's milestones.

NVML keeps no per-process peak, and a reading after a call misses what the call held only while it
ran (a reverse sweep's tape, a compile's workspace, a pool grown and trimmed). ``Sampler`` polls
``Nvml.poll`` (this process's and the whole device's used memory) from a daemon thread every
``INTERVAL_S`` while it is on; the worker keeps it beside the milestone samples, and the record's
``device_bytes`` is the largest of both (``compare.measuring.nvml``).

When it runs, and why not during the timed regimes: a poll is two NVML queries (the process list
query walks the driver's process table, tens of microseconds to a millisecond of a core) plus the
Python around them, which needs the GIL. In the latency and throughput regimes, calls of a few
microseconds would share the interpreter and the cores with it, and ``compare.measuring.timing``
promises nothing of ours between a call's two clock reads. So the sampler is on during

* the first call (``first_call_s`` is the build and one run, milliseconds to minutes, where a poll's
  tens of microseconds on another core are lost in the figure; its transients, such as a compile's
  or an autotuner's workspace, happen nowhere else), and
* an untimed *memory pass* after the timed regimes (``memory_pass``): the same ``run()`` +
  synchronise, at least one call and until ``MEMORY_PASS_S``, so a steady-state call's transient
  peak is sampled at ``INTERVAL_S`` through a whole call (a long call) or at many phases of many
  calls (a short one);

and off during the latency, event, throughput and graph regimes. A failed poll is a sample lost
(counted in ``errors``), never the cell; ``stop`` always ends the thread.
"""
from __future__ import annotations

import threading
import time
from typing import Any, Callable, Protocol

INTERVAL_S = 0.002       # 2 ms: a 180-step reverse sweep at scale lasts tens of milliseconds or more
MEMORY_PASS_S = 0.2      # the memory pass: at least one call, and calls until this much time


class Polled(Protocol):
    def poll(self) -> None: ...          # a reading for the sampling thread's peak

    def sample(self) -> None: ...        # a milestone reading


class Sampler:
    """Calls ``target.poll()`` every ``interval_s`` on a daemon thread between ``start`` and ``stop``;
    ``milestone()`` takes a milestone reading. With no target (no NVML: a CPU cell, or NVML
    unavailable) it does nothing and reports nothing."""

    def __init__(self, target: Polled | None, interval_s: float = INTERVAL_S) -> None:
        self.target, self.interval_s = target, interval_s
        self.polls = self.errors = 0
        self.on_s = 0.0                          # seconds the sampler was on, all windows together
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._since = 0.0

    def _loop(self) -> None:
        assert self.target is not None
        while True:
            try:
                self.target.poll()
                self.polls += 1
            except Exception:  # a reading lost is a sample lost, never the cell
                self.errors += 1
            if self._stop.wait(self.interval_s):
                return

    def milestone(self) -> None:
        if self.target is not None:
            self.target.sample()

    def start(self) -> None:
        if self._thread is not None or self.target is None:
            return
        self._stop.clear()
        self._since = time.perf_counter()
        self._thread = threading.Thread(target=self._loop, name="nvml-sampler", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stops the thread after one last poll: a peak at the window's end is seen too."""
        if self._thread is None:
            return
        self._stop.set()
        self._thread.join(timeout=5.0)
        self._thread = None
        self.on_s += time.perf_counter() - self._since
        try:
            assert self.target is not None
            self.target.poll()
            self.polls += 1
        except Exception:  # as in the loop: a sample lost
            self.errors += 1

    def __enter__(self) -> Sampler:
        self.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    def figures(self) -> dict[str, int | float]:
        if self.target is None:
            return {}
        return {"nvml_sample_interval_s": self.interval_s, "nvml_samples": self.polls,
                "nvml_sampled_s": round(self.on_s, 4), **({"nvml_sample_errors": self.errors} if self.errors else {})}


def memory_pass(run: Callable[[], Any], sync: Callable[[Any], None], sampler: Sampler,
                min_time: float = MEMORY_PASS_S, max_calls: int = 10_000) -> dict[str, int | float | str]:
    """Untimed ``run(); sync()`` calls with the sampler on: at least one, until ``min_time``.
    Returns ``nvml_memory_pass_calls`` and ``nvml_memory_pass_s`` ({} with nothing to sample: no
    call made); a failing call ends the pass (the timed regimes already ran the same call) and is
    noted, never raised."""
    if sampler.target is None:
        return {}
    calls, t0, note = 0, time.perf_counter(), dict[str, str]()
    with sampler:
        try:
            while calls < max_calls:
                sync(run())
                calls += 1
                if time.perf_counter() - t0 >= min_time:
                    break
        except Exception as exc:  # the figure loses its pass, the cell keeps its measurements
            note = {"nvml_memory_pass_error": f"{type(exc).__name__}: {str(exc).strip()[:200]}"}
    return {"nvml_memory_pass_calls": calls, "nvml_memory_pass_s": round(time.perf_counter() - t0, 4), **note}
