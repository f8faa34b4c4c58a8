"""The measurement protocol (issue 6): launch/copy cells through the worker path, the seeded
check sample, timing records and the CPU copy yardstick; the sweeps built on them are in
tests/suites/test_sweep.py."""
from __future__ import annotations

import time

import numpy as np
import pytest

import backends
from compare.running import cells, hardware
from compare.spec import Cell
from compare.measuring import timing
from compare.results.environment import Yardstick
from compare.results.record import Timing
from conftest import require_device

pytestmark = pytest.mark.cli


# ---- launch and copy through the real worker path, every installed backend, CPU --------------
@pytest.mark.parametrize("scenario,params", [("launch", {}), ("copy", {"n": 100_003})])
@pytest.mark.parametrize("backend", list(backends.BACKENDS))
def test_launch_and_copy_cells(backend, scenario, params):
    require_device(backend, "cpu")
    spec = {"scenario": scenario, "backend": backend, "device": "cpu", "precision": "float32",
            "params": params, "repeat": 2, "min_time": 0.0}
    rec, out = cells.run(Cell.from_dict(spec), timeout=600)
    assert rec["status"] == "ok", f"{rec.get('reason')}\n{rec.get('traceback', '')}"
    assert rec["error"]["vs_oracle"] == 0.0 and rec["error"]["checked_items"] == "all"
    t = rec["time"]
    assert t["timer"] == "wall" and t["cache"].startswith("cold")
    assert t["median_s"] == t["wall"]["median_s"] > 0 and t["first_call_s"] > 0
    assert t["repeats"] >= 2 and t["warmup"] == 2
    assert rec["memory"]["peak_host_rss_bytes"] > 0
    assert not any(k.startswith(("device_", "nvml_")) for k in rec["memory"])   # CPU: none
    assert out["out"].dtype == np.float32


def test_check_sample_checks_a_seeded_sample():
    """The worker checks the sample of scenarios.base.sample_rows (tests/scenarios/test_sample.py)."""
    spec = {"scenario": "saxpy", "backend": "warp", "device": "cpu", "precision": "float32",
            "params": {"n": 50_001}, "repeat": 1, "min_time": 0.0, "check_sample": 1000,
            "save_outputs": False, "cache": "warm"}
    require_device("warp", "cpu")
    rec, out = cells.run(Cell.from_dict(spec), timeout=600)
    assert rec["status"] == "ok", rec.get("reason")
    assert rec["error"]["checked_items"] == ("1000 of 50001 (seeded random: row 0, last, "
                                             "extremes + random, seed 0)")
    assert rec["time"]["cache"].startswith("warm")
    assert out is None


def test_big_particles_are_checked_on_a_sample_by_default():
    """Above PARTICLES_CHECKED the plain command checks a seeded sample (its float64 rollout
    of every particle took 14 minutes at 2^24); --check-sample n checks them all."""
    from scenarios.particles import PARTICLES_CHECKED
    n = PARTICLES_CHECKED + 1001
    base = {"scenario": "particles", "backend": "numpy", "device": "cpu", "precision": "float32",
            "params": {"n": n, "steps": 20}, "repeat": 1, "min_time": 0.0, "save_outputs": False,
            "throughput": False, "cache": "warm"}
    for k, expect in ((0, f"{PARTICLES_CHECKED} of {n} particles (seeded random"), (n, "all")):
        rec, _ = cells.run(Cell.from_dict({**base, "check_sample": k}), timeout=600)
        assert rec["status"] == "ok", rec.get("reason")
        assert rec["error"]["checked_items"].startswith(expect), rec["error"]
        assert rec["error"]["well_conditioned"] + rec["error"]["ill_conditioned"] == (PARTICLES_CHECKED if k == 0 else n)


# ---- timing --------------------------------------------------------------------------------
class FakeEvents:
    """Stands in for CUDA events: reports a fixed device time per call."""

    def start(self):
        pass

    def stop(self):
        pass

    def elapsed_s(self):
        return 1e-6


def test_steady_state_keeps_events_apart_from_the_wall_clock_latency():
    t = timing.steady_state(lambda: None, lambda r: None, repeat=5, min_time=0.0, timer=FakeEvents())
    ev = t["events"]
    assert ev["median_s"] == ev["min_s"] == 1e-6 and ev["iqr_s"] == 0.0 and ev["repeats"] == 5
    assert t["median_s"] == t["wall"]["median_s"] and t["repeats"] == 5
    assert timing.events_of(Timing.from_json(t)) is ev      # a record's time part
    w = timing.steady_state(lambda: None, lambda r: None, repeat=3, min_time=0.0)
    assert w["median_s"] == w["wall"]["median_s"] and "events" not in w and timing.events_of(Timing.from_json(w)) is None


