"""compare/measuring/nvml.py: device memory from NVML, on a stand-in for pynvml (fast tier; no GPU
needed). A machine without NVML gives no figure and a reason, never an exception."""
from __future__ import annotations

import os
import sys
import types

import pytest

from compare.measuring import nvml


class FakeNvml(types.ModuleType):
    """pynvml's calls the module makes, over a device whose use the test sets."""
    class NVMLError(Exception):
        pass

    def __init__(self, listed: bool = True) -> None:
        super().__init__("pynvml")
        self.used, self.mine, self.listed, self.handles = 1000, 0, listed, []

    def nvmlInit(self):
        pass

    def nvmlDeviceGetHandleByIndex(self, i):
        self.handles.append(("index", i))
        return "h"

    def nvmlDeviceGetHandleByUUID(self, u):
        self.handles.append(("uuid", u))
        return "h"

    def nvmlDeviceGetMemoryInfo(self, h):
        return types.SimpleNamespace(used=self.used)

    def nvmlDeviceGetComputeRunningProcesses(self, h):
        if not self.listed:
            return [types.SimpleNamespace(pid=os.getpid() + 1, usedGpuMemory=5)]
        return [types.SimpleNamespace(pid=os.getpid(), usedGpuMemory=self.mine)]


@pytest.fixture
def fake(monkeypatch):
    def install(listed=True, visible=None):
        mod = FakeNvml(listed)
        monkeypatch.setitem(sys.modules, "pynvml", mod)
        if visible is None:
            monkeypatch.delenv("CUDA_VISIBLE_DEVICES", raising=False)
        else:
            monkeypatch.setenv("CUDA_VISIBLE_DEVICES", visible)
        return mod
    return install


def test_without_nvml_there_is_no_figure_and_a_reason(monkeypatch):
    monkeypatch.setitem(sys.modules, "pynvml", None)            # not installed
    got, why = nvml.open_nvml("cuda")
    assert got is None and why.startswith("NVML unavailable: ")
    assert nvml.open_nvml("cpu") == (None, None)                 # off CUDA: nothing to ask


def test_this_process_peak_minus_its_use_once_the_context_exists(fake):
    dev = fake()
    n, why = nvml.open_nvml("cuda")
    assert why is None and dev.handles == [("index", 0)]
    dev.used, dev.mine = 1500, 300           # the framework's context
    n.mark_baseline()
    dev.used, dev.mine = 2500, 1300          # the cell's peak
    n.sample()
    dev.used, dev.mine = 1600, 400           # freed again: the peak stays
    n.sample()
    f = n.figures()
    assert f["device_bytes"] == 1000 and f["context_bytes"] == 300 and "this process" in f["device_bytes_source"]
    assert f["nvml_device_used_before_bytes"] == 1000 and f["nvml_device_delta_peak_bytes"] == 1500


def test_a_process_nvml_does_not_list_falls_back_to_the_whole_device(fake):
    dev = fake(listed=False, visible="GPU-1234,GPU-5678")
    n, _ = nvml.open_nvml("cuda")
    assert dev.handles == [("uuid", "GPU-1234")]
    dev.used = 1200
    n.mark_baseline()
    dev.used = 1700
    n.sample()
    f = n.figures()
    assert f["device_bytes"] == 500 and f["context_bytes"] == 200 and "whole device" in f["device_bytes_source"]
    assert "nvml_process_peak_bytes" not in f


def test_a_reading_lost_loses_the_figure_not_the_cell(fake):
    dev = fake(visible="1")
    n, _ = nvml.open_nvml("cuda")
    assert dev.handles == [("index", 1)]

    def broken(h):
        raise dev.NVMLError("gone")
    dev.nvmlDeviceGetMemoryInfo = broken
    n.mark_baseline()
    n.sample()
    assert "device_bytes" not in n.figures()
