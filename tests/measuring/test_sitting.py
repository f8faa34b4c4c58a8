"""compare/measuring/sitting.py: the sitting check's figures, its JSON, and the verdict's limits
both ways (fast tier; the CUDA path needs a GPU: the lead's run)."""
from __future__ import annotations

import json
import time

import pytest

from compare.measuring import sitting
from compare.measuring.sitting import Quiet, SittingCheck, judge

QUIET = Quiet(kind="NVIDIA H100 80GB HBM3", runs=21, launch_latency_s=10e-6, launch_pipelined_s=5e-6,
              copy_bytes_per_s=3e12)


def gpu_check(**kw) -> SittingCheck:
    base = dict(device="cuda", gpu="NVIDIA H100 80GB HBM3", cores=16, host_cores=16, launch_latency_s=10e-6,
                launch_pipelined_s=5e-6, null_spread=0.02, copy_bytes_per_s=3e12, others_cores=0.1,
                gpu_processes=(), throttle_reasons=("gpu_idle",))
    return SittingCheck.of(**{**base, **kw})


def test_a_quiet_sitting_has_no_reason():
    assert judge(gpu_check(), QUIET) == ()


@pytest.mark.parametrize("field, under, over, needle", [
    # each limit just under (quiet) and just over (noisy)
    ("launch_latency_s", 12.4e-6, 12.6e-6, "launch + synchronise 12.6 us, 1.26x the quiet 10 us"),
    ("launch_pipelined_s", 6.2e-6, 6.3e-6, "pipelined launch 6.3 us, 1.26x the quiet 5 us"),
    ("copy_bytes_per_s", 2.41e12, 2.39e12, "copy 2.39 TB/s, 1/1.26 of the quiet 3 TB/s"),
    ("null_spread", 0.099, 0.101, "empty-launch spread 10 % of the quiet floor 10 us"),
    ("others_cores", 3.99, 4.01, "host busy: other processes used 4.01 of 16 cores (limit 4.00)"),
    ("gpu_processes", (), (4242,), "1 other process(es) running on the GPU (pid 4242)"),
    ("throttle_reasons", ("gpu_idle", "sw_power_cap"), ("gpu_idle", "hw_thermal_slowdown"),
     "GPU clocks throttled: hw_thermal_slowdown"),
])
def test_each_limit_both_ways(field, under, over, needle):
    assert judge(gpu_check(**{field: under}), QUIET) == ()
    (why,) = judge(gpu_check(**{field: over}), QUIET)
    assert why.startswith(needle), why


def test_the_spread_is_judged_against_the_quiet_floor_not_a_fast_sittings_own():
    """The empty launches' IQR is about 1 us whatever the floor (stored H100 sittings: 0.9-1.15 us):
    session 34's fast sitting (9.55 us, IQR 10.6 % of it) is not noisy against the quiet 10.4 us,
    while the same IQR share of a slow floor is; without a reference the share of its own median."""
    quiet = Quiet(kind="NVIDIA H100 80GB HBM3", runs=24, launch_latency_s=10.4e-6, launch_pipelined_s=5.05e-6,
                  copy_bytes_per_s=3e12)
    fast = gpu_check(launch_latency_s=9.55e-6, launch_pipelined_s=4.63e-6, null_spread=0.106)
    assert judge(fast, quiet) == ()
    (why,) = judge(fast, None)
    assert why.startswith("empty-launch spread 11 % of the median")
    wide = gpu_check(launch_latency_s=12e-6, launch_pipelined_s=5.5e-6, null_spread=0.095)    # IQR 1.14 us
    (why,) = judge(wide, quiet)
    assert why.startswith("empty-launch spread 11 % of the quiet floor 10.4 us"), why


def test_without_a_quiet_reference_only_the_absolute_limits_apply():
    slow = gpu_check(launch_latency_s=30e-6, launch_pipelined_s=20e-6, copy_bytes_per_s=1e12)
    assert judge(slow, None) == () and len(judge(slow, QUIET)) == 3
    assert judge(gpu_check(gpu_processes=(1,)), None) != ()


def test_the_cpu_null_call_is_recorded_not_judged():
    cpu = SittingCheck.of(device="cpu", cores=2, host_cores=2, null_spread=0.5, copy_bytes_per_s=3e10, others_cores=0.2)
    assert judge(cpu, Quiet(kind="x", runs=5, copy_bytes_per_s=3e10)) == ()
    (why,) = judge(cpu.__class__.of(**{**cpu.to_json(), "others_cores": 0.6}), None)
    assert "of 2 cores (limit 0.50)" in why


def test_the_check_round_trips_through_json():
    c = gpu_check(measured="2026-12-06T03:42:03Z", sm_clock_hz=1.98e9, notes=["SM clock: not read"])
    back = SittingCheck.from_json(json.loads(json.dumps(c.to_json())))
    assert back.to_json() == c.to_json() and list(back) == list(c)
    assert back.gpu_processes == () and back.throttle_reasons == ("gpu_idle",) and back.notes == ("SM clock: not read",)
    assert back.launch_latency_s == 10e-6 and judge(back, QUIET) == judge(c, QUIET)
    assert SittingCheck.from_json({"device": "cuda", "later": 1}).extra["later"] == 1     # a newer key is kept
    assert Quiet.from_json(json.loads(json.dumps(QUIET.to_json()))) == QUIET


