"""compare/measuring/memory_sampler.py: NVML polled from a thread through a call catches what the
call holds only while it runs, which milestone samples miss (fast tier; a stand-in for pynvml, no
GPU needed). A poll that fails is a sample lost, never the cell."""
from __future__ import annotations

import time

from compare.measuring import memory_sampler, nvml
from test_nvml import fake  # noqa: F401  (the stand-in pynvml fixture)

MiB = 1 << 20


def transient_call(dev, held_s: float = 0.03):
    """A call that holds 800 MiB more while it runs and frees it before it returns."""
    def run():
        dev.used, dev.mine = dev.used + 800 * MiB, dev.mine + 800 * MiB
        time.sleep(held_s)
        dev.used, dev.mine = dev.used - 800 * MiB, dev.mine - 800 * MiB
    return run


def opened(fake):
    dev = fake()
    n, _ = nvml.open_nvml("cuda")
    dev.used, dev.mine = 500 * MiB, 300 * MiB          # the framework's context
    n.mark_baseline()
    dev.used, dev.mine = 600 * MiB, 400 * MiB          # what the cell keeps between calls
    return dev, n


def test_a_transient_peak_between_milestones_is_caught_by_the_sampler(fake):
    dev, n = opened(fake)
    s = memory_sampler.Sampler(n, interval_s=0.001)
    run = transient_call(dev)
    s.milestone()
    with s:
        run()
    s.milestone()
    f = {**n.figures(), **s.figures()}
    assert f["device_bytes_milestones"] == 100 * MiB          # the milestones saw no transient
    assert f["device_bytes_sampled"] == f["device_bytes"] == 900 * MiB
    assert f["nvml_process_peak_bytes"] == 1200 * MiB and f["nvml_samples"] >= 3
    assert "sampling thread" in f["device_bytes_source"] and "this process" in f["device_bytes_source"]


def test_without_the_sampler_the_figure_is_the_milestones_and_says_so(fake):
    dev, n = opened(fake)
    s = memory_sampler.Sampler(n)
    s.milestone()
    transient_call(dev, 0.005)()
    s.milestone()
    f = n.figures()
    assert f["device_bytes"] == f["device_bytes_milestones"] == 100 * MiB and "device_bytes_sampled" not in f
    assert "no sampling thread" in f["device_bytes_source"]


def test_the_memory_pass_samples_untimed_calls_until_its_time(fake):
    dev, n = opened(fake)
    s = memory_sampler.Sampler(n, interval_s=0.001)
    synced = []
    got = memory_sampler.memory_pass(transient_call(dev, 0.01), synced.append, s, min_time=0.05)
    assert 3 <= got["nvml_memory_pass_calls"] == len(synced) and got["nvml_memory_pass_s"] >= 0.05
    assert n.figures()["device_bytes"] == 900 * MiB and s._thread is None     # stopped


def test_a_long_call_is_sampled_once_through(fake):
    dev, n = opened(fake)
    s = memory_sampler.Sampler(n, interval_s=0.001)
    got = memory_sampler.memory_pass(transient_call(dev, 0.03), lambda r: None, s, min_time=0.0)
    assert got["nvml_memory_pass_calls"] == 1 and n.figures()["device_bytes"] == 900 * MiB


def test_failing_polls_and_a_failing_call_lose_samples_not_the_cell(fake):
    dev, n = opened(fake)
    s = memory_sampler.Sampler(n, interval_s=0.001)

    def broken(h):
        raise dev.NVMLError("gone")
    dev.nvmlDeviceGetMemoryInfo = broken

    def fails():
        time.sleep(0.005)
        raise RuntimeError("device lost")
    got = memory_sampler.memory_pass(fails, lambda r: None, s)
    assert got["nvml_memory_pass_calls"] == 0 and got["nvml_memory_pass_error"] == "RuntimeError: device lost"
    assert s.figures()["nvml_sample_errors"] >= 1 and s.polls == 0 and s._thread is None


def test_without_nvml_the_sampler_does_nothing():
    s = memory_sampler.Sampler(None)
    s.milestone()
    with s:
        pass
    calls = []
    assert memory_sampler.memory_pass(lambda: calls.append(1), lambda r: None, s) == {} and not calls
    assert s.figures() == {}


def test_the_worker_samples_the_first_call_and_a_memory_pass_never_a_timed_regime(fake, monkeypatch, tmp_path):
    """A numpy SAXPY cell through compare.running.worker.run_cell with the stand-in NVML: the
    sampling thread polls during the first call and the memory pass, and not once inside the
    latency or throughput regimes; the record keeps both figures and says which it shows."""
    import threading
    from compare.measuring import timing
    from compare.running import worker
    from compare.spec import Cell
    dev = fake()
    polls, windows = [], []
    real = dev.nvmlDeviceGetMemoryInfo

    def info(h):
        if threading.current_thread() is not threading.main_thread():
            polls.append(time.perf_counter())
        return real(h)
    dev.nvmlDeviceGetMemoryInfo = info
    monkeypatch.setattr(worker, "open_nvml", lambda device: (nvml.Nvml(), None))
    for name in ("steady_state", "pipelined"):
        def timed(*a, _f=getattr(timing, name), **k):
            t0 = time.perf_counter()
            try:
                return _f(*a, **k)
            finally:
                windows.append((t0, time.perf_counter()))
        monkeypatch.setattr(timing, name, timed)
    cell = Cell.from_dict({"scenario": "saxpy", "backend": "numpy", "device": "cpu", "precision": "float32",
                           "params": {"n": 4096}, "quick": True, "repeat": 20, "min_time": 0.05,
                           "throughput": True})
    rec = worker.run_cell(cell, tmp_path)
    mem = rec.memory.to_json()
    assert len(windows) == 2 and polls and mem["nvml_samples"] >= 2 and mem["nvml_memory_pass_calls"] >= 1
    assert not [t for t in polls for a, b in windows if a <= t <= b]
    assert "sampling thread" in mem["device_bytes_source"] and "device_bytes_milestones" in mem
    assert "memory_pass" in rec.time.to_json()["phases"]
