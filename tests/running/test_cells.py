"""Cells in worker processes (compare/running/cells.py): a cell's record JSON and outputs come back
from a fresh interpreter; a worker that hangs is killed at the timeout and one that crashes costs
its cell alone (the cells after it run in a new process); a backend is probed in its own process.
Faults come from the tests' faulty backend (tests/extra_backends/faulty), as in tests/test_cli.py."""
from __future__ import annotations

import os
import time
from pathlib import Path
from typing import Any

import psutil
import pytest
from conftest import CORRECTNESS, FAULTY

from compare.running import cells
from compare.spec import Cell

QUICK = {**CORRECTNESS, "repeat": 1, "min_time": 0.0, "warmup": 0}


def cell(scenario: str = "saxpy", backend: str = "numpy", **kw: Any) -> Cell:
    return Cell.make(scenario, backend, "cpu", "float32", quick=True, **{**QUICK, **kw})


def workers() -> list[psutil.Process]:
    """This process's worker processes still alive."""
    out = []
    for p in psutil.Process().children(recursive=True):
        try:
            if "compare.running.worker" in " ".join(p.cmdline()) and p.status() != psutil.STATUS_ZOMBIE:
                out.append(p)
        except psutil.NoSuchProcess:
            pass
    return out


@pytest.fixture
def faulty(monkeypatch: pytest.MonkeyPatch):
    """The workers know the faulty backend; ``faulty(kind)`` makes its saxpy cells fail so."""
    monkeypatch.setenv("COMPARE_BACKENDS_EXTRA", str(FAULTY))
    return lambda kind: monkeypatch.setenv("COMPARE_FAULT", f"saxpy:{kind}")


def test_a_cell_runs_in_a_worker_and_hands_back_its_record_and_outputs() -> None:
    c = cell(params={"n": 256}, save_inputs=True)
    rec, out = cells.run(c, timeout=120)
    assert rec["status"] == "ok", rec.get("reason")
    assert (rec["scenario"], rec["backend"], rec["device"], rec["precision"]) == ("saxpy", "numpy", "cpu", "float32")
    assert rec["params"]["n"] == 256 and rec["time"]["repeats"] >= 1
    assert rec["error"]["vs_oracle"] <= rec["error"]["tolerance"]
    assert out is not None and out["out"].shape == (256,) and out["out"].dtype.name == "float32"
    assert set(rec["_inputs"]) and all(v.shape[-1] == 256 for v in rec["_inputs"].values() if v.ndim)   # --save-arrays
    # the same through a Dask task's JSON
    rec2, out2 = cells.run_task(c.to_dict(), timeout=120)
    assert rec2["status"] == "ok" and (out2["out"] == out["out"]).all()          # type: ignore[index]
    assert not workers()


def test_a_hanging_worker_is_killed_at_the_timeout(faulty) -> None:
    faulty("hang")
    t0 = time.monotonic()
    rec, out = cells.run(cell(backend="faulty"), timeout=3)
    took = time.monotonic() - t0
    assert rec["status"] == "error" and rec["reason"].startswith("timed out after 3 s"), rec
    assert out is None and 3 <= took < 15
    assert not workers()                                                  # killed, not left to run on


def test_a_crash_costs_its_cell_alone_and_the_rest_run_in_a_new_process(faulty) -> None:
    faulty("crash")
    batch = [cell("sdf", "faulty"), cell("saxpy", "faulty"), cell("sdf", "faulty", params={"width": 16, "height": 8})]
    seen: list[tuple[int, str]] = []
    results = cells.run_batch(batch, timeout=120, on_result=lambda i, r: seen.append((i, r[0]["status"])))
    assert [r["status"] for r, _ in results] == ["ok", "error", "ok"], [r.get("reason") for r, _ in results]
    assert results[1][0]["reason"].startswith("worker died (killed by signal SIGABRT)")
    assert results[1][1] is None and results[2][0]["params"]["width"] == 16
    assert seen == [(0, "ok"), (1, "error"), (2, "ok")]                      # as each finished, in order
    assert cells.run_batch([], timeout=1) == []
    assert not workers()


def test_a_probe_says_which_devices_a_backend_can_use(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    from compare.running import reuse
    monkeypatch.delenv(reuse.PROBE_ENV, raising=False)        # its own process, not the tests' kept answer
    got = cells.probe("numpy")
    assert got["available"]["cpu"] is None and isinstance(got["available"]["cuda"], str)
    assert set(got["available"]) == set(cells.DEVICES)
    # the tests' processes share it (tests/conftest.py): kept once, read back without a process,
    # asked anew in another environment; an answer its process never gave is never kept
    monkeypatch.setenv(reuse.PROBE_ENV, str(tmp_path))
    assert cells.probe("numpy") == got and len(list(tmp_path.glob("probe-numpy-*.json"))) == 1
    real = cells._probe
    monkeypatch.setattr(cells, "_probe", lambda *a: pytest.fail("probed again"))
    assert cells.probe("numpy") == got
    monkeypatch.setenv("COMPARE_TEST_OTHER", "1")
    monkeypatch.setattr(cells, "_probe", lambda name, timeout: ({"available": {}, "versions": {}}, False))
    assert cells.probe("numpy") == {"available": {}, "versions": {}}
    assert len(list(tmp_path.glob("probe-numpy-*.json"))) == 1
    monkeypatch.setattr(cells, "_probe", real)
    assert cells.probe("numpy") == got and len(list(tmp_path.glob("probe-numpy-*.json"))) == 2


def test_the_worker_environment_puts_the_repository_first_and_the_users_settings_win(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PYTHONPATH", "/elsewhere")
    monkeypatch.setenv("PYTHONUNBUFFERED", "0")
    env = cells.worker_env("numpy")
    assert env["PYTHONPATH"].split(os.pathsep) == [str(cells.ROOT), "/elsewhere"]
    assert env["PYTHONUNBUFFERED"] == "0" and Path(cells.ROOT, "compare", "running", "cells.py").is_file()


def test_a_dead_workers_reason_names_the_signal_or_exit_code_and_its_last_lines() -> None:
    class Proc:
        returncode = -9
    assert cells.died(Proc(), "a\n\nb\nc\nd\ne\nf\n") == "worker died (killed by signal SIGKILL): b | c | d | e | f"
    Proc.returncode = 3
    assert cells.died(Proc(), "") == "worker died (exit code 3): "
    assert cells.tail("x\ny\nz", 2) == "y | z"
