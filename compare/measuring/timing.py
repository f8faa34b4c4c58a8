"""The one timing protocol every backend is measured with (docs/measurement.md is the long form).

1. first call: compile + one run, synchronised, on the wall clock (``first_call_s``, never mixed
   into the steady state); the worker runs it against empty framework caches (``cache`` policy);
2. ``warmup`` more calls, untimed (fewer when they take more than ``max_time``);
3. timed calls, each ``run(); synchronize()``, until at least ``repeat`` calls *and* ``min_time``
   seconds (wall clock) have been measured, stopping early only when ``max_time`` is exceeded with
   at least 3 calls;
4. median, inter-quartile range and min of the per-call times (the *latency* regime: one call and
   its synchronisation, what an interactive caller or a host loop waits);
5. the *throughput* regime (``pipelined``): k back-to-back calls, one synchronisation, time / k,
   what a simulation loop that synchronises rarely pays per call; and, where the backend can
   capture a call as a graph (``Backend.capture``), the same with graph replays.
Every timed call is measured on the wall clock (time.perf_counter) around ``run(); synchronize()``
and nothing else: no event record, meter read or bookkeeping of ours between the two clock reads,
for every framework alike (a pair of event records costs more than a small kernel's launch). On a
GPU, where the framework offers device events (``Backend.event_timer``), a separate pass of calls
is bracketed by two events on the stream the kernels run on: the device's time of a call, stored
as its own figure (``events``), never mixed into the latency. The *null call* (a no-op ``run`` and
the framework's synchronise on an idle device) is timed the same way as the latency: the floor of
what the latency regime can show for that framework (``null``).
Host<->device transfers are outside the timed calls (uploads in the kernel's constructor,
downloads in ``outputs()``); both are timed separately by the worker.
"""
from __future__ import annotations

import time
from typing import Any, Callable, TypedDict

import numpy as np

from backends.base import Backend, Device, EventTimer
from compare.results.record_parts import Regime, Timing

class ProfiledFunction(TypedDict):
    """One function of ``host_profile``: where it is, its own and cumulative seconds per call."""
    function: str
    where: str
    own_s: float
    cumulative_s: float
    calls: float


class HostProfile(TypedDict):
    """``time.host_profile`` (--host-profile): the top functions by own time in the throughput regime."""
    calls: int
    host_s: float
    profiled_s: float
    top: list[ProfiledFunction]


CLOCK = "wall clock (time.perf_counter) around run() + backend synchronize"


def event_timer(backend: Backend, device: Device, mode: str = "auto") -> tuple[EventTimer | None, str]:
    """(timer or None, description of the primary clock) for a cell. mode: 'auto' | 'wall'.
    The timer is the backend's own (``Backend.event_timer``): frameworks without device events
    around a call (Taichi, JAX) are timed on the wall clock alone."""
    if mode == "wall":
        return None, CLOCK
    try:
        timer = backend.event_timer(device)
    except Exception as exc:  # e.g. the CUDA simulator: say why and fall back
        return None, f"{CLOCK} (events unavailable: {type(exc).__name__}: {exc})"
    return (timer, timer.description) if timer is not None else (None, CLOCK)


def call(run: Callable[[], Any], sync: Callable[[Any], None]) -> float:
    t0 = time.perf_counter()
    sync(run())
    return time.perf_counter() - t0


def event_call(run: Callable[[], Any], sync: Callable[[Any], None], timer: EventTimer) -> float:
    """Device seconds of one call between two events (its wall time is not kept: the event
    records sit inside it)."""
    timer.start()
    r = run()
    timer.stop()
    sync(r)
    return timer.elapsed_s()


def steady_state(run: Callable[[], Any], sync: Callable[[Any], None], repeat: int = 10,
                 warmup: int = 2, min_time: float = 0.2, max_time: float = 10.0,
                 max_calls: int = 100_000, timer: EventTimer | None = None) -> Timing:
    """Median/IQR/min of the wall clock around each synchronised call (the latency), plus
    ``wall`` (the same figures, the name older readers use) and, with ``timer``, ``events``: a
    separate pass of at least ``repeat`` calls (and ``min_time / 2`` seconds) timed by device events.
    Warm-up stops early once its calls took ``max_time`` (a cell whose one call takes minutes
    warms up with one call); ``warmup`` in the result is the number made."""
    warm_s, made = 0.0, 0
    while made < warmup and warm_s < max_time:
        warm_s += call(run, sync)
        made += 1
    walls = until(lambda: call(run, sync), repeat, min_time, max_time, max_calls)
    lat = summarise(walls)     # the latency, and how it was reached
    wall = Regime.of(median_s=lat.median_s, iqr_s=lat.iqr_s, min_s=lat.min_s)
    events: dict[str, Regime | str] = {}
    if timer is not None:
        spent = [0.0]

        def timed() -> float:   # the pass's own budget is wall time, events included
            t0 = time.perf_counter()
            ev = event_call(run, sync, timer)
            spent[0] += time.perf_counter() - t0
            return ev
        try:
            evs = until(timed, repeat, min(min_time / 2, max_time), max_time, max_calls, spent)
            events["events"] = Regime.of(**summarise(evs), clock=getattr(timer, "description", "device events"))
        except Exception as exc:  # an event API failing must not cost the cell's latency
            events["events_error"] = f"{type(exc).__name__}: {exc}"
            sync(None)
    return Timing.of(**lat, warmup=made, timed_total_s=float(sum(walls)), wall=wall, **events)