class SleepyEvents(FakeEvents):
    """Event records that cost host time, as a pair of CUDA event records does."""
    COST_S = 0.005

    def start(self):
        time.sleep(self.COST_S)

    def stop(self):
        time.sleep(self.COST_S)


def test_the_latency_does_not_include_the_event_records():
    """Issue 43: the harness bracketed every timed call with its event records, so the latency of
    the five event-timed frameworks carried their cost. A timer whose start and stop sleep 5 ms:
    the latency of a no-op call must stay far below one of them, the events still taken."""
    t = timing.steady_state(lambda: None, lambda r: None, repeat=5, min_time=0.0, timer=SleepyEvents())
    assert t["median_s"] < SleepyEvents.COST_S / 5 and t["wall"]["median_s"] < SleepyEvents.COST_S / 5
    assert t["events"]["repeats"] >= 5 and t["events"]["median_s"] == 1e-6


def test_an_old_event_timed_record_reads_its_events_from_its_own_figures():
    old = {"median_s": 2e-6, "iqr_s": 0.0, "min_s": 2e-6, "repeats": 3, "timer": "events",
           "wall": {"median_s": 9e-6, "iqr_s": 0.0, "min_s": 9e-6}}
    ev = timing.events_of(Timing.from_json(old))
    assert ev is not None and ev.median_s == 2e-6
    assert timing.events_of(Timing.from_json({**old, "timer": "wall"})) is None


def test_the_null_call_times_the_synchronise_alone():
    synced = []
    t = timing.null_call(lambda r: synced.append(r), calls=50)
    assert t["repeats"] == 50 and 0 < t["median_s"] < 1e-3
    assert len(synced) == 60 and set(synced) == {None}


def test_a_call_longer_than_max_time_warms_up_once_and_times_three():
    """A cell whose one call takes longer than max_time (2^24 particles on one CPU core) is not
    made to pay the full warm-up and repeat count: one warm-up call, then at least three timed."""
    calls = []

    def slow():
        calls.append(1)
        time.sleep(0.02)
    t = timing.steady_state(slow, lambda r: None, repeat=10, warmup=2, min_time=0.0, max_time=0.01)
    assert t["warmup"] == 1 and t["repeats"] == 3 and len(calls) == 4
    quick = timing.steady_state(lambda: None, lambda r: None, repeat=10, warmup=2, min_time=0.0)
    assert quick["warmup"] == 2 and quick["repeats"] == 10


class BrokenEvents(FakeEvents):
    def elapsed_s(self):
        raise RuntimeError("no events here")


def test_failing_events_fall_back_to_the_wall_clock():
    t = timing.steady_state(lambda: None, lambda r: None, repeat=4, min_time=0.0,
                            timer=BrokenEvents())
    assert "no events here" in t["events_error"] and "events" not in t
    assert t["repeats"] == 4 and t["median_s"] == t["wall"]["median_s"]


def test_event_timer_choice():
    assert timing.event_timer(backends.get("warp"), "cpu") == (None, timing.CLOCK)
    assert timing.event_timer(backends.get("jax"), "cuda") == (None, timing.CLOCK)
    assert timing.event_timer(backends.get("warp"), "cuda", mode="wall") == (None, timing.CLOCK)


# ---- the CPU copy yardstick ------------------------------------------------------------------
@pytest.fixture(scope="module")
def cpu_yardstick() -> Yardstick:
    """One measurement for the tests below to read (one xdist group: one process measures it)."""
    return hardware.measure_cpu()


@pytest.mark.xdist_group("cpu-yardstick")
def test_cpu_yardstick_is_the_faster_of_one_thread_and_one_per_core(cpu_yardstick):
    """The CPU copy yardstick must not fall below one thread's copy nor below what the
    multi-threaded ports' copies reach; it says which it took, and the sliced copy copies all."""
    from concurrent.futures import ThreadPoolExecutor
    hw = cpu_yardstick
    assert hw["copy_bytes_per_s"] >= hw["copy_one_thread_bytes_per_s"] > 0
    assert f"in {hw['copy_threads']} thread" in hw["copy_how"]
    assert hw["copy_bytes_per_s"] == pytest.approx(2 * hw["copy_bytes"] / hw["copy_median_s"])
    src = np.arange(1001, dtype=np.float32)
    for parts in (1, 2, 3, 7):
        dst = np.zeros_like(src)
        with ThreadPoolExecutor(parts) as pool:
            hardware.copy_in_slices(dst, src, pool, parts)
        assert np.array_equal(dst, src), parts


