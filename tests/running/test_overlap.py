"""Overlapped runs (compare/running/overlap.py): workers start before their turn, yet no two cells'
timed windows overlap, a CPU cell is timed only while every other worker waits, and a call that
already lasts the throughput batch is not timed twice (compare/measuring/timing.py)."""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

import pytest

from compare.running import overlap
from compare.measuring import timing
from compare.results.record_parts import Regime
from compare.spec import Cell
from reliability_checks import run_main
from shared_runs import QUICK_RUN, numpy_quick_run


_READ_ENDS: list[int] = []


@pytest.fixture(autouse=True)
def _close_read_ends():
    yield
    while _READ_ENDS:
        os.close(_READ_ENDS.pop())


class _Proc:
    def poll(self):
        return None


def _job(i: int, device: str, state: str, backend: str = "numpy") -> overlap._Job:
    r, w = os.pipe()                # the read end stays open (the worker's), so a grant lands
    _READ_ENDS.append(r)
    cell = Cell.from_dict({"scenario": "saxpy", "backend": backend, "device": device,
                           "precision": "float32", "variant": "default", "params": {}})
    job = overlap._Job(i, cell, Path("."), _Proc(), w, open(os.devnull, "w"), time.monotonic(), state=state)
    job.ready_at = time.monotonic()
    return job


def _cells(*devices_backends: tuple[str, str]) -> list[Cell]:
    return [Cell.from_dict({"scenario": "saxpy", "backend": b, "device": d, "precision": "float32",
                            "variant": "default", "params": {}}) for d, b in devices_backends]


def test_a_cpu_cell_is_timed_only_while_every_other_worker_waits():
    cpu, other = _job(0, "cpu", "ready"), _job(1, "cuda", "start", "warp")
    overlap._grant([cpu, other])
    assert cpu.state == "ready"                  # the other worker is still setting up
    other.state = "ready"
    overlap._grant([cpu, other])
    assert cpu.state == "timed" and other.state == "ready"
    overlap._grant([cpu, other])
    assert other.state == "ready"                # one window at a time
    for j in (cpu, other):
        j.close()


def test_a_cuda_cell_waits_too_while_another_worker_sets_up():
    gpu, other = _job(0, "cuda", "ready", "warp"), _job(1, "cpu", "start")
    overlap._grant([gpu, other])
    assert gpu.state == "ready"
    other.state = "after"                        # checking its outputs, or exiting
    overlap._grant([gpu, other])
    assert gpu.state == "ready"
    for j in (gpu, other):
        j.close()


def test_workers_start_together_only_while_no_window_is_open_or_due():
    plan = _cells(("cpu", "numpy"), ("cuda", "warp"), ("cpu", "numba"))
    for device, backend in (("cpu", "numpy"), ("cuda", "warp")):
        for state in ("ready", "timed"):
            active = [_job(0, device, state, backend)]
            assert overlap._launchable([1, 2], active, plan, 3, None, None, None) is None
            active[0].close()
    active = [_job(1, "cuda", "start", "warp"), _job(3, "cpu", "after")]
    assert overlap._launchable([0, 2], active, plan, 3, None, None, None) == 0
    assert overlap._launchable([0, 2], active, plan, 1, None, None, None) is None     # 1 + ahead workers
    for j in active:
        j.close()


def test_launches_keep_to_the_gpu_lanes_and_the_memory_budget():
    from compare.running.engine import gpu_lane
    plan = _cells(("cuda", "warp"), ("cuda", "warp"), ("cuda", "jax"))
    active = [_job(0, "cuda", "start", "warp")]
    assert overlap._launchable([1, 2], active, plan, 3, None, None, gpu_lane) == 2     # warp's lane is busy
    need = {"warp": 5.0, "jax": 6.0}
    assert overlap._launchable([1, 2], active, plan, 3, lambda c: need[c.backend], 9.0, None) is None
    assert overlap._launchable([], [], plan, 3, None, None, None) is None
    active[0].close()


class _Exits:
    """A worker process that exits when told (its pipe closed)."""
    def __init__(self) -> None:
        self.code: int | None = None

    def poll(self):
        return self.code


