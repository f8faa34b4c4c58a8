"""The sitting check: is this machine session (a *sitting*) as quiet as the machine kind's quiet ones?

Processes on lent machines disagree by up to 1.6x between sittings, and the driver's empty-kernel
launch shows it before any framework runs (docs/measurement.md, "The sitting check"). So before
anything is timed, a check (``sitting_from``; ``compare.running.sitting_run.check_sitting`` measures
it) looks at what pyperf's ``system show`` / ``check`` look at
that can move a figure here:

- the launch floor, with a synchronise (``launch_latency_s``) and pipelined, and the null call's
  spread (IQR / median of the synchronised empty launches): from several CUDA yardstick processes
  (``compare.running.hardware``; a process's floor sits at one of two levels, ``of_processes``); on
  the CPU the harness's null call
  (``compare.measuring.timing.null_call``), recorded, never judged (its spread is the clock's grain);
- the copy yardstick (the same module's copy, on the CPU without its curve of sizes);
- host load: the 1-minute load average and the cores other processes used over ``WINDOW_S``
  (/proc/stat, ``compare.measuring.noise.HostMeter``);
- the GPU (NVML, ``compare.measuring.nvml``): other processes running compute on it, the SM clock
  and the clocks-throttle reasons, decoded to names.

Each figure is None where it cannot be read (no GPU, no NVML, no /proc), and ``notes`` says why.
``judge`` compares a check with the quiet sittings of its machine kind learned from the stored
runs (``compare.measuring.sitting_quiet``); the run keeps its checks (``sitting``:
``{"start": ..., "end": ...}``, ``compare.running.sitting_run``).
"""
from __future__ import annotations

import dataclasses
import math
import os
import time
from typing import Any, Mapping, Sequence, TypedDict

from compare.measuring import noise
from compare.results.environment import QuietSittings, Yardstick
from compare.results.record_parts import Part

WINDOW_S = 0.25           # the host meter's window: long enough for /proc/stat's 10 ms ticks
FLOOR_RATIO = 1.25        # a launch floor above this times the quiet one is noisy
COPY_RATIO = 1.25         # a copy below the quiet one over this is noisy
NULL_SPREAD = 0.10        # the empty launches' IQR above this share of their median is noisy
BUSY_SHARE = 0.25         # other processes on more than this share of the cores is noisy
SLOW_SHARE = 0.7          # CUDA: a launch limit counts when this share of the check's processes is over it
# NVML's clocks-throttle (clocks-event) reason bits (nvml.h): a name for each
THROTTLE_BITS = {0x1: "gpu_idle", 0x2: "applications_clocks_setting", 0x4: "sw_power_cap",
                 0x8: "hw_slowdown", 0x10: "sync_boost", 0x20: "sw_thermal_slowdown",
                 0x40: "hw_thermal_slowdown", 0x80: "hw_power_brake_slowdown", 0x100: "display_clock_setting"}
# the reasons that slow an idle GPU's next kernels (the card protecting itself); the others are an
# idle card's clock management (gpu_idle, the power cap) or settings
SLOWING = ("hw_slowdown", "sw_thermal_slowdown", "hw_thermal_slowdown", "hw_power_brake_slowdown")


@dataclasses.dataclass(frozen=True, eq=False)
class SittingCheck(Part):
    """One sitting check (``sitting_from``): its figures, each None where not read."""
    device: str = "cpu"
    measured: str | None = None               # ISO time (UTC) it was taken
    gpu: str | None = None                    # the machine kind: the GPU's name, else the CPU's
    cpu: str | None = None
    cpu_id: str | None = None                 # family, model, stepping
    cores: int | None = None
    launch_latency_s: float | None = None     # the empty kernel: launch + synchronise (median)
    launch_pipelined_s: float | None = None   # ... pipelined, per launch
    null_spread: float | None = None          # IQR / median of the null calls
    null_how: str | None = None
    # CUDA: the launch figures above stand for this many yardstick processes (of_processes), each listed
    processes: int | None = None
    launch_latency_each_s: tuple[float, ...] | None = None
    launch_pipelined_each_s: tuple[float, ...] | None = None
    copy_bytes_per_s: float | None = None
    loadavg_1m: float | None = None
    others_cores: float | None = None         # cores other processes used over the window
    host_cores: int | None = None             # ... of the host's
    window_s: float | None = None
    gpu_processes: tuple[int, ...] | None = None      # other processes running compute on the GPU
    sm_clock_hz: float | None = None
    sm_clock_max_hz: float | None = None
    throttle_reasons: tuple[str, ...] | None = None
    seconds: float | None = None              # what the check took
    notes: tuple[str, ...] = ()               # why a figure is missing