def until(one: Callable[[], float], repeat: int, min_time: float, max_time: float, max_calls: int,
           spent: list[float] | None = None) -> list[float]:
    """Times from ``one()`` until ``repeat`` of them and ``min_time`` of their sum (or of
    ``spent[0]`` where given), stopping early past ``max_time`` with at least 3."""
    times: list[float] = []
    total = 0.0
    while len(times) < max_calls:
        times.append(one())
        total = spent[0] if spent is not None else total + times[-1]
        if (len(times) >= repeat and total >= min_time) or (total >= max_time and len(times) >= min(3, repeat)):
            break
    return times


NULL_CALLS = 200     # the null call's repeats: a few microseconds each


def null_call(sync: Callable[[Any], None], calls: int = NULL_CALLS) -> Regime:
    """The harness's floor: the latency regime's clock around a no-op ``run`` and the
    framework's synchronise (``sync(None)``) on an idle device, ``calls`` times after 10 warm."""
    noop: Callable[[], Any] = lambda: None  # noqa: E731
    for _ in range(10):
        call(noop, sync)
    return summarise([call(noop, sync) for _ in range(calls)])


def events_of(t: Timing | None) -> Regime | Timing | None:
    """A record's ``time`` part's device-event figures (median_s, iqr_s, min_s, repeats), or
    None. Records made before the separate event pass (``timer == "events"`` and no ``events``)
    kept them as the block's own figures."""
    if t is None:
        return None
    if t.events is not None:
        return t.events
    return t if t.timer == "events" else None


BATCH_S = 0.02     # the throughput regime's shortest batch (``pipelined``)


def pipelined(run: Callable[[], Any], sync: Callable[[Any], None], batch_s: float = BATCH_S,
              repeat: int = 5, max_k: int = 1 << 16, max_time: float = 10.0,
              latency: Regime | None = None) -> Regime:
    """The throughput regime: ``k`` back-to-back ``run()`` calls, one synchronise, time / k.

    What a simulation loop that synchronises rarely pays per call: launches are queued while the
    device works, so per-call host overhead hides behind device time (or shows, where the host is
    slower than the device). ``k`` doubles from 1 until one batch lasts at least ``batch_s``
    (stable against the one synchronise and the clock), at most ``max_k``; then ``repeat`` batches
    are timed on the wall clock. Returns median/IQR/min of the per-call time, ``repeats`` and ``k``.
    Where one synchronised call already lasts ``batch_s`` (``latency``'s median, wall clock) the
    batch is one call and one synchronise, which is the latency regime itself: its figures are
    returned (``same_as``) rather than timing the same thing again.
    """
    if latency is not None and (latency.median_s or 0.0) >= batch_s:
        return Regime.of(median_s=latency.median_s, iqr_s=latency.iqr_s, min_s=latency.min_s,
                         repeats=latency.repeats, k=1, host_s=None, same_as="latency")
    k, spent = 1, 0.0
    while True:
        t0 = time.perf_counter()
        r = None
        for _ in range(k):
            r = run()
        sync(r)
        dt = time.perf_counter() - t0
        spent += dt
        if dt >= batch_s or k >= max_k or spent >= max_time:
            break
        k = min(max_k, k * 2 if dt <= 0 else max(k * 2, int(k * batch_s / dt * 1.2)))
    per_call: list[float] = []
    host: list[float] = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(k):
            r = run()
        t1 = time.perf_counter()
        sync(r)
        per_call.append((time.perf_counter() - t0) / k)
        host.append((t1 - t0) / k)
        spent += per_call[-1] * k
        if spent >= max_time and len(per_call) >= 3:
            break
    return Regime.of(**summarise(per_call), k=k, host_s=float(np.median(host)))


def host_profile(run: Callable[[], Any], sync: Callable[[Any], None], calls: int,
                 top: int) -> HostProfile:
    """Where the host's time per call goes in the throughput regime: ``calls`` back-to-back
    ``run()`` under cProfile (which slows Python code, so these are shares, not timings to
    compare with the regimes), then one synchronise. Returns the ``top`` functions by own time,
    each with its own and cumulative time per call and its calls per call; ``where`` is the file
    relative to its installed package (``warp/context.py:1234``) or ``~`` for C functions."""
    import cProfile
    import pstats
    prof = cProfile.Profile()
    r = None
    t0 = time.perf_counter()
    prof.enable()
    for _ in range(calls):
        r = run()
    prof.disable()
    issued = time.perf_counter() - t0
    sync(r)
    # (file, line, name) -> (primitive calls, calls, own, cumulative, callers); the stdlib stubs
    # (typeshed) leave this attribute of pstats.Stats out
    stats = pstats.Stats(prof).stats  # type: ignore[attr-defined]
    rows = sorted(stats.items(), key=lambda kv: kv[1][2], reverse=True)[:top]
    total_own = sum(v[2] for v in stats.values())
    return {"calls": calls, "host_s": issued / calls, "profiled_s": total_own / calls,
            "top": [{"function": name, "where": _where(file, line),
                     "own_s": own / calls, "cumulative_s": cum / calls, "calls": n / calls}
                    for (file, line, name), (_, n, own, cum, _) in rows]}


def _where(file: str, line: int) -> str:
    if file == "~":
        return "~"
    parts = file.replace("\\", "/").split("/")
    for marker in ("site-packages", "dist-packages"):
        if marker in parts:
            parts = parts[parts.index(marker) + 1:]
            break
    else:
        parts = parts[-3:]
    return f"{'/'.join(parts)}:{line}"


def summarise(times: list[float]) -> Regime:
    a = np.asarray(times)
    q1, med, q3 = np.percentile(a, [25, 50, 75])
    return Regime.of(median_s=float(med), iqr_s=float(q3 - q1), min_s=float(a.min()), repeats=int(a.size))