def test_beside_a_gpu_window_others_set_up_check_and_exit(tmp_path):
    """``beside``: a GPU cell's gate opens while others set up, check or exit, and workers start
    and exit while it is timed; a CPU cell's window is still alone, and still one window at a time."""
    gpu, setting_up, checking = _job(0, "cuda", "ready", "warp"), _job(1, "cuda", "start", "jax"), _job(2, "cpu", "after")
    overlap._grant([gpu, setting_up, checking], beside=False)
    assert gpu.state == "ready"                               # without beside: it waits for them
    exiting = _job(3, "cuda", "exiting", "numba")
    overlap._grant([gpu, setting_up, checking], [exiting], beside=True)
    assert gpu.state == "timed"
    other = _job(4, "cuda", "ready", "cupy")
    overlap._grant([gpu, other], beside=True)
    assert other.state == "ready"                             # one window at a time
    plan = _cells(("cuda", "torch"), ("cpu", "numba"))
    assert overlap._launchable([0, 1], [gpu, other], plan, 3, None, None, None, beside=True) == 0
    assert overlap._launchable([0, 1], [gpu, other], plan, 3, None, None, None, beside=False) is None
    parked = _job(5, "cuda", "parked", "taichi")
    parked.proc, parked.dir = _Exits(), tmp_path / "cell-5"
    parked.dir.mkdir()
    overlap._release([parked], [gpu], time.monotonic(), beside=True)
    assert parked.state == "exiting"                          # its exit runs beside the GPU window
    cpu = _job(6, "cpu", "ready")
    gpu.state = "after"
    overlap._grant([cpu, gpu], beside=True)
    assert cpu.state == "ready"                               # a CPU window waits for the others
    assert overlap._launchable([0], [cpu], plan, 3, None, None, None, beside=True) is None
    held = _job(7, "cuda", "parked", "warp")
    held.proc, held.dir = _Exits(), tmp_path / "cell-7"
    held.dir.mkdir()
    overlap._release([held], [cpu], time.monotonic(), beside=True)
    assert held.state == "parked"                             # nor does an exit run beside it
    gpu.state = "ready"
    overlap._grant([cpu, gpu], [exiting], beside=True)
    assert cpu.state == "ready"                               # an exit still running
    overlap._grant([cpu, gpu], beside=True)
    assert cpu.state == "timed"
    for j in (gpu, setting_up, checking, exiting, other, parked, cpu, held):
        j.close()


def test_beside_needs_an_overlapped_run_on_enough_cores(monkeypatch):
    from compare.measuring import environment
    monkeypatch.setattr(environment, "usable_cores", lambda: 16)
    assert overlap.beside(7) and not overlap.beside(0)
    monkeypatch.setattr(environment, "usable_cores", lambda: overlap.BESIDE_CORES - 1)
    assert not overlap.beside(1)


def test_a_batch_fills_up_past_cells_whose_lane_is_taken():
    from compare.running.engine import gpu_lane
    plan = _cells(*[("cuda", "warp")] * 9, ("cuda", "jax"))
    active = [_job(0, "cuda", "start", "warp")]
    assert overlap._launchable(list(range(1, 10)), active, plan, 3, None, None, gpu_lane) == 9
    active[0].close()


def test_a_parked_worker_exits_only_while_no_window_is_open_or_due(tmp_path):
    """Its record is in: it holds no gate, but its exit waits for the set-up phase, and no gate
    opens until it is gone; its lane stays taken until then."""
    from compare.running.engine import gpu_lane
    parked, ready = _job(0, "cuda", "parked", "warp"), _job(1, "cuda", "ready", "jax")
    parked.proc, parked.dir = _Exits(), tmp_path / "cell-0"     # removed once its worker is gone
    parked.dir.mkdir()
    idle = overlap._release([parked], [ready], time.monotonic())
    assert idle == [parked] and parked.state == "parked" and parked.gate >= 0     # a window is due
    overlap._grant([ready])
    assert ready.state == "timed"                  # the parked worker does not hold the gate
    idle = overlap._release(idle, [ready], time.monotonic())
    assert parked.state == "parked"                # nor exits during the window
    ready.state = "after"
    idle = overlap._release(idle, [ready], time.monotonic())
    assert parked.state == "exiting" and parked.gate == -1 and idle == [parked]
    plan = _cells(("cuda", "warp"), ("cuda", "numba"))
    assert overlap._launchable([0, 1], [], plan, 3, None, None, gpu_lane, idle) == 1   # warp's lane still held
    parked.proc.code = 0
    assert overlap._release(idle, [], time.monotonic()) == [] and not parked.dir.exists()
    ready.close()


def test_the_schedule_alternates_devices_and_frameworks():
    plan = _cells(("cuda", "warp"), ("cuda", "warp"), ("cpu", "numpy"), ("cuda", "jax"), ("cpu", "numba"))
    order = overlap.schedule(plan)
    assert sorted(order) == list(range(5))
    assert [plan[i].device for i in order[:4]] == ["cuda", "cpu", "cuda", "cpu"]
    assert [plan[i].backend for i in order if plan[i].device == "cuda"] == ["jax", "warp", "warp"]


def test_a_call_that_fills_the_batch_is_its_own_throughput_regime():
    latency = Regime.of(median_s=0.03, iqr_s=0.001, min_s=0.029, repeats=10)
    calls = []
    got = timing.pipelined(lambda: calls.append(time.sleep(0.03)), lambda r: None, latency=latency)
    assert got["same_as"] == "latency" and got["k"] == 1 and got["median_s"] == 0.03
    assert not calls                                         # not one call timed again
    fast = timing.pipelined(lambda: None, lambda r: None, latency=Regime.of(**{**latency, "median_s": 1e-6}))
    assert "same_as" not in fast and fast["k"] > 1


