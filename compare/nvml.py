"""Device memory from NVML, for every CUDA cell whatever its framework."""
from __future__ import annotations

import ctypes
import os
from typing import Any


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
