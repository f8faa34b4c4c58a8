"""Framework-neutral hardware yardsticks, measured in the same run as the cells they judge.

No contestant controls them (docs/measurement.md, "Hardware yardstick"):
  * CUDA: a device-to-device ``cuMemcpyDtoDAsync`` of 1 GiB timed with driver events (bandwidth
    = 2 x bytes / time: one read, one write), and an empty kernel (hand-written PTX, loaded with
    ``cuModuleLoadData``) launched with ``cuLaunchKernel``: its latency (launch + synchronise)
    and its pipelined cost (k launches, one synchronise). All through the CUDA driver library
    with ctypes, so no framework's allocator, stream or launch path is involved. The GPU's name
    and maximum SM clock come from NVML.
  * CPU: ``numpy.copyto`` of 128 MiB, in one thread and in one per core (a slice each), the
    faster of the two (bandwidth = 2 x bytes / time).
Run as ``python -m compare.running.hardware DEVICE`` in its own process (it must not share a CUDA
context with a framework); ``measure`` returns its JSON, or ``{"error": reason}``.

The floors each scenario states (``Scenario.floor``) use these figures and, for FLOP floors, the
vendor's stated peak rates below. ``annotated`` adds to each cell ``throughput.floor_s`` (with the
floor's kind and derivation) and ``throughput.hw_fraction`` = floor / throughput-regime time:
1 is the hardware's limit. On the CPU a cell's bandwidth floor uses the copy of the smallest
measured size that moves at least the cell's bytes (``copy_curve``), so a cache-resident cell is
judged against a cache-resident copy; above 1 then means a loose stated floor (FLOPs counted low)
or a cell that beats a plain copy (fewer writes than it counts).
"""
from __future__ import annotations

import ctypes
import json
import math
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from typing import Any, Callable, Mapping, TypedDict

import numpy as np

from compare.measuring import environment
from compare.results.environment import Yardstick
from compare.results.record import Record, plain
from compare.running import reuse

# Stated peak non-tensor FLOP rates (NVIDIA datasheets, boost clock): the FLOP floors' denominators.
STATED_PEAK_FLOPS: dict[str, dict[str, float | str]] = {
    "H100 80GB HBM3": {"float32": 66.9e12, "float64": 33.5e12, "source": "H100 SXM5 datasheet"},
    "H100 PCIe": {"float32": 51.2e12, "float64": 25.6e12, "source": "H100 PCIe datasheet"},
    "H200": {"float32": 66.9e12, "float64": 33.5e12, "source": "H200 SXM datasheet (H100 SXM5 compute)"},
}
PTX = b""".version 7.0
.target sm_70
.address_size 64
.visible .entry noop()
{
	ret;
}
"""


def _median(xs: list[float]) -> float:
    return float(np.median(np.asarray(xs)))


def _copy_seconds(copy: Any, reps: int = 1) -> float:
    """Median of 10 samples of one copy's time; a sample times ``reps`` copies (small copies)."""
    copy()
    times = []
    for _ in range(10):
        t0 = time.perf_counter()
        for _ in range(reps):
            copy()
        times.append((time.perf_counter() - t0) / reps)
    return _median(times)


def copy_in_slices(dst: np.ndarray, src: np.ndarray, pool: ThreadPoolExecutor, parts: int) -> None:
    """``dst[:] = src`` as ``parts`` contiguous slices copied by the pool's threads at once."""
    cut = np.linspace(0, src.size, parts + 1).astype(np.int64)
    list(pool.map(lambda i: np.copyto(dst[cut[i]:cut[i + 1]], src[cut[i]:cut[i + 1]]), range(parts)))


