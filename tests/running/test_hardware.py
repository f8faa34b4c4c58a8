"""compare/running/hardware.py: the same-run yardstick's process contract and the floors it gives
records (fast tier; the CPU copy itself is measured in tests/measuring/test_timing.py)."""
from __future__ import annotations

import json
import subprocess

import pytest

from compare.results.record import Record
from compare.running import hardware

HW = {"copy_bytes_per_s": 20e9, "copy_bytes": 1 << 27, "copy_how": "test copy", "launch_latency_s": 5e-6}


TIME = {"median_s": 1e-3, "iqr_s": 0.0, "min_s": 1e-3, "repeats": 10, "first_call_s": 0.1}


def cell(status="ok", median=1e-3, device="cpu", throughput=True) -> dict:
    """A record's JSON: an ok cell is checked and timed (with a throughput regime unless not)."""
    timed = status in ("ok", "mismatch")
    return {"scenario": "saxpy", "backend": "numpy", "device": device, "precision": "float32", "status": status,
            "reason": "" if timed else "not run", "params": {"n": 2**20},
            **({"error": {"vs_oracle": 0.0, "tolerance": 1.0},
                "time": {**TIME, **({"throughput": {"median_s": median}} if throughput else {})}} if timed else {})}


def test_a_timed_cell_gets_its_yardstick_floor_and_fraction():
    r = hardware.annotated(Record.from_json(cell()), {"cpu": HW})
    assert r.to_json()["hardware"] == {"copy_bytes_per_s": 20e9, "copy_how": "test copy", "launch_latency_s": 5e-6,
                                       "copy_bytes": 1 << 27}
    t = r.throughput
    assert t is not None and t.floor_kind == "bandwidth" and t.floor_s == pytest.approx(3 * 4 * 2**20 / 20e9)
    assert t.hw_fraction == pytest.approx(t.floor_s / 1e-3)


@pytest.mark.parametrize("r,hw", [
    (cell(status="error"), {"cpu": HW}), (cell(status="skipped"), {"cpu": HW}),
    (cell(), {"cpu": {"error": "no yardstick"}}), (cell(), {}), (cell(device="cuda"), {"cpu": HW}),
    (cell(throughput=False), {"cpu": HW})])
def test_cells_without_a_yardstick_or_a_timing_are_left_alone(r, hw):
    rec = Record.from_json(r)
    assert hardware.annotated(rec, hw) is rec


def test_annotated_returns_a_new_record_only_where_something_was_added():
    rec = Record(scenario="saxpy", backend="numpy", device="cpu", precision="float32", status="ok",
                 params={"n": 2**20}, error={"vs_oracle": 0.0, "tolerance": 1.0},
                 time={"median_s": 1e-3, "iqr_s": 0.0, "min_s": 1e-3, "repeats": 10, "first_call_s": 0.1,
                       "throughput": {"median_s": 1e-3}})
    got = hardware.annotated(rec, {"cpu": HW})
    assert got is not rec and got.throughput["floor_kind"] == "bandwidth" and rec.throughput is None
    assert hardware.annotated(rec, {}) is rec


def test_measure_says_why_when_the_yardstick_process_fails_or_hangs(monkeypatch):
    def hangs(*a, **k):
        raise subprocess.TimeoutExpired(a[0], k.get("timeout"))
    monkeypatch.setattr(subprocess, "run", hangs)
    assert hardware.measure("cpu", timeout=7) == {"error": "yardstick timed out after 7 s"}

    def fails(*a, **k):
        return subprocess.CompletedProcess(a[0], 3, "", "line 1\nTraceback\nOSError: no device\n")
    monkeypatch.setattr(subprocess, "run", fails)
    assert hardware.measure("cuda") == {"error": "yardstick process failed (exit 3): Traceback | OSError: no device"}

    def measured(*a, **k):
        assert a[0][-2:] == ["compare.running.hardware", "cuda"]
        return subprocess.CompletedProcess(a[0], 0, 'noise\nYARDSTICK{"copy_bytes_per_s": 1.0}\n', "")
    monkeypatch.setattr(subprocess, "run", measured)
    assert hardware.measure("cuda") == {"copy_bytes_per_s": 1.0}


def test_main_prints_one_yardstick_line_even_when_it_cannot_measure(monkeypatch, capsys):
    def no_driver():
        raise OSError("libcuda.so.1: cannot open shared object file")
    monkeypatch.setattr(hardware, "measure_cuda", no_driver)
    assert hardware.main(["cuda"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 1 and json.loads(out[0][len("YARDSTICK"):]) == {
        "error": "OSError: libcuda.so.1: cannot open shared object file"}


def test_for_run_measures_each_run_unless_the_tests_folder_keeps_the_first(monkeypatch, tmp_path):
    calls = []
    monkeypatch.setattr(hardware, "measure", lambda device: calls.append(device) or {"copy_bytes_per_s": len(calls)})
    monkeypatch.delenv(hardware.REUSE_ENV, raising=False)
    assert [hardware.for_run("cpu")["copy_bytes_per_s"] for _ in range(2)] == [1, 2]     # each run its own
    monkeypatch.setenv(hardware.REUSE_ENV, str(tmp_path))
    assert [hardware.for_run("cpu")["copy_bytes_per_s"] for _ in range(2)] == [3, 3]     # the first one's
    assert hardware.for_run("cuda") == {"copy_bytes_per_s": 4} and len(calls) == 4         # per device
    monkeypatch.setattr(hardware, "measure", lambda device: calls.append(device) or {"error": "no device"})
    (tmp_path / "yardstick-cuda.json").unlink()
    assert hardware.for_run("cuda") == hardware.for_run("cuda") == {"error": "no device"}
    assert len(calls) == 6 and not (tmp_path / "yardstick-cuda.json").exists()          # a failure not kept