def throttle_names(mask: int) -> tuple[str, ...]:
    """NVML's throttle-reason bit mask as names (an unknown bit as its hex value)."""
    names = [n for bit, n in THROTTLE_BITS.items() if mask & bit]
    rest = mask & ~sum(THROTTLE_BITS)
    return tuple(names + ([hex(rest)] if rest else []))


class HostFigures(TypedDict, total=False):
    window_s: float
    loadavg_1m: float
    host_cores: int
    others_cores: float


class GpuFigures(TypedDict, total=False):
    gpu_processes: tuple[int, ...]
    sm_clock_hz: float
    sm_clock_max_hz: float
    throttle_reasons: tuple[str, ...]


class NullFigures(TypedDict):
    null_spread: float | None
    null_how: str


def host_figures(window_s: float = WINDOW_S) -> HostFigures:
    """The load average and the cores other processes used over ``window_s`` (this process idle)."""
    out: HostFigures = {"window_s": window_s}
    try:
        out["loadavg_1m"] = os.getloadavg()[0]
    except OSError:
        pass
    meter = noise.HostMeter()
    time.sleep(window_s)
    load = meter.stop()
    out["window_s"], out["host_cores"] = round(load["measured_s"], 4), load["cores"]
    if "others_cores" in load:
        out["others_cores"] = round(load["others_cores"], 3)
    return out


def gpu_figures() -> tuple[GpuFigures, list[str]]:
    """Other compute processes on the GPU, its SM clock and throttle reasons (NVML), and notes."""
    from compare.measuring.nvml import open_nvml
    nv, why = open_nvml("cuda")
    if nv is None:
        return {}, [why or "NVML unavailable"]
    out: GpuFigures = {}
    notes: list[str] = []
    lib, h = nv.nv, nv.handle
    try:
        procs = lib.nvmlDeviceGetComputeRunningProcesses(h)
        out["gpu_processes"] = tuple(sorted(int(p.pid) for p in procs if p.pid != os.getpid()))
    except Exception as exc:  # a figure lost is a figure lost, never the check
        notes.append(f"GPU processes: {type(exc).__name__}: {exc}")
    try:
        out["sm_clock_hz"] = lib.nvmlDeviceGetClockInfo(h, lib.NVML_CLOCK_SM) * 1e6
        out["sm_clock_max_hz"] = lib.nvmlDeviceGetMaxClockInfo(h, lib.NVML_CLOCK_SM) * 1e6
    except Exception as exc:
        notes.append(f"SM clock: {type(exc).__name__}: {exc}")
    reasons = (getattr(lib, "nvmlDeviceGetCurrentClocksEventReasons", None)
               or getattr(lib, "nvmlDeviceGetCurrentClocksThrottleReasons", None))
    try:
        if reasons is None:
            raise AttributeError("no clocks-event reasons in this nvidia-ml-py")
        out["throttle_reasons"] = throttle_names(int(reasons(h)))
    except Exception as exc:
        notes.append(f"throttle reasons: {type(exc).__name__}: {exc}")
    return out, notes


def _cpu_null() -> NullFigures:
    """The harness's null call on the CPU (a no-op and a no-op synchronise): its spread."""
    from compare.measuring import timing
    r = timing.null_call(lambda _: None)
    med, iqr = r.median_s, r.iqr_s
    spread = iqr / med if med and iqr is not None else None
    return {"null_spread": spread, "null_how": f"the harness's null call on the CPU, {r.repeats} calls "
                                              "(not judged: its spread is the clock's grain)"}


def rank(count: int) -> int:
    """The index, in ascending order, of the figure that stands for ``count`` processes: over a
    limit only when at least ``SLOW_SHARE`` of them are (with one process, that one)."""
    return count - math.ceil(round(SLOW_SHARE * count, 9))


def of_processes(yardsticks: Sequence[Yardstick]) -> Yardstick:
    """One yardstick from several processes' of one sitting (none failed). A process's launch floor
    sits at one of two levels, and the share of a sitting's processes at the slower one varies
    between sittings (docs/measurement.md, "The sitting check"), so each launch figure is the one
    that is over its limit only when at least ``SLOW_SHARE`` of the processes' are (``rank``), the
    spread that of the process whose floor it is, and the copy likewise from the fast end."""
    timed = sorted((y for y in yardsticks if y.get("launch_latency_s")), key=lambda y: y["launch_latency_s"])
    out = Yardstick(**(timed[rank(len(timed))] if timed else yardsticks[0]))
    pipelined = sorted(y["launch_pipelined_s"] for y in yardsticks if y.get("launch_pipelined_s"))
    copies = sorted((y["copy_bytes_per_s"] for y in yardsticks if y.get("copy_bytes_per_s")), reverse=True)
    if pipelined:
        out["launch_pipelined_s"] = pipelined[rank(len(pipelined))]
    if copies:
        out["copy_bytes_per_s"] = copies[rank(len(copies))]
    return out