@pytest.mark.xdist_group("cpu-yardstick")
def test_cpu_cells_are_judged_against_a_copy_of_their_own_size(cpu_yardstick):
    """The CPU yardstick has a copy at every power of two from 64 KiB to 128 MiB; a cell's
    bandwidth floor uses the one nearest its traffic, so a cache-resident SAXPY is not compared
    with DRAM (a hardware fraction of 4 at n = 1e6 was the symptom) and its floor says so."""
    hw = cpu_yardstick
    sizes = [p[0] for p in hw["copy_curve"]]
    assert sizes == sorted(sizes) and sizes[0] == 1 << 16 and sizes[-1] == hw["copy_bytes"]
    assert all(bw > 0 for _, bw in hw["copy_curve"])
    assert hardware.matched_copy(hw, 2 * 2**20) == (hw["copy_curve"][4][1], 1 << 20)
    assert hardware.matched_copy(hw, 10**12)[1] == hw["copy_bytes"]       # past the end: the largest
    assert hardware.matched_copy({}, 1e6) is None and hardware.matched_copy(hw, 0) is None

    curve = [[1 << 20, 100e9], [1 << 27, 20e9]]      # a fast cache, a slow DRAM
    fake = {"copy_bytes_per_s": 20e9, "copy_bytes": 1 << 27, "copy_curve": curve, "copy_how": "test"}
    from compare.results.record import Record

    def cell(n: int, per_call: float) -> Record:
        return Record.from_json({"scenario": "saxpy", "backend": "numpy", "device": "cpu", "precision": "float32",
                                 "status": "ok", "params": {"n": n},
                                 "time": {"first_call_s": per_call, "median_s": per_call, "iqr_s": 0.0,
                                          "min_s": per_call, "repeats": 3, "throughput": {"median_s": per_call}},
                                 "error": {"vs_oracle": 0.0, "tolerance": 1e-6}})
    small = hardware.annotated(cell(2**18, 1e-4), {"cpu": fake})
    big = hardware.annotated(cell(2**27, 1.0), {"cpu": fake})
    assert small.throughput is not None and big.throughput is not None
    assert small.throughput.floor_s == pytest.approx(3 * 4 * 2**18 / 100e9)
    assert "same size (1 MiB per array" in (small.throughput.floor or "")
    assert big.throughput.floor_s == pytest.approx(3 * 4 * 2**27 / 20e9)
    assert "same size" not in (big.throughput.floor or "")
    assert small.hardware is not None and small.hardware.copy_how == "test"
    assert small.throughput.hw_fraction == pytest.approx(small.throughput.floor_s / 1e-4)
    assert hardware.annotated(small, {"cpu": fake}) is small        # judged once: nothing changes


def test_the_own_timer_is_compared_in_its_own_statistic():
    """A timer that reports blocks' means is compared with our calls in blocks of its size: a
    tail of slow calls (one in ten, 10x) moves a mean, not a median."""
    from compare.running.worker import in_blocks
    times = [1.0] * 9 + [10.0]
    assert in_blocks(times * 10, 1) == 1.0
    assert in_blocks(times * 10, 10) == pytest.approx(1.9)
    assert in_blocks(times, 50) == pytest.approx(1.9)      # fewer calls than a block: one block


def test_the_own_timer_alternates_with_our_clock_round_by_round():
    from compare.running import worker

    class Timed:                    # the framework's own timer: a fixed figure in blocks of 4
        def own_latency(self, device, call):
            call()
            return {"tool": "fake", "median_s": 0.002, "calls": 8, "block": 4}

    out = worker.own_latency(Timed(), "cpu", lambda: time.sleep(0.001), lambda r: None)
    assert out["rounds"] == worker.CROSS_ROUNDS and out["block"] == 4 and out["tool"] == "fake"
    assert 0.001 <= out["ours_call_s"] <= out["ours_s"] * 1.5
    assert out["ratio"] == pytest.approx(out["ours_s"] / 0.002, rel=0.5)

    class Failing:
        def own_latency(self, device, call):
            raise RuntimeError("no timer today")
    assert worker.own_latency(Failing(), "cpu", lambda: None, lambda r: None)["failed"].startswith("RuntimeError")
