"""Device memory from NVML (nvidia-ml-py), one metric for every CUDA cell whatever its framework.

The figure users compare across frameworks is ``memory.device_bytes``: this process's device
memory at its peak minus a baseline taken *after* the framework's device context exists
(``Backend.ensure_context``), so the CUDA context (hundreds of MiB, the same for every framework)
is left out and what remains is what the cell's allocations, kernels and framework pools hold.
NVML keeps no per-process peak, so the worker reads it two ways and keeps the largest: at the
cell's milestones (``sample``: after set-up, after the first call, after each timing regime) and
from a sampling thread (``poll``, ``compare.measuring.memory_sampler``: every 2 ms through the
first call and an untimed memory pass), which sees what a call holds only while it runs. Both
are kept (``device_bytes_milestones``, ``device_bytes_sampled``). Where NVML does not list
this process (some containers' PID namespaces), the whole device's use is used instead and the
record says so (``device_bytes_source``). A framework's own figure (a pool's high-water mark,
``peak_bytes_in_use``) stays in its own column, ``device_peak_bytes``.
"""
from __future__ import annotations

import os
from typing import Any


class Nvml:
    def __init__(self) -> None:
        import pynvml
        self.nv = pynvml
        pynvml.nvmlInit()
        visible = os.environ.get("CUDA_VISIBLE_DEVICES", "0").split(",")[0].strip()
        if visible.startswith(("GPU-", "MIG-")):
            self.handle = pynvml.nvmlDeviceGetHandleByUUID(visible)
        else:
            self.handle = pynvml.nvmlDeviceGetHandleByIndex(int(visible) if visible.isdigit() else 0)
        self.start_device = self.device_used()         # before the framework touched the GPU
        self.base: tuple[int, int | None] | None = None   # (device, process) after the context
        self.peak_device = self.start_device
        self.peak_process: int | None = None
        self.polled_device: int | None = None          # the sampling thread's peaks (``poll``)
        self.polled_process: int | None = None

    def device_used(self) -> int:
        return int(self.nv.nvmlDeviceGetMemoryInfo(self.handle).used)

    def process_used(self) -> int | None:
        try:
            procs = self.nv.nvmlDeviceGetComputeRunningProcesses(self.handle)
        except self.nv.NVMLError:
            return None
        for p in procs:
            if p.pid == os.getpid() and p.usedGpuMemory is not None:
                return int(p.usedGpuMemory)
        return None

    def mark_baseline(self) -> None:
        """The framework's context exists now: what is in use is the baseline of the metric."""
        try:
            self.base = (self.device_used(), self.process_used())
        except Exception:  # a reading lost is a figure lost, never the cell
            self.base = None
        if self.base:
            self.peak_device, self.peak_process = self.base[0], self.base[1]

    def sample(self) -> None:
        try:
            self.peak_device = max(self.peak_device, self.device_used())
            mine = self.process_used()
        except Exception:  # a reading lost is a sample lost, never the cell
            return
        if mine is not None:
            self.peak_process = max(self.peak_process or 0, mine)

    def poll(self) -> None:
        """One reading of the sampling thread (its own peaks; a failure raises to the sampler,
        which counts it)."""
        dev, mine = self.device_used(), self.process_used()
        self.polled_device = dev if self.polled_device is None else max(self.polled_device, dev)
        if mine is not None:
            self.polled_process = mine if self.polled_process is None else max(self.polled_process, mine)

    def figures(self) -> dict[str, int | str]:
        peak_device = max(self.peak_device, self.polled_device or 0)
        peak_process = max(self.peak_process, self.polled_process or 0) if self.peak_process is not None else None
        out: dict[str, int | str] = {"nvml_device_used_before_bytes": self.start_device,
                                     "nvml_device_delta_peak_bytes": peak_device - self.start_device}
        if peak_process is not None:
            out["nvml_process_peak_bytes"] = peak_process
        if self.base is None:
            return out
        if self.base[1] is not None and self.peak_process is not None:
            base, milestone, polled = self.base[1], self.peak_process, self.polled_process
            out["context_bytes"] = self.base[1]
            whose = "NVML, this process"
        else:
            base, milestone, polled = self.base[0], self.peak_device, self.polled_device
            out["context_bytes"] = self.base[0] - self.start_device
            whose = "NVML, whole device (this PID not listed)"
        out["device_bytes"] = max(milestone, polled or 0) - base
        out["device_bytes_milestones"] = milestone - base
        if polled is not None:
            out["device_bytes_sampled"] = polled - base
        how = ("the peak of a sampling thread (every 2 ms through the first call and an untimed "
               "memory pass) and of milestone samples (after set-up, the first call and each timing "
               "regime)" if polled is not None else "the peak of milestone samples (after set-up, the "
               "first call and each timing regime; no sampling thread)")
        out["device_bytes_source"] = f"{whose}: {how}, minus its use once the framework's context existed"
        return out


def open_nvml(device: str) -> tuple[Nvml | None, str | None]:
    if device != "cuda":
        return None, None
    try:
        return Nvml(), None
    except Exception as exc:  # no package, no driver library, or no device
        return None, f"NVML unavailable: {type(exc).__name__}: {exc}"