def test_throttle_reasons_are_decoded_to_names():
    assert sitting.throttle_names(0) == ()
    assert sitting.throttle_names(0x1 | 0x40) == ("gpu_idle", "hw_thermal_slowdown")
    assert sitting.throttle_names(0x4 | 0x1000) == ("sw_power_cap", "0x1000")


def test_a_check_from_a_yardstick_reads_the_host():
    t0 = time.perf_counter()
    c = sitting.sitting_from("cpu", {"copy_bytes_per_s": 1.5e10})     # a run's own, just measured
    assert time.perf_counter() - t0 < 1.0
    assert c.device == "cpu" and c.launch_latency_s is None and c.gpu is None and c.copy_bytes_per_s == 1.5e10
    assert c.others_cores is not None and c.host_cores and c.loadavg_1m is not None and c.null_spread is not None
    assert c.cpu and c.cores and c.measured and c.notes == ()
    assert "copy 15 GB/s" in sitting.summary(c) and "others on" in sitting.summary(c)
    lost = sitting.sitting_from("cpu", {"error": "boom"})       # a yardstick that failed: the notes say why
    assert lost.copy_bytes_per_s is None and lost.notes == ("yardstick: boom",)


def cuda_yardstick(lat_us: float, piped_us: float, iqr_us: float = 1.0, copy: float = 3e12) -> dict:
    return {"launch_latency_s": lat_us * 1e-6, "launch_latency_iqr_s": iqr_us * 1e-6,
            "launch_pipelined_s": piped_us * 1e-6, "copy_bytes_per_s": copy, "gpu": "NVIDIA H100 80GB HBM3"}


def gpu_reasons(c: SittingCheck) -> tuple[str, ...]:
    """The verdict on the GPU's figures (this test host's own load is not the point here)."""
    return tuple(w for w in judge(c, QUIET) if not w.startswith("host busy"))


def test_a_cuda_check_stands_for_its_processes():
    """Session 42's start: a check process read pipelined 7.69 us, the run's own yardstick 5.27 us
    seconds later. Of three processes, all three must be over a limit (SLOW_SHARE of three): the
    lowest floor with that process's own spread, the lowest pipelined launch, the fastest copy;
    each process is kept."""
    slow, fast, other = cuda_yardstick(11.5, 7.69, 0.58, 2.99e12), cuda_yardstick(10.5, 5.9, 1.0), cuda_yardstick(10.9, 5.27)
    c = sitting.sitting_from("cuda", [slow, fast, {"error": "yardstick timed out after 120 s"}, other])
    assert (c.launch_latency_s, c.launch_pipelined_s, c.copy_bytes_per_s) == pytest.approx((10.5e-6, 5.27e-6, 3e12))
    assert c.null_spread == pytest.approx(1.0 / 10.5)        # that floor's own IQR over its median
    assert c.processes == 3 and c.launch_pipelined_each_s == pytest.approx((7.69e-6, 5.9e-6, 5.27e-6))
    assert c.launch_latency_each_s == pytest.approx((11.5e-6, 10.5e-6, 10.9e-6))
    assert "yardstick: yardstick timed out after 120 s" in c.notes
    assert gpu_reasons(c) == () and gpu_reasons(sitting.sitting_from("cuda", slow)) != ()
    assert "pipelined 5.27 us, best of 3 processes (pipelined 5.27-7.69 us)" in sitting.summary(c)
    back = SittingCheck.from_json(json.loads(json.dumps(c.to_json())))     # the processes' figures travel
    assert back.launch_pipelined_each_s == c.launch_pipelined_each_s and back.to_json() == c.to_json()
    # every process at the slower level: the sitting is
    (why,) = gpu_reasons(sitting.sitting_from("cuda", [slow, cuda_yardstick(11.0, 7.2, 0.6)]))
    assert why.startswith("pipelined launch 7.2 us, 1.44x the quiet 5 us")
    lost = sitting.sitting_from("cuda", [{"error": "boom"}, {"error": "boom"}])
    assert lost.launch_latency_s is None and lost.processes == 0 and lost.notes[0] == "yardstick: boom"


@pytest.mark.parametrize("slow, noisy", [(4, False), (5, True), (7, True), (0, False)])
def test_seven_processes_are_noisy_when_five_are_over_a_limit(slow, noisy):
    """The check's seven processes: a figure over its limit only when at least 5 of the 7 are
    (SLOW_SHARE 0.7): its figure is the 3rd lowest; the copy the 3rd fastest."""
    assert [sitting.rank(n) for n in (1, 3, 5, 7, 10)] == [0, 0, 1, 2, 3]
    piped = [7.5] * slow + [4.8] * (7 - slow)
    c = sitting.sitting_from("cuda", [cuda_yardstick(10.0, p, copy=3e12 - i * 1e10) for i, p in enumerate(piped)])
    assert c.launch_pipelined_s == pytest.approx(sorted(piped)[2] * 1e-6) and c.copy_bytes_per_s == 2.98e12
    assert bool(gpu_reasons(c)) is noisy
    assert (f"3rd best of 7 processes (pipelined {min(piped):g}-{max(piped):g} us), spread 10 %, copy 2.98 TB/s"
            in sitting.summary(c))