def sitting_from(device: str, hw: Yardstick | Sequence[Yardstick], window_s: float = WINDOW_S) -> SittingCheck:
    """The sitting of ``device`` ('cuda' or 'cpu') now, its launch and copy figures from ``hw``,
    yardsticks just measured (``compare.running.sitting_run.check_sitting`` measures them; ``compare
    all`` adds its own), as ``of_processes`` combines them: the host window and NVML on top, a
    quarter of a second."""
    from compare.measuring import environment
    t0 = time.perf_counter()
    each = [hw] if isinstance(hw, Mapping) else list(hw)
    ok = [y for y in each if not y.get("error")]
    notes = list(dict.fromkeys(f"yardstick: {y.get('error')}" for y in each if y.get("error")))
    hw = of_processes(ok) if ok else Yardstick()      # every process failed: the notes say why
    fig: dict[str, object] = {}
    fig["copy_bytes_per_s"] = hw.get("copy_bytes_per_s")
    if device == "cuda":
        lat, iqr = hw.get("launch_latency_s"), hw.get("launch_latency_iqr_s")
        fig.update(launch_latency_s=lat, launch_pipelined_s=hw.get("launch_pipelined_s"),
                   null_spread=iqr / lat if lat and iqr is not None else None,
                   null_how="the yardstick's empty-kernel launches with a synchronise (IQR / median)",
                   processes=len(ok),
                   launch_latency_each_s=tuple(float(y["launch_latency_s"]) for y in ok if y.get("launch_latency_s")),
                   launch_pipelined_each_s=tuple(float(y["launch_pipelined_s"]) for y in ok
                                                 if y.get("launch_pipelined_s")))
        gpu, more = gpu_figures()
        fig.update(gpu)
        notes += more
    else:
        fig.update(_cpu_null())
    fig.update(host_figures(window_s))
    name = (hw.get("gpu") or next((g["name"] for g in environment.gpus()), None)) if device == "cuda" else None
    return SittingCheck.of(device=device, measured=time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                           gpu=name, cpu=environment.cpu_model(), cpu_id=environment.cpu_id(),
                           cores=environment.usable_cores(),
                           **{k: v for k, v in fig.items() if k in SittingCheck.names()},
                           seconds=round(time.perf_counter() - t0, 3), notes=notes)


def summary(c: SittingCheck) -> str:
    """A check in one line (its figures that were read)."""
    words = []
    if c.launch_latency_s is not None:
        words.append(f"launch + sync {_us(c.launch_latency_s)}")
    if c.launch_pipelined_s is not None:
        words.append(f"pipelined {_us(c.launch_pipelined_s)}")
    if c.processes and c.processes > 1:
        k = rank(c.processes) + 1
        nth = "" if k == 1 else f"{k}{'th' if 10 <= k % 100 <= 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(k % 10, 'th')} "
        words.append(f"{nth}best of {c.processes} processes" + (
            f" (pipelined {min(c.launch_pipelined_each_s) * 1e6:.3g}-{max(c.launch_pipelined_each_s) * 1e6:.3g} us)"
            if c.launch_pipelined_each_s else ""))
    if c.null_spread is not None and c.device == "cuda":
        words.append(f"spread {100 * c.null_spread:.0f} %")
    if c.copy_bytes_per_s:
        words.append(f"copy {_rate(c.copy_bytes_per_s)}")
    if c.others_cores is not None:
        words.append(f"others on {c.others_cores:.2f} of {c.host_cores} cores")
    if c.loadavg_1m is not None:
        words.append(f"load {c.loadavg_1m:.2f}")
    if c.gpu_processes is not None:
        words.append(f"{len(c.gpu_processes)} other GPU processes")
    if c.sm_clock_hz is not None:
        words.append(f"SM {c.sm_clock_hz / 1e6:.0f} MHz")
    if c.throttle_reasons:
        words.append("throttle: " + ", ".join(c.throttle_reasons))
    return ", ".join(words) or "nothing measured"


