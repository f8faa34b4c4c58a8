"""compare/running/sitting_run.py: the check measured, a run's sitting checks in its entry of
``runs``, publish's handed check and the noisy-sitting stamp (fast tier; CUDA: the lead's run)."""
from __future__ import annotations

import pytest

from compare.measuring import environment
from compare.running import sitting_run
from compare.measuring.sitting import Quiet, SittingCheck, judge


def judge_now(check: SittingCheck) -> tuple[str, ...]:
    """``check`` judged against its kind's quiet sittings in the published stores."""
    return judge(check, sitting_run.reference(check))


BAD = SittingCheck.of(device="cpu", cores=2, host_cores=2, others_cores=1.9, copy_bytes_per_s=1e10)


def test_a_run_outside_publish_keeps_its_start_from_its_own_yardstick(monkeypatch):
    monkeypatch.delenv(sitting_run.ENV, raising=False)
    monkeypatch.setattr(sitting_run, "reference", lambda check: None)      # no stores of this kind
    monkeypatch.setattr(sitting_run, "judge", lambda check, quiet: ())      # this host's load: the next test's
    env = {"created": "t", "hardware": {"cpu": {"copy_bytes_per_s": 2.5e10}}}
    sitting_run.start(env)
    assert env["sitting"]["start"]["copy_bytes_per_s"] == 2.5e10 and env["sitting"]["start"]["device"] == "cpu"
    sitting_run.end(env)                          # outside publish: no end check
    # the reference it was judged against is kept: none here, so a page judges it after the fact
    assert env["sitting"] == {"start": env["sitting"]["start"], "quiet": None} and "noisy_sitting" not in env
    quiet = {}
    sitting_run.start(quiet, measure=False)       # the stress suite outside publish measures nothing
    assert quiet == {}


def test_a_run_outside_publish_in_a_noisy_sitting_is_stamped_not_refused(monkeypatch):
    monkeypatch.delenv(sitting_run.ENV, raising=False)
    for check, noisy in ((BAD, True), (SittingCheck.of(device="cpu", cores=2, host_cores=2, others_cores=0.0), False)):
        monkeypatch.setattr(sitting_run, "check_sitting", lambda device, yardstick=None, c=check: c)
        env = {"created": "t", "git_commit": "abc", "git_dirty": False, "hardware": {"cpu": {"copy_bytes_per_s": 1e10}}}
        sitting_run.start(env)
        assert bool(env.get("noisy_sitting")) is noisy
        if noisy:
            assert env["noisy_sitting_reasons"][0].startswith("host busy: other processes used 1.90 of 2 cores")
            assert environment.run_stamp(env)["noisy_sitting"] is True
    quiet = judge_now(SittingCheck.of(device="cuda", gpu="NVIDIA H100 80GB HBM3", launch_latency_s=9.5e-6,
                                      launch_pipelined_s=4.4e-6, copy_bytes_per_s=3e12))
    slow = judge_now(SittingCheck.of(device="cuda", gpu="NVIDIA H100 80GB HBM3", launch_latency_s=13.7e-6,
                                     launch_pipelined_s=8.34e-6, copy_bytes_per_s=3e12))
    assert quiet == () and any(r.startswith("pipelined launch 8.34 us") for r in slow)    # from the H100 store


def test_a_publish_part_takes_its_start_and_is_stamped(monkeypatch):
    monkeypatch.setenv(sitting_run.ENV, sitting_run.handed(BAD, ["host busy: x"], Quiet(kind="k", runs=5)))
    env = {"created": "t", "git_commit": "abc", "git_dirty": False}
    sitting_run.start(env)
    assert env["sitting"]["start"] == BAD.to_json() and env["sitting"]["quiet"] == Quiet(kind="k", runs=5).to_json()
    assert env["noisy_sitting"] is True and env["noisy_sitting_reasons"] == ["host busy: x"]
    assert environment.run_stamp(env) == {"created": "t", "commit": "abc", "dirty": False, "noisy_sitting": True}
    monkeypatch.setattr(sitting_run, "check_sitting", lambda device: BAD)
    sitting_run.end(env)
    assert env["sitting"]["end"] == BAD.to_json()
    assert env["noisy_sitting_reasons"][1].startswith("at the end: host busy: other processes used 1.90 of 2 cores")


def test_a_quiet_start_stamps_nothing_and_bad_handed_text_is_ignored(monkeypatch):
    monkeypatch.setenv(sitting_run.ENV, sitting_run.handed(BAD, [], None))
    env: dict = {"created": "t"}
    sitting_run.start(env, measure=False)
    assert "noisy_sitting" not in env and "noisy_sitting" not in environment.run_stamp(env)
    monkeypatch.setenv(sitting_run.ENV, "{not json")
    assert sitting_run.from_publish() is None
    assert sitting_run.device_of(["cpu", "cuda"]) == "cuda" and sitting_run.device_of({"cpu": {}}) == "cpu"


def test_the_cpu_check_measures_only_its_main_copy():
    """The CPU check costs two 128 MiB copies of ten repeats (about a second on 2 cores), not the
    yardstick's curve of eleven smaller sizes: what keeps it cheap is asserted, not its speed on a
    loaded test machine."""
    y = sitting_run.measure_yardstick("cpu")
    assert "error" not in y and [size for size, _ in y["copy_curve"]] == [y["copy_bytes"]] == [128 << 20]
    c = sitting_run.check_sitting("cpu")
    assert c.device == "cpu" and c.copy_bytes_per_s > 0 and c.others_cores is not None and c.notes == ()
    assert c.seconds is not None and c.seconds > 0          # what the check took, recorded


def test_a_cuda_check_measures_its_processes_one_after_another(monkeypatch):
    """CUDA: ``PROCESSES`` yardsticks, the run's own among them; the CPU: the one given, else one."""
    made: list[str] = []

    def measure(device):
        made.append(device)
        return {"launch_latency_s": 1e-5, "launch_latency_iqr_s": 1e-6, "launch_pipelined_s": 5e-6 + len(made) * 1e-7}
    monkeypatch.setattr(sitting_run, "measure_yardstick", measure)
    own = {"launch_latency_s": 1.2e-5, "launch_latency_iqr_s": 1e-6, "launch_pipelined_s": 7.7e-6}
    c = sitting_run.check_sitting("cuda", yardstick=own)
    assert made == ["cuda"] * (sitting_run.PROCESSES - 1) and c.processes == sitting_run.PROCESSES
    assert c.launch_pipelined_each_s[0] == 7.7e-6 and c.launch_pipelined_s == pytest.approx(5.3e-6)   # the 3rd lowest
    made.clear()
    assert sitting_run.check_sitting("cuda").processes == sitting_run.PROCESSES == len(made)
    made.clear()
    assert sitting_run.check_sitting("cpu", yardstick={"copy_bytes_per_s": 1e10}).processes is None and made == []
    sitting_run.check_sitting("cpu")
    assert made == ["cpu"]
    made.clear()
    monkeypatch.setattr(sitting_run, "measure_yardstick", lambda device: made.append(device) or {"error": "timed out"})
    lost = sitting_run.check_sitting("cuda")          # a failed process ends the series
    assert made == ["cuda"] and lost.processes == 0 and lost.notes[0] == "yardstick: timed out"
