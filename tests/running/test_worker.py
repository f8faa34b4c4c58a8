"""compare/running/worker.py: one cell in a worker, its record whatever happens (fast tier: NumPy
cells in this process; the driver's side is tested through compare/running/cells.py)."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest

import scenarios
from compare.running import worker
from compare.spec import Cell
from scenarios.base import Precision


def quick(**settings) -> Cell:
    settings = {"cache": "warm", "warmup": 0, "repeat": 3, "min_time": 0.0, "max_time": 0.5, "throughput": False,
                **settings}
    return Cell.make("saxpy", "numpy", "cpu", "float32", params={"n": 1000}, **settings)


@pytest.fixture(autouse=True)
def fresh_process(monkeypatch):
    """Each test is a worker's first cell."""
    monkeypatch.setattr(worker, "_SET_UP", set())


def record_in(cell_dir) -> dict:
    assert not (cell_dir / "record.json.tmp").exists()
    return json.loads((cell_dir / "record.json").read_text())


def test_a_cell_leaves_its_record_as_json(tmp_path):
    worker.run_one(quick().to_dict(), tmp_path / "cell-0")
    rec = record_in(tmp_path / "cell-0")
    assert rec["status"] == "ok" and rec["backend"] == "numpy" and rec["params"]["n"] == 1000
    assert rec["time"]["repeats"] >= 3 and rec["error"]["vs_oracle"] <= rec["error"]["tolerance"]
    assert rec["time"]["cache"].startswith("warm")


def test_a_failing_cell_leaves_an_error_record_with_its_traceback(tmp_path):
    worker.run_one({**quick().to_dict(), "backend": "no-such-framework"}, tmp_path / "c")
    rec = record_in(tmp_path / "c")
    assert rec["status"] == "error" and rec["reason"] and "Traceback" in rec["traceback"]


def test_cells_sharing_a_worker_must_be_warm_and_of_one_set_up(tmp_path):
    worker._SET_UP.add(("numpy", "cpu", "float32", "default"))
    worker.run_one(quick(cache="cold").to_dict(), tmp_path / "cold")
    assert record_in(tmp_path / "cold")["reason"] == "ValueError: only warm-cache cells may share a worker process"
    worker.run_one(Cell.make("saxpy", "numpy", "cpu", "float64", params={"n": 10}, cache="warm").to_dict(),
                   tmp_path / "other")
    assert "must share backend, device, precision and variant" in record_in(tmp_path / "other")["reason"]


def test_main_runs_every_cell_of_the_file_into_its_own_folder(tmp_path):
    cells = tmp_path / "cells.json"
    cells.write_text(json.dumps([quick().to_dict(), quick().to_dict()]))
    assert worker.main([str(cells), str(tmp_path / "out")]) == 0
    assert [record_in(tmp_path / "out" / f"cell-{i}")["status"] for i in (0, 1)] == ["ok", "ok"]


@pytest.mark.parametrize("cache", ["cold", "warm"])
def test_the_worker_process_skips_its_teardown_only_with_cold_caches(tmp_path, cache):
    """compare/running/caches.py ``leave``: a cold cell's worker exits once its record is written,
    its exit handlers never run; a warm one's run (a framework writes its offline cache there)."""
    import subprocess
    import sys
    (tmp_path / "cells.json").write_text(json.dumps([quick(cache=cache).to_dict()]))
    code = (f"import atexit, runpy, sys; atexit.register(open, {str(tmp_path / 'teardown')!r}, 'w'); "
            f"sys.argv = ['worker', {str(tmp_path / 'cells.json')!r}, {str(tmp_path / 'out')!r}]; "
            "runpy.run_module('compare.running.worker', run_name='__main__')")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120, cwd=os.path.dirname(scenarios.__path__[0]))
    assert record_in(tmp_path / "out" / "cell-0")["status"] == "ok"
    assert (tmp_path / "teardown").exists() == (cache == "warm")


def test_contract_violations_are_named():
    sc = scenarios.get("saxpy")
    p = sc.params({"n": 8})
    good = {"out": np.zeros(8, np.float32)}
    assert worker.contract_violation(sc, p, Precision.FLOAT32, good) is None
    assert "returned no 'out'" in worker.contract_violation(sc, p, Precision.FLOAT32, {})
    assert "undeclared output 'x'" in worker.contract_violation(sc, p, Precision.FLOAT32, {**good, "x": good["out"]})
    assert "dtype float64" in worker.contract_violation(sc, p, Precision.FLOAT32, {"out": np.zeros(8)})
    assert "shape (7,), expected (8,)" in worker.contract_violation(sc, p, Precision.FLOAT32,
                                                                    {"out": np.zeros(7, np.float32)})


def test_memory_figures_of_this_process():
    assert worker.peak_rss_bytes() >= worker.current_rss_bytes() > 0


def test_in_blocks_and_record_layout():
    assert worker.in_blocks([1.0, 2.0, 3.0, 4.0], 2) == pytest.approx(worker.in_blocks([1.5, 3.5], 1))
    rec = worker.record_of(quick(tags={"sweep": "x"}), status="ok", time=None)
    assert rec.layout[:2] == ("status", "time") and rec.layout[-1] == "tags" and rec.tags == {"sweep": "x"}


def test_a_repeat_process_times_the_figures_alone(tmp_path):
    """check=False (compare.running.repeats): the figures the rounds read, without the download,
    the oracle, the host profile, the null call or the framework's own timer, which the first
    process of the cell made once."""
    settings = {"throughput": True, "host_profile": 3}
    worker.run_one(quick(**settings).to_dict(), tmp_path / "first")
    worker.run_one(quick(check=False, **settings).to_dict(), tmp_path / "again")
    first, again = record_in(tmp_path / "first"), record_in(tmp_path / "again")
    assert first["status"] == again["status"] == "ok"
    for k in ("host_profile", "null"):
        assert k in first["time"] and k not in again["time"], k
    assert first["time"]["download_s"] is not None and again["time"].get("download_s") is None
    assert "error" in first and again.get("error") is None
    assert "download" not in again["time"]["phases"] and "check" not in again["time"]["phases"]
    for k in ("latency", "throughput", "first_call_s", "setup_s"):
        assert again["time"][k] is not None, k
    assert not (tmp_path / "again" / "outputs.npz").exists()


def test_a_sweeps_cell_leaves_out_the_framework_s_own_timer(tmp_path, monkeypatch):
    """own_timer=False (the sweeps: no sweep page reads the cross-check): the framework's own timer
    is not run; the matrix's cells (the default) run it once, in their first process."""
    asked: list[str] = []
    monkeypatch.setattr(worker, "own_latency", lambda be, device, run, sync: asked.append(device))
    worker.run_one(quick().to_dict(), tmp_path / "matrix")
    assert asked == ["cpu"] and "own_timer" in record_in(tmp_path / "matrix")["time"]["phases"]
    worker.run_one(quick(own_timer=False).to_dict(), tmp_path / "sweep")
    assert asked == ["cpu"] and "own_timer" not in record_in(tmp_path / "sweep")["time"]["phases"]


def test_the_host_profile_is_bounded_by_its_time_budget():
    from compare.results.record_parts import Regime
    assert worker.profile_calls(Regime.of(median_s=1e-5, k=4096)) == 2000      # the batch, at most 2000
    assert worker.profile_calls(Regime.of(median_s=1e-5, k=4)) == 20            # at least 20 short calls
    assert worker.profile_calls(Regime.of(median_s=0.5, k=1)) == 4              # PROFILE_S of long ones
    assert worker.profile_calls(Regime.of(median_s=30.0, k=1)) == 3             # never fewer than 3
