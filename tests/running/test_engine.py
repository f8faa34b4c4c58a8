"""The one engine (compare/running/engine.py): every planned cell gets one record, in plan order;
a cell that must not start gets its record without a process (skipped with the reason, or a
contract error); lanes keep one backend's cells on one GPU one after another; a store keeps every
record as it arrives, and --resume runs only what it does not hold."""
from __future__ import annotations

import copy
import json
import threading
import time
from pathlib import Path
from typing import Any

import pytest

import backends
from compare import spec
from compare.results.record import Record
from compare.results.store import Store
from compare.running import engine
from compare.spec import Cell

ROOT = Path(__file__).resolve().parents[2]
SITE = ROOT / "tests" / "data" / "site"
OK_RUN = next(r for r in json.loads((SITE / "results.json").read_text())["records"]
              if r["status"] == "ok" and r.get("time") is not None)
PROBES: engine.Probes = {"numpy": {"available": {"cpu": None, "cuda": "NumPy runs on the CPU only"}, "versions": {}},
                         "jax": {"available": {"cpu": None, "cuda": "no GPU"}, "versions": {}}}


def saxpy(backend: str = "numpy", device: str = "cpu", precision: str = "float32", n: int = 1000, **kw: Any) -> Cell:
    return Cell.make("saxpy", backend, device, precision, params={"n": n}, **kw)


def stand_in(cell: Cell) -> tuple[dict, None]:
    """A runner that starts no process: the record a worker would leave, minus the figures."""
    return {"status": "skipped", "reason": f"ran n={cell.params.n}"}, None


def test_one_result_per_cell_in_plan_order_each_with_its_identity() -> None:
    plan = [saxpy(n=n) for n in (300, 100, 200)] + [saxpy(device="cuda"), saxpy(precision="float64", tags={"k": 1})]
    results = engine.run_cells(plan, timeout=60, probes=PROBES, runner=stand_in)
    assert len(results) == len(plan)
    for cell, (rec, out) in zip(plan, results):
        assert isinstance(rec, Record) and out is None and rec.key == cell.key()
    assert [r.reason for r, _ in results] == ["ran n=300", "ran n=100", "ran n=200", "NumPy runs on the CPU only",
                                              "ran n=1000"]


def test_a_cell_that_must_not_start_is_skipped_with_its_reason_and_never_run() -> None:
    ran: list[Cell] = []
    plan = [saxpy(device="cuda"), saxpy(backend="jax", variant="graph"), saxpy(backend="warp"), saxpy()]
    results = engine.run_cells(plan, timeout=60, probes=PROBES, runner=lambda c: (ran.append(c), stand_in(c))[1])
    assert ran == [plan[3]]
    assert [(r.status, r.reason) for r, _ in results[:3]] == [
        ("skipped", "NumPy runs on the CPU only"),
        ("skipped", engine.not_runnable(plan[1], PROBES)[1]),     # type: ignore[index]
        ("skipped", "device not probed")]
    assert "CUDA" in results[1][0].reason


def test_not_runnable_names_a_missing_kernel_an_error_only_for_an_all_scenario(monkeypatch: pytest.MonkeyPatch) -> None:
    assert engine.not_runnable(saxpy(), PROBES) is None
    assert engine.not_runnable(saxpy(device="cuda"), PROBES) == ("skipped", "NumPy runs on the CPU only")
    monkeypatch.setattr(backends.get("numpy"), "has_kernel", lambda scenario: False)
    status, why = engine.not_runnable(saxpy(), PROBES)           # type: ignore[misc]
    assert status == "error" and why.startswith("contract: no backends/numpy/saxpy.py")
    launch = Cell.make("launch", "numpy", "cpu", "float32", quick=True)
    assert engine.not_runnable(launch, PROBES) == ("skipped", "no backends/numpy/launch.py (optional: measurement-only scenario)")


def test_refuse_is_the_callers_own_reason_not_to_start() -> None:
    plan = [saxpy(n=100), saxpy(n=10**6)]
    results = engine.run_cells(plan, timeout=60, probes=PROBES, runner=stand_in,
                               refuse=lambda c: ("skipped", "too big") if c.params.n > 1000 else None)
    assert [r.reason for r, _ in results] == ["ran n=100", "too big"]


def test_lanes_are_one_per_backend_per_gpu() -> None:
    assert engine.device_lane("warp", "cpu") is None and engine.device_lane("warp", "host") is None
    assert engine.device_lane("warp", "cuda") == ("warp", "cuda")
    assert engine.gpu_lane(saxpy(device="cuda")) == ("numpy", "cuda") and engine.gpu_lane(saxpy()) is None
    assert engine.gpu_lane(saxpy(backend="jax", device="cuda")) != engine.gpu_lane(saxpy(device="cuda"))


def test_pool_map_keeps_order_and_never_overlaps_one_lane() -> None:
    busy: dict[str, int] = {}
    overlap: list[str] = []
    lock = threading.Lock()

    def fn(item: tuple[str, int]) -> int:
        lane, value = item
        with lock:
            busy[lane] = busy.get(lane, 0) + 1
            if lane != "free" and busy[lane] > 1:
                overlap.append(lane)
        time.sleep(0.01)
        with lock:
            busy[lane] -= 1
        return value * 10

    items = [("a", 1), ("b", 2), ("a", 3), ("free", 4), ("b", 5), ("free", 6), ("a", 7)]
    got = engine.pool_map(fn, items, lane=lambda it: None if it[0] == "free" else it[0], jobs=4)
    assert got == [10, 20, 30, 40, 50, 60, 70] and overlap == []
    assert engine.pool_map(fn, items, lane=lambda it: it[0], jobs=1) == got