def measure_cpu(curve_sizes: tuple[int, ...] | None = None) -> Yardstick:
    """The faster of one thread's ``numpy.copyto`` and one per core on a slice each (copyto
    releases the GIL): the multi-threaded ports' copies beat one thread's (docs/measurement.md).
    ``curve_sizes``: the smaller copies' sizes (default ``CURVE_BYTES``; the sitting check
    passes none, its figure is the main copy's)."""
    n = 1 << 25                                    # float32: 128 MiB per array
    src = np.ones(n, np.float32)
    dst = np.empty_like(src)
    cores = environment.usable_cores()
    with ThreadPoolExecutor(cores) as pool:
        t1 = _copy_seconds(lambda: np.copyto(dst, src))
        tn = _copy_seconds(lambda: copy_in_slices(dst, src, pool, cores))
        # the same copy at the sizes a cell's working set may have: a cache-resident cell is
        # judged against a copy that fits the same caches (docs/measurement.md)
        curve = []
        for nbytes in CURVE_BYTES if curve_sizes is None else curve_sizes:
            a, b = src[: nbytes // 4], dst[: nbytes // 4]
            reps = max(1, (4 << 20) // nbytes)
            tc = min(_copy_seconds(lambda: np.copyto(b, a), reps),
                     _copy_seconds(lambda: copy_in_slices(b, a, pool, cores), reps))
            curve.append([nbytes, 2.0 * nbytes / tc])
    t, threads = (t1, 1) if t1 <= tn else (tn, cores)
    return Yardstick(copy_bytes_per_s=2.0 * src.nbytes / t, copy_bytes=src.nbytes, copy_median_s=t,
                     copy_one_thread_bytes_per_s=2.0 * src.nbytes / t1, copy_threads=threads,
                     copy_how=f"numpy.copyto of 128 MiB float32 in {threads} thread{'s' * (threads > 1)} "
                              f"(the faster of 1 and {cores}), median of 10 (2 x bytes / time)",
                     copy_curve=curve + [[src.nbytes, 2.0 * src.nbytes / t]])


# bytes per array of the smaller copies (64 KiB to 64 MiB); 128 MiB is the main figure
CURVE_BYTES = tuple(1 << k for k in range(16, 27))


def matched_copy(hw: Yardstick, traffic: float) -> tuple[float, int] | None:
    """(bandwidth, bytes per array) of the measured copy whose traffic (2 x its array: one read,
    one write) is nearest ``traffic`` (by ratio), or None without a curve or traffic."""
    curve = [(nbytes, bw) for nbytes, bw in hw.get("copy_curve") or [] if nbytes > 0 and bw > 0]
    if not curve or not traffic or traffic <= 0:
        return None
    nbytes, bw = min(curve, key=lambda p: abs(math.log(2 * p[0] / traffic)))
    return bw, int(nbytes)


# The driver functions the yardstick and the cells' own floor probes (compare.measuring.cell_floor)
# call, with their ctypes signatures: one definition for both.
_P, _U64, _SZ = ctypes.c_void_p, ctypes.c_uint64, ctypes.c_size_t
SIGNATURES = {
    "cuInit": [ctypes.c_uint], "cuDeviceGet": [ctypes.POINTER(ctypes.c_int), ctypes.c_int],
    "cuDevicePrimaryCtxRetain": [ctypes.POINTER(_P), ctypes.c_int], "cuCtxSetCurrent": [_P],
    "cuDevicePrimaryCtxRelease_v2": [ctypes.c_int], "cuCtxGetCurrent": [ctypes.POINTER(_P)],
    "cuDevicePrimaryCtxGetState": [ctypes.c_int, ctypes.POINTER(ctypes.c_uint), ctypes.POINTER(ctypes.c_int)],
    "cuMemAlloc_v2": [ctypes.POINTER(_U64), _SZ], "cuMemsetD8_v2": [_U64, ctypes.c_ubyte, _SZ],
    "cuMemcpyDtoDAsync_v2": [_U64, _U64, _SZ, _P], "cuEventCreate": [ctypes.POINTER(_P), ctypes.c_uint],
    "cuEventRecord": [_P, _P], "cuEventSynchronize": [_P],
    "cuEventElapsedTime": [ctypes.POINTER(ctypes.c_float), _P, _P],
    "cuModuleLoadData": [ctypes.POINTER(_P), ctypes.c_char_p], "cuModuleUnload": [_P],
    "cuModuleGetFunction": [ctypes.POINTER(_P), _P, ctypes.c_char_p],
    "cuLaunchKernel": [_P] + [ctypes.c_uint] * 7 + [_P, _P, _P], "cuCtxSynchronize": []}


def cuda_driver() -> Any:
    """The CUDA driver library through ctypes, its functions' signatures set (``SIGNATURES``)."""
    cu = ctypes.CDLL("libcuda.so.1")
    for name, args in SIGNATURES.items():
        getattr(cu, name).argtypes = args
    return cu


def ck(r: int, what: str) -> None:
    """A driver call's result: 0, or an OSError naming the call."""
    if r != 0:
        raise OSError(f"{what} failed (CUresult {r})")


def noop_function(cu: Any) -> tuple[Any, Any]:
    """The empty kernel (``PTX``) loaded into the current context: (module, function)."""
    mod, fn = ctypes.c_void_p(), ctypes.c_void_p()
    ck(cu.cuModuleLoadData(ctypes.byref(mod), PTX), "cuModuleLoadData")
    ck(cu.cuModuleGetFunction(ctypes.byref(fn), mod, b"noop"), "cuModuleGetFunction")
    return mod, fn


def noop_launcher(cu: Any, fn: Any) -> Callable[[], None]:
    """One launch of the empty kernel per call: one block of one thread, the default stream (the
    same closure for the yardstick and the cells' probes: the same Python cost per launch)."""
    def launch() -> None:
        ck(cu.cuLaunchKernel(fn, 1, 1, 1, 1, 1, 1, 0, None, None, None), "cuLaunchKernel")
    return launch


class LaunchFloor(TypedDict, total=False):
    """``launch_loops``' figures: an empty launch + synchronise (median, IQR, samples) and one
    launch of k back to back with one synchronise (median over the batches after the first)."""
    latency_s: float
    latency_iqr_s: float
    launches: int
    pipelined_s: float
    k: int
    batches: int


def launch_loops(cu: Any, launch: Callable[[], None], budget_s: float | None, warmup: int, latency: int,
                 k: int, batches: int) -> LaunchFloor:
    """The launch floor from ``launch`` (one empty launch) and the driver's synchronise: ``warmup``
    synchronised launches, ``latency`` timed ones, then ``batches`` of k launches and one synchronise
    (the first batch left out of the median). The yardstick and the cells' own probes
    (``compare.running.cell_floor``) both measure it here. ``budget_s``: the loops stop at it (half for
    the latency, half for the batches; k shrinks so that a batch fits its share), so a slow launch
    gives fewer samples, never a longer cell; None: the counts alone."""
    start = time.perf_counter()
    half, end = (start + budget_s / 2, start + budget_s) if budget_s is not None else (math.inf, math.inf)
    for _ in range(warmup):
        launch()
        ck(cu.cuCtxSynchronize(), "cuCtxSynchronize")
        if time.perf_counter() > half:
            break
    lat: list[float] = []
    while len(lat) < latency and time.perf_counter() < half:
        t0 = time.perf_counter()
        launch()
        ck(cu.cuCtxSynchronize(), "cuCtxSynchronize")
        lat.append(time.perf_counter() - t0)
    out: LaunchFloor = {}
    if lat:
        q1, q2, q3 = np.percentile(np.asarray(lat), [25, 50, 75])
        out["latency_s"], out["latency_iqr_s"], out["launches"] = float(q2), float(q3 - q1), len(lat)
    # a pipelined launch costs no more than one with its synchronise: k sized by the latency fits
    # each batch in its share of the budget (no clock read inside a batch)
    share = budget_s / 2 / batches if budget_s is not None else 0.0
    if budget_s is not None:
        k = max(1, min(k, int(share / max(float(np.median(lat)) if lat else share, 1e-9))))
    piped: list[float] = []
    while len(piped) < batches and time.perf_counter() + share < end:
        t0 = time.perf_counter()
        for _ in range(k):
            launch()
        ck(cu.cuCtxSynchronize(), "cuCtxSynchronize")
        piped.append((time.perf_counter() - t0) / k)
    if piped:
        out["pipelined_s"], out["k"], out["batches"] = float(np.median(piped[1:] or piped)), k, len(piped)
    return out


def measure_cuda() -> Yardstick:
    cu = cuda_driver()
    P, U64 = _P, _U64
    ck(cu.cuInit(0), "cuInit")
    dev, ctx = ctypes.c_int(), P()
    ck(cu.cuDeviceGet(ctypes.byref(dev), 0), "cuDeviceGet")
    ck(cu.cuDevicePrimaryCtxRetain(ctypes.byref(ctx), dev), "cuDevicePrimaryCtxRetain")
    ck(cu.cuCtxSetCurrent(ctx), "cuCtxSetCurrent")
    n = 1 << 30
    src, dst = U64(), U64()
    ck(cu.cuMemAlloc_v2(ctypes.byref(src), n), "cuMemAlloc")
    ck(cu.cuMemAlloc_v2(ctypes.byref(dst), n), "cuMemAlloc")
    ck(cu.cuMemsetD8_v2(src, 1, n), "cuMemsetD8")
    a, b, ms = P(), P(), ctypes.c_float()
    ck(cu.cuEventCreate(ctypes.byref(a), 0), "cuEventCreate")
    ck(cu.cuEventCreate(ctypes.byref(b), 0), "cuEventCreate")
    copies = []
    for i in range(23):                            # 3 warm-up copies, then 20 timed
        ck(cu.cuEventRecord(a, None), "cuEventRecord")
        ck(cu.cuMemcpyDtoDAsync_v2(dst, src, n, None), "cuMemcpyDtoDAsync")
        ck(cu.cuEventRecord(b, None), "cuEventRecord")
        ck(cu.cuEventSynchronize(b), "cuEventSynchronize")
        ck(cu.cuEventElapsedTime(ctypes.byref(ms), a, b), "cuEventElapsedTime")
        if i >= 3:
            copies.append(ms.value * 1e-3)
    _, fn = noop_function(cu)
    floor = launch_loops(cu, noop_launcher(cu, fn), None, warmup=100, latency=2000, k=2000, batches=6)
    t = _median(copies)
    out = Yardstick(copy_bytes_per_s=2.0 * n / t, copy_bytes=n, copy_median_s=t,
                    copy_how="cuMemcpyDtoDAsync of 1 GiB, CUDA events, median of 20 (2 x bytes / time)",
                    launch_latency_s=floor["latency_s"], launch_latency_iqr_s=floor["latency_iqr_s"],
                    launch_pipelined_s=floor["pipelined_s"],
                    launch_how="empty PTX kernel, cuLaunchKernel: latency = launch + cuCtxSynchronize "
                               "(median of 2000); pipelined = 2000 launches, one synchronise, / 2000")
    try:
        import pynvml
        pynvml.nvmlInit()
        h = pynvml.nvmlDeviceGetHandleByIndex(0)
        name = pynvml.nvmlDeviceGetName(h)
        out["gpu"] = name.decode() if isinstance(name, bytes) else name
        out["sm_clock_max_hz"] = pynvml.nvmlDeviceGetMaxClockInfo(h, pynvml.NVML_CLOCK_SM) * 1e6
    except Exception as exc:  # the floors that need them say so
        out["nvml_error"] = f"{type(exc).__name__}: {exc}"
    peak = next((v for k, v in STATED_PEAK_FLOPS.items() if k in out.get("gpu", "")), None)
    if peak:
        out["peak_flops"] = peak
    return out


def measure(device: str, timeout: float = 300.0) -> Yardstick:
    """The yardstick of ``device``, measured in a fresh process; {"error": reason} if it cannot be.
    The process is tied to this driver's life (compare.running.lifeline) as cell workers are: a driver
    killed mid-measurement leaves no yardstick running on."""
    from compare.running import lifeline
    from compare.running.cells import ROOT, worker_env
    try:
        proc = subprocess.run(lifeline.command("compare.running.hardware", device), cwd=ROOT,
                              env=lifeline.child_environment(worker_env()), capture_output=True, text=True,
                              timeout=timeout, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return Yardstick(error=f"yardstick timed out after {timeout:g} s")
    for line in proc.stdout.splitlines():
        if line.startswith("YARDSTICK"):
            return json.loads(line[len("YARDSTICK"):])
    tail = " | ".join(proc.stderr.strip().splitlines()[-2:])
    return Yardstick(error=f"yardstick process failed (exit {proc.returncode}): {tail}")


REUSE_ENV = "COMPARE_YARDSTICK_REUSE"     # a folder: the tests' runs share one yardstick per device


def for_run(device: str) -> Yardstick:
    """A run's yardstick of ``device``: ``measure``d now. Where ``REUSE_ENV`` names a folder (the
    test suite sets it, tests/conftest.py; nothing else does) the first run's, kept there, stands
    for every later run's: the tests check what a run does with its yardstick, and measuring one
    (a process, 128 MiB copies) costs each of their runs seconds on a small host."""
    return reuse.kept(os.environ.get(REUSE_ENV, ""), f"yardstick-{device}.json", lambda: measure(device),
                lambda got: None if "error" in got else json.dumps(got).encode(), json.loads)


def annotated(rec: Record, hardware: Mapping[str, Yardstick]) -> Record:
    """The record judged against its run's yardstick of its device (a new record; the record
    itself where nothing changes): a timed cell (throughput regime) gets the yardstick it was
    judged against (``hardware``) and, where its scenario states a floor, the throughput's
    ``floor_s``, ``floor_kind``, ``floor`` and hardware fraction."""
    import scenarios
    thr = rec.time.throughput if rec.time else None
    hw = hardware.get(rec.device) or Yardstick()
    sc = scenarios.SCENARIOS.get(rec.scenario)
    if rec.status not in ("ok", "mismatch") or not thr or "error" in hw or not hw or sc is None:
        return rec
    # the yardstick the cell was judged against travels with it (pages are functions of records)
    stamp = {k: hw[k] for k in ("copy_bytes_per_s", "copy_how", "launch_pipelined_s",
                                "launch_latency_s", "gpu", "copy_bytes") if k in hw}
    obj = rec.to_json()
    obj["hardware"] = stamp
    params = sc.params(plain(rec.params))
    match = matched_copy(hw, sc.work(params, rec.precision).get("bytes") or 0)
    cell_hw: Yardstick = hw if match is None else {**hw, "copy_bytes_per_s": match[0]}
    floor = sc.floor(params, rec.precision, dict(cell_hw))
    if floor is not None:
        if match is not None and floor["kind"] == "bandwidth" and match[1] < hw.get("copy_bytes", 0):
            floor["derivation"] += (f" of a copy of the same size ({match[1] / 2**20:.3g} MiB per array: "
                                    "it fits the same caches)")
        per_call = thr.median_s
        obj["throughput"] = {**(obj.get("throughput") or {}), "floor_s": floor["seconds"], "floor_kind": floor["kind"],
                             "floor": floor["derivation"],
                             "hw_fraction": floor["seconds"] / per_call if per_call and per_call > 0 else None}
    before = rec.to_json()
    changed = (obj.get("hardware"), obj.get("throughput")) != (before.get("hardware"), before.get("throughput"))
    return Record.from_json(obj) if changed else rec


def main(argv: list[str]) -> int:
    try:
        out = measure_cuda() if argv[0] == "cuda" else measure_cpu()
    except Exception as exc:
        out = {"error": f"{type(exc).__name__}: {exc}"}
    print("YARDSTICK" + json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
