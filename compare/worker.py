"""One cell, in its own process: ``python -m compare.worker SPEC.json OUT_DIR``.

Process-global framework state (ti.init's precision, JAX's x64 flag, CUDA contexts) lives and dies
with this process, and a crash here becomes an ``error`` record in the parent, not a lost run.
Writes OUT_DIR/record.json and OUT_DIR/outputs.npz (the outputs, for cross-backend comparison).

Spec keys beyond the cell's identity (all optional): ``repeat``, ``min_time``, ``max_time``
(timing.steady_state); ``cache`` 'cold' (default: every framework's on-disk kernel cache pointed
at an empty directory, so the first call compiles) or 'warm' (the framework defaults, noted as
such); ``timer`` 'auto' (CUDA events where the framework has them) or 'wall'; ``check_sample`` k
(check k evenly spaced items against the oracle when n > k, for per-item scenarios at sizes where
a full float64 oracle would dominate the run); ``save_outputs`` (default true); ``save_inputs``.
"""
from __future__ import annotations

import ctypes
import dataclasses
import json
import os
import platform
import sys
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

import backends
import scenarios
from compare import timing


def jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        x = float(x)
        return x if np.isfinite(x) else str(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def peak_rss_bytes() -> int:
    """Peak resident set size of this worker (the cell alone: each cell has its own process).

    VmHWM (Linux) belongs to this process image only. getrusage's ru_maxrss would not do: Linux
    carries the parent's high-water mark across fork + exec, so a large driver process (a sweep
    holding references and outputs) would set a floor under every cell's figure.
    """
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) * 1024                          # kB
    except (OSError, ValueError, IndexError):
        pass
    import resource
    scale = 1 if sys.platform == "darwin" else 1024                          # bytes on macOS, KiB on Linux
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * scale


def injected_fault(spec: dict[str, Any]) -> str | None:
    """Test hook: COMPARE_FAULT="<scenario>/<backend>:<kind>" (kind: crash, hang, raise, mismatch, oom)
    makes matching cells misbehave, so the driver's handling of each failure can be tested."""
    rule = os.environ.get("COMPARE_FAULT", "")
    if ":" not in rule:
        return None
    target, kind = rule.rsplit(":", 1)
    return kind if target == f"{spec['scenario']}/{spec['backend']}" else None



# Where each framework keeps compiled kernels between processes. 'cold' points every one at an
# empty directory inside the cell's own temporary directory (deleted with it), so first_call_s
# always includes compilation; Taichi's offline cache is also off in its setup(), Numba caches on
# disk only for cache=True functions (none here), and JAX's persistent cache is off by default.
CACHE_DIRS = {"WARP_CACHE_PATH": "warp", "CUDA_CACHE_PATH": "cuda-driver-jit",
              "TI_OFFLINE_CACHE_FILE_PATH": "taichi", "NUMBA_CACHE_DIR": "numba"}


def apply_cache_policy(policy: str, out_dir: Path) -> str:
    """Set the framework cache locations (before any framework is imported); returns the note."""
    if policy == "warm":
        return "warm: framework default caches, which may hold kernels compiled by earlier runs"
    if policy != "cold":
        raise ValueError(f"cache must be 'cold' or 'warm', got {policy!r}")
    for var, sub in CACHE_DIRS.items():
        (out_dir / "cache" / sub).mkdir(parents=True, exist_ok=True)
        os.environ[var] = str(out_dir / "cache" / sub)
    os.environ.pop("JAX_COMPILATION_CACHE_DIR", None)
    os.environ["JAX_ENABLE_COMPILATION_CACHE"] = "false"
    return ("cold: empty " + ", ".join(CACHE_DIRS) + "; JAX persistent cache off; "
            "Taichi offline_cache off")


class _NvmlMem(ctypes.Structure):
    _fields_ = [("total", ctypes.c_ulonglong), ("free", ctypes.c_ulonglong),
                ("used", ctypes.c_ulonglong)]


class _NvmlProc(ctypes.Structure):
    _fields_ = [("pid", ctypes.c_uint), ("usedGpuMemory", ctypes.c_ulonglong),
                ("gpuInstanceId", ctypes.c_uint), ("computeInstanceId", ctypes.c_uint)]