def test_resume_returns_the_kept_records_and_runs_the_rest(tmp_path: Path) -> None:
    plan = [saxpy(n=n) for n in (100, 200, 300)]
    store = Store(tmp_path / "results.json", "run")
    kept = Record.from_json({**plan[0].identity(), "status": "ok", "reason": "kept", "time": None, "error": None})
    store.put(kept)
    store.put(Record.from_json({**plan[1].identity(), "status": "error", "reason": "crashed", "time": None,
                                "error": None}))
    ran: list[int] = []
    results = engine.run_cells(plan, timeout=60, probes=PROBES, store=store, resume=True,
                               runner=lambda c: (ran.append(c.params.n), stand_in(c))[1])
    assert ran == [200, 300] and results[0] == (kept, None)
    assert [r.reason for r in Store.read(store.path).records] == ["kept", "ran n=200", "ran n=300"]


def test_on_record_maps_each_record_before_the_store_keeps_it(tmp_path: Path) -> None:
    store = Store(tmp_path / "results.json", "run")
    seen: list[int] = []

    def on_record(i: int, rec: Record, out: Any) -> Record:
        seen.append(i)
        return rec.replace(machine=f"box{i}")
    results = engine.run_cells([saxpy(n=100), saxpy(device="cuda")], timeout=60, probes=PROBES, store=store,
                               runner=stand_in, on_record=on_record)
    assert sorted(seen) == [0, 1] and [r.machine for r, _ in results] == ["box0", "box1"]
    assert [r.machine for r in Store.read(store.path).records] == ["box1", "box0"]     # the skip is saved first


def test_the_engine_stores_no_record_a_reader_could_not_load(tmp_path: Path) -> None:
    """A worker's record that fails the loader's checks becomes an error record of its cell (the
    reason names the field), so the results file stays readable."""
    bad = {k: copy.deepcopy(v) for k, v in OK_RUN.items()
           if k not in ("scenario", "backend", "device", "precision", "variant", "params", "tags")}
    bad["time"]["median_s"] = 0.0
    cell = {"scenario": "saxpy", "backend": "numpy", "device": "cpu", "precision": "float32",
            "params": {"n": 1000}, "quick": True}
    probes = {"numpy": {"available": {"cpu": None}, "versions": {}}}
    store = Store(tmp_path / "results.json", "run")
    (rec, _), = engine.run_cells([spec.Cell.from_dict(cell)], timeout=60, probes=probes, store=store,
                                 runner=lambda s: (copy.deepcopy(bad), None))
    assert isinstance(rec, Record) and rec.status == "error"
    assert rec.reason == "malformed record: time.median_s must be a finite number > 0, got 0.0"
    assert (rec.scenario, rec.backend, rec.params["n"]) == ("saxpy", "numpy", 1000)
    assert [r.status for r in Store.read(store.path).records] == ["error"]


def test_cells_that_cannot_start_are_stored_in_one_write_before_any_cell_runs(tmp_path, monkeypatch):
    """Skipped cells (here: a device no backend has) cost no file write each; they are in the
    store before the first cell runs, and every cell that runs is saved as it finishes."""
    probes = {"numpy": {"available": {"cpu": None, "cuda": "NumPy runs on the CPU only"}, "versions": {}}}
    cells = [{"scenario": "saxpy", "backend": "numpy", "device": d, "precision": p, "params": {"n": 1000},
              "quick": True} for d in ("cuda", "cpu") for p in ("float32", "float64")]
    store = Store(tmp_path / "results.json", "run")
    saved: list[list[str]] = []
    real_save = Store.save
    monkeypatch.setattr(Store, "save", lambda self: (saved.append([r.status for r in self.records]),
                                                     real_save(self))[1])
    good = {"status": "skipped", "reason": "stand-in for a run"}
    results = engine.run_cells([spec.Cell.from_dict(c) for c in cells], timeout=60, probes=probes, store=store,
                               runner=lambda s: (copy.deepcopy(good), None))
    assert [r.status for r, _ in results] == ["skipped"] * 4
    assert saved == [["skipped"] * 2, ["skipped"] * 3, ["skipped"] * 4]
    assert len(Store.read(store.path).records) == 4


def test_cells_run_in_worker_processes_sharing_one_when_warm(tmp_path: Path) -> None:
    """No runner: real workers. Two warm cells of one set-up share a process (share_process); the
    records carry the figures and the outputs come back; the CUDA cell never starts."""
    quick = {"cache": "warm", "throughput": False, "repeat": 1, "min_time": 0.0, "warmup": 0}
    plan = [saxpy(n=64, **quick), saxpy(device="cuda", **quick), saxpy(n=128, **quick)]
    store = Store(tmp_path / "results.json", "run")
    results = engine.run_cells(plan, timeout=120, probes=PROBES, store=store, share_process=True)
    assert [r.status for r, _ in results] == ["ok", "skipped", "ok"], [r.reason for r, _ in results]
    for (rec, out), n in ((results[0], 64), (results[2], 128)):
        assert rec.time is not None and rec.error is not None and rec.params["n"] == n
        assert out is not None and out["out"].shape == (n,)
    assert results[1][1] is None
    assert {r.key for r in Store.read(store.path).records} == {c.key() for c in plan}
