"""A CUDA cell's own launch floor, probed in its worker beside its timed window (the record's
``cell_floor``, ``compare.results.record_floor``).

The run's yardstick (``compare.running.hardware``) is taken once, at the start of a run, and the
launch floor moves within a sitting, so per-call figures divided by it travel worse than seconds
in a long run (docs/results/h100/evidence/units). A probe is the yardstick's empty kernel (its PTX,
driver signatures and launch closure: ``hardware``), through the driver with ctypes, no memory
allocated:

- latency: one launch + ``cuCtxSynchronize``, the median (and IQR) of up to ``LATENCY`` launches
  after ``WARMUP``;
- pipelined: k launches and one synchronise, / k, the median of up to ``BATCHES`` batches less the
  first; k is ``K`` or fewer where one latency would not fit a batch's share of the budget;
- the launch loops stop at ``BUDGET_S`` whatever the machine: a slow launch gives fewer samples,
  never a longer cell.

When (``Probes``):

- ``before``: in a worker run alone (no gate), after NVML's baseline and before the framework's
  set-up, on the device's primary context (the one the frameworks retain); a primary context the
  probe created stays retained, not current, for the framework to take up (destroying it would
  make the set-up create it again). In an overlapped run (gated) other cells' windows run beside
  the set-up, and no kernel may run beside a window (``compare.running.overlap``): the probe waits
  for its own window to open and runs first in it, before the kernel build, on the primary context.
- ``after``: once the timed regimes end, still inside the window: on the context current on the
  worker's thread (the framework's), else the primary one.
Each probe's ``context`` says which. A probe that fails is an ``error`` string, never the cell's.
"""
from __future__ import annotations

import contextlib
import ctypes
import time
from typing import Any, Callable, Iterator

from compare.measuring.phases import Laps
from compare.results.record_floor import CellFloor, FloorProbe
from compare.running import hardware
from compare.running.hardware import ck

WARMUP, LATENCY, K, BATCHES = 20, 300, 200, 6
FIGURES = ("latency_s", "latency_iqr_s", "pipelined_s", "launches", "k", "batches")    # FloorProbe's order
BUDGET_S = 0.1          # the launch loops' wall-clock bound (a probe's figures take ~10 ms on an H100)
HOW = (f"empty PTX kernel, cuLaunchKernel: latency = launch + cuCtxSynchronize (median of up to {LATENCY} "
       f"after {WARMUP}); pipelined = k launches (k <= {K}), one synchronise, / k (median of up to "
       f"{BATCHES - 1} batches after one); launch loops within {BUDGET_S:g} s")


@contextlib.contextmanager
def on_context(cu: Any, current: bool, keep: bool = False) -> Iterator[str]:
    """A context made current for the probe, in words: the thread's own where ``current`` and the
    thread has one (the framework's), else the device's primary context, retained (where the probe
    created it and ``keep``, kept for the framework to take up; else released). The thread's
    context is put back."""
    ck(cu.cuInit(0), "cuInit")
    dev, prev, primary = ctypes.c_int(), ctypes.c_void_p(), ctypes.c_void_p()
    flags, active = ctypes.c_uint(), ctypes.c_int()
    ck(cu.cuDeviceGet(ctypes.byref(dev), 0), "cuDeviceGet")
    ck(cu.cuCtxGetCurrent(ctypes.byref(prev)), "cuCtxGetCurrent")
    ck(cu.cuDevicePrimaryCtxGetState(dev, ctypes.byref(flags), ctypes.byref(active)), "cuDevicePrimaryCtxGetState")
    ck(cu.cuDevicePrimaryCtxRetain(ctypes.byref(primary), dev), "cuDevicePrimaryCtxRetain")
    keep = keep and not active.value
    try:
        if current and prev.value:
            ctx, words = prev, ("the thread's current context (the framework's): "
                                + ("the primary" if prev.value == primary.value else "not the primary"))
        else:
            made = "created by the probe, " + ("kept for the framework" if keep else "released after")
            ctx, words = primary, "the primary context, " + ("already active" if active.value else made)
        words += f" (flags {flags.value:#x})" if flags.value and ctx.value == primary.value else ""
        ck(cu.cuCtxSetCurrent(ctx), "cuCtxSetCurrent")
        try:
            yield words
        finally:
            cu.cuCtxSetCurrent(prev)
    finally:
        if not keep:
            cu.cuDevicePrimaryCtxRelease_v2(dev)


def probe(current: bool = False, when: str = "", keep: bool = False, budget_s: float = BUDGET_S,
          driver: Callable[[], Any] = hardware.cuda_driver) -> FloorProbe:
    """One probe (``launch_loops``) on ``on_context``; ``when`` prefixes its context's words. Never raises."""
    t0 = time.perf_counter()
    floor: hardware.LaunchFloor = {}
    said: dict[str, str] = {}       # its context, or why it has no figures
    try:
        cu = driver()
        with on_context(cu, current, keep) as words:
            said["context"] = f"{when}{words}"
            mod, fn = hardware.noop_function(cu)
            try:
                floor = hardware.launch_loops(cu, hardware.noop_launcher(cu, fn), budget_s,
                                              WARMUP, LATENCY, K, BATCHES)
            finally:
                cu.cuModuleUnload(mod)
    except Exception as exc:  # the probe is a yardstick beside the cell, never the cell
        said["error"] = f"{type(exc).__name__}: {str(exc).strip()[:200]}"
    got = dict(floor)
    figures = {k: got[k] for k in FIGURES if k in got}
    return FloorProbe.of(**figures, spent_s=time.perf_counter() - t0, **said)


class Probes:
    """A CUDA cell's two probes, at the worker's three points (nothing off CUDA): ``Probes(...)``
    before the framework's set-up, ``gate_opened`` before the kernel build, ``after`` the regimes."""

    def __init__(self, device: str, laps: Laps, gated: bool) -> None:
        self.on, self.laps, self.gated = device == "cuda", laps, gated
        self.before: FloorProbe | None = None
        self.last: FloorProbe | None = None
        if self.on and not gated:
            laps.lap("framework")       # NVML's opening, as before the probe was there
            self.before = probe(when="before the framework's set-up, on ", keep=True)
            laps.lap("floor")

    def gate_opened(self) -> None:
        if self.on and self.gated:
            self.before = probe(when="at its window's opening, the framework set up, on ")
            self.laps.lap("floor")

    def after(self) -> None:
        if self.on:
            self.last = probe(current=True, when="after the timed regimes, on ")
            self.laps.lap("floor")

    def fields(self) -> dict[str, CellFloor]:
        """The record's ``cell_floor`` (nothing off CUDA)."""
        if not self.on:
            return {}
        return {"cell_floor": CellFloor.of(before=self.before, after=self.last, how=HOW)}