class Nvml:
    """Device memory from NVML (the driver's libnvidia-ml, through ctypes: no Python package).

    NVML has no per-process peak, so the worker samples at the cell's milestones and keeps the
    largest value; it reports this process's usage where NVML lists our PID (not inside some
    containers' PID namespaces), and otherwise the whole device's usage minus a baseline taken
    before the framework started. Framework-independent, so it is recorded for every CUDA cell.
    """

    def __init__(self) -> None:
        self.lib = ctypes.CDLL("libnvidia-ml.so.1")
        if self.lib.nvmlInit_v2() != 0:
            raise OSError("nvmlInit failed")
        visible = os.environ.get("CUDA_VISIBLE_DEVICES", "0").split(",")[0].strip()
        self.handle = ctypes.c_void_p()
        idx = int(visible) if visible.isdigit() else 0
        if self.lib.nvmlDeviceGetHandleByIndex_v2(idx, ctypes.byref(self.handle)) != 0:
            raise OSError(f"no NVML device {idx}")
        self.baseline = self.device_used()
        self.peak_device = self.baseline
        self.peak_process: int | None = None

    def device_used(self) -> int:
        mem = _NvmlMem()
        if self.lib.nvmlDeviceGetMemoryInfo(self.handle, ctypes.byref(mem)) != 0:
            raise OSError("nvmlDeviceGetMemoryInfo failed")
        return int(mem.used)

    def process_used(self) -> int | None:
        for name in ("nvmlDeviceGetComputeRunningProcesses_v3", "nvmlDeviceGetComputeRunningProcesses_v2"):
            fn = getattr(self.lib, name, None)
            if fn is None:
                continue
            count = ctypes.c_uint(256)
            procs = (_NvmlProc * 256)()
            if fn(self.handle, ctypes.byref(count), procs) != 0:
                return None
            for p in procs[:count.value]:
                if p.pid == os.getpid() and p.usedGpuMemory < 2**63:   # 2^64-1: not available
                    return int(p.usedGpuMemory)
            return None
        return None

    def sample(self) -> None:
        try:
            self.peak_device = max(self.peak_device, self.device_used())
            mine = self.process_used()
        except Exception:  # a reading lost is a sample lost, never the cell
            return
        if mine is not None:
            self.peak_process = max(self.peak_process or 0, mine)

    def figures(self) -> dict[str, Any]:
        out: dict[str, Any] = {"nvml_device_used_before_bytes": self.baseline,
                               "nvml_device_delta_peak_bytes": self.peak_device - self.baseline}
        if self.peak_process is not None:
            out["nvml_process_peak_bytes"] = self.peak_process
            out["nvml_source"] = "NVML, this process, max of samples after set-up, first call, steady state"
        else:
            out["nvml_source"] = ("NVML, whole device minus the use before the framework started "
                                  "(this PID not listed by NVML), max of samples")
        return out


def open_nvml(device: str) -> tuple[Nvml | None, str | None]:
    if device != "cuda":
        return None, None
    try:
        return Nvml(), None
    except Exception as exc:  # no driver library, or no device
        return None, f"NVML unavailable: {type(exc).__name__}: {exc}"


def device_memory(be: Any, device: str) -> dict[str, Any]:
    """The backend's own device-memory figures; a failing reader is noted, not fatal."""
    try:
        return be.memory(device)
    except Exception as exc:
        return {"device_memory_error": f"{type(exc).__name__}: {exc}"}


def sample_items(params: Any, inputs: dict[str, np.ndarray], outputs: dict[str, np.ndarray],
                 k: int) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], int] | None:
    """k evenly spaced items (first and last included) of a per-item scenario, or None.

    Per-item: every input and output array is indexed by item along axis 0 (scalars pass through),
    so the oracle of the sampled inputs is the sample of the oracle (saxpy, copy, launch, particles
    without trajectories). Anything else is checked in full.
    """
    n = getattr(params, "n", None)
    if not k or n is None or n <= k:
        return None
    arrays = list(inputs.values()) + list(outputs.values())
    if any(np.ndim(a) and np.shape(a)[0] != n for a in arrays):
        return None
    idx = np.unique(np.linspace(0, n - 1, k).round().astype(np.int64))
    pick = lambda d: {key: (np.asarray(a)[idx] if np.ndim(a) else a) for key, a in d.items()}  # noqa: E731
    return pick(inputs), pick(outputs), int(idx.size)