@dataclasses.dataclass(frozen=True)
class Quiet:
    """The quiet sittings of a machine kind, learned from stored runs (``sitting_quiet``): the
    best quartile of each figure (lowest launch floors, highest copy), and how many runs."""
    kind: str
    runs: int
    launch_latency_s: float | None = None
    launch_pipelined_s: float | None = None
    copy_bytes_per_s: float | None = None

    def to_json(self) -> QuietSittings:
        return QuietSittings(kind=self.kind, runs=self.runs, launch_latency_s=self.launch_latency_s,
                             launch_pipelined_s=self.launch_pipelined_s, copy_bytes_per_s=self.copy_bytes_per_s)

    @classmethod
    def from_json(cls, obj: Mapping[str, Any]) -> Quiet:
        def num(k: str) -> float | None:
            v = obj.get(k)
            return float(v) if isinstance(v, (int, float)) else None
        return cls(kind=str(obj.get("kind", "")), runs=int(obj.get("runs") or 0),
                   launch_latency_s=num("launch_latency_s"), launch_pipelined_s=num("launch_pipelined_s"),
                   copy_bytes_per_s=num("copy_bytes_per_s"))


def _us(s: float) -> str:
    return f"{s * 1e6:.3g} us"


def _rate(bps: float) -> str:
    return f"{bps / 1e12:.3g} TB/s" if bps >= 1e12 else f"{bps / 1e9:.3g} GB/s"


def _spread(sitting: SittingCheck, q: Quiet | None) -> tuple[float | None, str]:
    """The empty launches' IQR as a share of the quiet floor where there is one, else of their own
    median. Their IQR is about the same in every stored H100 sitting, whatever the floor:
    over its own median it would call the fastest sittings the noisiest (docs/measurement.md)."""
    if sitting.null_spread is None:
        return None, ""
    if q is not None and q.launch_latency_s and sitting.launch_latency_s:
        iqr = sitting.null_spread * sitting.launch_latency_s
        return iqr / q.launch_latency_s, f"the quiet floor {_us(q.launch_latency_s)}"
    return sitting.null_spread, "the median"


def judge(sitting: SittingCheck, quiet: Quiet | None) -> tuple[str, ...]:
    """Why ``sitting`` is measurably worse than ``quiet`` (empty: it is not). Thresholds: the
    module's constants (docs/measurement.md, "The sitting check"). Without a quiet reference
    (too few stored runs of the kind) only the absolute checks apply: the spread, other processes
    on the GPU, a slowing throttle reason, a busy host."""
    why: list[str] = []
    q = quiet
    for name, words in (("launch_latency_s", "launch + synchronise"), ("launch_pipelined_s", "pipelined launch")):
        mine, best = getattr(sitting, name), getattr(q, name, None) if q else None
        if mine is not None and best and mine > FLOOR_RATIO * best:
            why.append(f"{words} {_us(mine)}, {mine / best:.2f}x the quiet {_us(best)} (limit {FLOOR_RATIO}x)")
    best_copy = q.copy_bytes_per_s if q else None
    if sitting.copy_bytes_per_s and best_copy and sitting.copy_bytes_per_s * COPY_RATIO < best_copy:
        why.append(f"copy {_rate(sitting.copy_bytes_per_s)}, 1/{best_copy / sitting.copy_bytes_per_s:.2f} "
                   f"of the quiet {_rate(best_copy)} (limit 1/{COPY_RATIO})")
    spread, of = _spread(sitting, q)
    if sitting.device == "cuda" and spread is not None and spread > NULL_SPREAD:
        why.append(f"empty-launch spread {100 * spread:.0f} % of {of} (limit {100 * NULL_SPREAD:.0f} %)")
    if sitting.gpu_processes:
        pids = ", ".join(map(str, sitting.gpu_processes[:5]))
        why.append(f"{len(sitting.gpu_processes)} other process(es) running on the GPU (pid {pids})")
    slowing = [r for r in sitting.throttle_reasons or () if r in SLOWING]
    if slowing:
        why.append("GPU clocks throttled: " + ", ".join(slowing))
    cores = sitting.host_cores or sitting.cores or 1
    busy = max(noise.IDLE_FLOOR, BUSY_SHARE * cores)
    if sitting.others_cores is not None and sitting.others_cores > busy:
        why.append(f"host busy: other processes used {sitting.others_cores:.2f} of {cores} cores "
                   f"(limit {busy:.2f})")
    return tuple(why)


__all__ = ["BUSY_SHARE", "COPY_RATIO", "FLOOR_RATIO", "NULL_SPREAD", "Quiet", "SittingCheck", "THROTTLE_BITS",
           "SLOW_SHARE", "WINDOW_S", "judge", "of_processes", "rank", "sitting_from", "summary", "throttle_names"]