@QUICK_RUN
def test_an_overlapped_run_times_each_cell_alone(tmp_path_factory):
    """The quick run of tests/shared_runs.py (--overlap 2), which tests/test_cli.py reads too."""
    p, out = numpy_quick_run(tmp_path_factory)
    assert p.returncode == 0, p.stderr[-2000:]
    data = json.loads((out / "results.json").read_text())
    assert data["runs"][-1]["overlap"] == 2
    recs = [r for r in data["records"] if r["status"] == "ok"]
    assert len(recs) == 8
    spans = []
    for r in recs:
        t, ph = r["time"], r["time"]["phases"]
        start, end = t["window"]
        assert end > start and "wait" in ph
        launched = start - sum(ph.get(k, 0.0) for k in ("start", "inputs", "framework", "wait"))
        ready = start - ph["wait"]
        finished = end + sum(ph.get(k, 0.0) for k in ("check", "record", "save"))
        spans.append((start, end, [(launched, ready), (end, finished)]))
    slack = 0.01                                             # the records' rounding and clocks
    for a in spans:
        for b in spans:
            if a is b:
                continue
            assert b[1] <= a[0] + slack or b[0] >= a[1] - slack          # windows never overlap
            for lo, hi in b[2]:                                          # nor another's work
                assert hi <= a[0] + slack or lo >= a[1] - slack, (a, b)


def test_protocol_calls_follow_the_timing_rules():
    from compare.planning import calibrate
    cell = Cell.from_dict({"scenario": "projectile", "backend": "numpy", "device": "cpu",
                           "precision": "float32", "variant": "default", "params": {}})
    # a 60 s call: one warm-up, three timed, no throughput batch of its own
    assert calibrate.protocol_calls(60.0, cell) == 1 + 3
    # a 1 ms call: two warm-ups, 200 timed calls (min_time 0.2 s), the throughput batches
    assert calibrate.protocol_calls(1e-3, cell) == 2 + 200 + 160


def test_a_big_cell_predicted_past_the_timeout_is_skipped_with_the_prediction(tmp_path):
    out = tmp_path / "run"
    # compare.cli.main in this process (no interpreter to start); the miniature in its own, as ever
    rc, lines = run_main(["projectile", "--set", "batch=65536", "--backends", "numpy", "--devices", "cpu",
                          "--precision", "float32", "--timeout", "2", "--no-plots", "--out", str(out)])
    assert rc == 0, lines
    (rec,) = [r for r in json.loads((out / "results.json").read_text())["records"] if r["backend"] == "numpy"]
    assert rec["status"] == "skipped", rec
    assert "predicted to take about" in rec["reason"] and "over --timeout 2 s; --timeout" in rec["reason"]


def test_miniatures_run_one_at_a_time():
    # side by side, frameworks that start a thread per core oversubscribe the host and the
    # predictions that decide whether a cell runs come out hundreds of times too long
    from compare.planning import calibrate
    active, most, seen = [0], [0], []

    def run(small: Cell) -> tuple[dict, None]:
        active[0] += 1
        most[0] = max(most[0], active[0])
        time.sleep(0.05)
        seen.append(small.params.batch)
        active[0] -= 1
        return {"status": "ok", "time": {"median_s": 1.0, "first_call_s": 1.0}}, None

    plan = [Cell.make("projectile", b, "cpu", "float32", params={"batch": 65536}) for b in ("numpy", "jax", "torch")]
    refuse = calibrate.time_refusal(plan, 10.0, run=run)
    assert most[0] == 1 and seen == [65536 // calibrate.FACTOR] * 3
    assert all(refuse(c)[0] == "skipped" for c in plan)      # 64 s a call, over 10 s


def test_the_default_overlaps_set_ups_only_where_every_window_is_alone(monkeypatch):
    """No --overlap: auto on fewer than BESIDE_CORES usable cores (every window alone there),
    never with --busy (its spinners run through a worker's set-up) or --scheduler (no local
    workers to overlap); 0 on larger hosts; a given count always wins."""
    from argparse import Namespace
    from compare.measuring import environment
    for cores, want in ((2, 1), (6, 2), (overlap.BESIDE_CORES, 0), (16, 0)):
        monkeypatch.setattr(environment, "usable_cores", lambda: cores)
        assert overlap.ahead(Namespace(overlap=None)) == want, cores
        assert overlap.ahead(Namespace(overlap=None, busy=2)) == 0
        assert overlap.ahead(Namespace(overlap=None, scheduler="tcp://x:8786")) == 0
        assert overlap.ahead(Namespace(overlap=0)) == 0 and overlap.ahead(Namespace(overlap=3)) == 3
        assert not overlap.beside(overlap.ahead(Namespace(overlap=None)))
    assert overlap.ahead() == 0