def run_cell(spec: dict[str, Any], out_dir: Path, cache_note: str = "") -> dict[str, Any]:
    """Build, time, download and check one cell. Exceptions propagate (the parent records them)."""
    sc = scenarios.get(spec["scenario"])
    be = backends.get(spec["backend"])
    device, precision, variant = spec["device"], spec["precision"], spec.get("variant", "default")
    params = sc.params(spec.get("params", {}), quick=spec.get("quick", False))
    inputs = sc.inputs(params, precision)

    nvml, nvml_note = open_nvml(device)       # baseline before the framework touches the GPU
    be.setup(device, precision, variant)
    sync = lambda r: be.synchronize(device, r)  # noqa: E731
    t0 = time.perf_counter()
    kernel = be.kernel(sc.name)(params, inputs, device, precision, variant)
    sync(None)
    setup_s = time.perf_counter() - t0
    if nvml:
        nvml.sample()
    first_call_s = timing.call(kernel.run, sync)
    if nvml:
        nvml.sample()
    timer, clock = timing.event_timer(be.name, device, spec.get("timer", "auto"))
    t = timing.steady_state(kernel.run, sync, repeat=spec.get("repeat", 10),
                            min_time=spec.get("min_time", 0.2), max_time=spec.get("max_time", 10.0),
                            timer=timer)
    if nvml:
        nvml.sample()
    t0 = time.perf_counter()
    outputs = {k: np.asarray(v) for k, v in kernel.outputs().items()}
    download_s = time.perf_counter() - t0

    fault = injected_fault(spec)
    if fault == "crash":
        os.abort()
    if fault == "hang":
        time.sleep(10**6)
    if fault == "raise":
        raise RuntimeError("injected fault")
    if fault == "oom":   # out of memory, safely: cap this process's address space, then exceed it
        import resource
        resource.setrlimit(resource.RLIMIT_AS, (2**31, resource.getrlimit(resource.RLIMIT_AS)[1]))
        np.ones(2**31, dtype=np.float64)
    if fault == "mismatch":
        outputs = {k: v + np.asarray(1, v.dtype) if v.dtype.kind == "f" else v for k, v in outputs.items()}

    sampled = sample_items(params, inputs, outputs, int(spec.get("check_sample") or 0))
    c_in, c_out = (sampled[0], sampled[1]) if sampled else (inputs, outputs)
    reference = sc.oracle(params, c_in)
    check = sc.check(params, c_in, c_out, reference, precision)
    work = sc.work(params, precision)
    record: dict[str, Any] = {
        "status": "ok" if check.ok else "mismatch",
        "reason": "" if check.ok else f"error {check.error:.3g} exceeds tolerance {check.tolerance:.3g}",
        "params": dataclasses.asdict(params),
        "time": {"first_call_s": first_call_s, **t, "setup_s": setup_s, "download_s": download_s,
                 "clock": timing.CLOCK if "events_error" in t else clock,
                 "timer": "events" if timer is not None and "events_error" not in t else "wall",
                 "first_call_clock": timing.CLOCK, "cache": cache_note},
        "error": {"vs_oracle": check.error, "tolerance": check.tolerance, "vs_warp": None,
                  **{k: v for k, v in check.details.items()},
                  "checked_items": f"{sampled[2]} of {params.n} (evenly spaced)" if sampled else "all"},
        "work": work,
        "throughput": {f"{k}_per_s": v / t["median_s"] for k, v in work.items() if t["median_s"] > 0},
        "memory": {"peak_host_rss_bytes": peak_rss_bytes(), **device_memory(be, device),
                   **(nvml.figures() if nvml else {}), **({"nvml_note": nvml_note} if nvml_note else {})},
        "info": kernel.info(),
        "host": platform.node(),
        "host_load_1m": os.getloadavg()[0],   # other processes on the host perturb CPU timings
        "versions": be.versions(),
    }
    if sc.has_gradient:
        record["gradient"] = {
            "method": be.gradient_method,
            "value": outputs["grad"],
            "reference": check.details.get("gradient_reference"),
            "reference_value": reference["grad"],
            "vs_oracle": check.details.get("gradient_error"),
            "vs_oracle_rel": check.details.get("gradient_rel_error"),
            "vs_fd64_rel": check.details.get("gradient_vs_fd64_rel"),
            "tolerance": check.details.get("gradient_tolerance"),
        }
    if spec.get("save_outputs", True):
        np.savez(out_dir / "outputs.npz", **outputs)
    if spec.get("save_inputs"):
        np.savez(out_dir / "inputs.npz", **inputs)
    return record


def main(argv: list[str]) -> int:
    spec = json.loads(Path(argv[0]).read_text())
    out_dir = Path(argv[1])
    try:
        cache_note = apply_cache_policy(spec.get("cache", "cold"), out_dir)
        record = run_cell(spec, out_dir, cache_note)
    except Exception as exc:  # the record says what went wrong; the parent keeps going
        record = {"status": "error", "reason": f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}",
                  "traceback": traceback.format_exc()}
    (out_dir / "record.json").write_text(json.dumps(jsonable(record)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
