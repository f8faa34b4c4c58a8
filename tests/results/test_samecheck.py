"""compare/results/samecheck.py: two result folders that differ in any way that matters are told apart,
one line per difference; measurements and the environment are not differences."""
from __future__ import annotations

import copy
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from compare.results import samecheck
from compare.results.record import Record
from compare.results.store import Store, array_file, save_arrays
from conftest import ROOT


def record(backend: str, status: str = "ok") -> dict[str, Any]:
    return {"scenario": "saxpy", "backend": backend, "device": "cpu", "precision": "float32",
            "variant": "default", "params": {"n": 3, "a": 2.5, "inputs": "linspace", "seed": 0},
            "status": status, "reason": "" if status == "ok" else "error 1 exceeds tolerance 0.1",
            "time": {"first_call_s": 1.5, "median_s": 0.1, "iqr_s": 0.01, "min_s": 0.09, "repeats": 10,
                     "wall": {"median_s": 0.1, "iqr_s": 0.01, "min_s": 0.09},
                     "noise": {"noisy": False, "reasons": []}},
            "error": {"vs_oracle": 0.0, "tolerance": 1e-7, "vs_reference": 0.0, "metric": "max"},
            "memory": {"peak_host_rss_bytes": 100}, "host": "vm", "versions": {backend: "1.0"},
            "info": {"threads": 2}}


ARRAYS = {"a": np.array(2.5, np.float32), "x": np.arange(3, dtype=np.float32),
          "out": np.array([1.0, 2.0, np.nan], np.float32)}


def folder(path: Path, records: list[dict[str, Any]], arrays: dict[str, dict[str, np.ndarray]] | None = None) -> Path:
    Store(path / "results.json", "run", [{"hostname": str(path)}], [Record.from_json(r) for r in records]).save()
    for rec in records:
        if rec["status"] == "ok":
            save_arrays(path, rec, (arrays or {}).get(rec["backend"], ARRAYS))
    return path


@pytest.fixture
def base(tmp_path: Path) -> Path:
    return folder(tmp_path / "a", [record("warp"), record("numpy")])


def test_a_copy_is_the_same_and_measurements_do_not_count(base: Path, tmp_path: Path) -> None:
    recs = [record("warp"), record("numpy")]
    for r in recs:                    # another run: other timings, memory, host and versions
        r["time"].update(first_call_s=9.0, median_s=0.2)
        r["time"]["noise"]["reasons"] = [{"why": "host busy", "regime": "latency"}]
        r["memory"]["peak_host_rss_bytes"] = 7
        r.update(host="other", versions={r["backend"]: "2.0"}, traceback="File x, line 9")
    b = folder(tmp_path / "b", recs)
    assert samecheck.differences(base, b) == []
    assert samecheck.main([str(base), str(b)]) == 0


def planted(base: Path, tmp_path: Path, change: Any) -> list[str]:
    recs = [record("warp"), record("numpy")]
    arrays = {"warp": dict(ARRAYS), "numpy": dict(ARRAYS)}
    change(recs, arrays)
    return samecheck.differences(base, folder(tmp_path / "b", recs, arrays))


def flip_bit(recs: list[dict[str, Any]], arrays: dict[str, dict[str, np.ndarray]]) -> None:
    out = arrays["numpy"]["out"].copy()
    out.view(np.uint32)[1] ^= 1
    arrays["numpy"]["out"] = out


@pytest.mark.parametrize("change, expected", [
    (lambda r, a: r[1].update(status="mismatch", reason="error 1 exceeds tolerance 0.1"),
     ["saxpy/numpy/cpu/float32/default: reason: ", "saxpy/numpy/cpu/float32/default: status: "]),
    (lambda r, a: r[0]["error"].update(vs_oracle=1e-9), ["saxpy/warp/cpu/float32/default: error.vs_oracle: "]),
    (lambda r, a: r[0]["info"].pop("threads"), ["saxpy/warp/cpu/float32/default: info.threads: only in A"]),
    (lambda r, a: r[0]["time"].update(events_s=1.0), ["saxpy/warp/cpu/float32/default: time.events_s: only in B"]),
    (lambda r, a: r[0]["error"].update(metric="max abs"), ["saxpy/warp/cpu/float32/default: error.metric: "]),
    (lambda r, a: r[0]["params"].update(n=4), ['saxpy/warp/cpu/float32/default {"a": 2.5, "inputs": "linspace", '
                                               '"n": 3, "seed": 0}: cell only in A', '"n": 4, "seed": 0}: cell only in B']),
    (lambda r, a: r.pop(), ["saxpy/numpy/cpu/float32/default {", "}: cell only in A"]),
    (flip_bit, ["saxpy/numpy/cpu/float32/default: array 'out': bits differ (1 bytes of 12)"]),
    (lambda r, a: a["warp"].update(out=ARRAYS["out"].astype(np.float64)),
     ["saxpy/warp/cpu/float32/default: array 'out': float32[3] in A, float64[3] in B"]),
    (lambda r, a: a["warp"].pop("x"), ["saxpy/warp/cpu/float32/default: array 'x': only in A"]),
])
def test_a_planted_difference_is_reported(base: Path, tmp_path: Path, change: Any, expected: list[str]) -> None:
    lines = planted(base, tmp_path, change)
    assert lines, "a planted difference went unreported"
    text = "\n".join(lines)
    for part in expected:
        assert part in text, text


def test_missing_arrays_file_is_reported(base: Path, tmp_path: Path) -> None:
    b = folder(tmp_path / "b", [record("warp"), record("numpy")])
    gone = array_file(b, record("numpy"))
    gone.unlink()
    assert samecheck.differences(base, b) == [f"saxpy/numpy/cpu/float32/default: arrays file {gone.name} only in A"]


def test_command_line_prints_one_line_per_difference(base: Path, tmp_path: Path) -> None:
    recs = [record("warp", "mismatch"), record("numpy")]
    b = folder(tmp_path / "b", recs)
    run = subprocess.run([sys.executable, "-m", "compare.results.samecheck", str(base), str(b)], cwd=ROOT,
                         capture_output=True, text=True)
    assert run.returncode == 1, run.stderr
    lines = run.stdout.splitlines()
    assert len(lines) == 3 and all(line.startswith("saxpy/warp/cpu/float32/default: ") for line in lines), lines
    assert any("status: " in line for line in lines) and any("arrays file" in line for line in lines)
    bad = subprocess.run([sys.executable, "-m", "compare.results.samecheck", str(base), str(tmp_path / "none")], cwd=ROOT,
                         capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stderr.startswith("error: "), bad.stderr


def test_a_reordered_file_is_the_same(base: Path, tmp_path: Path) -> None:
    b = tmp_path / "b"
    b.mkdir()
    data = json.loads((base / "results.json").read_text())
    data["records"].reverse()
    (b / "results.json").write_text(json.dumps(copy.deepcopy(data)))
    (b / "arrays").mkdir()
    for f in (base / "arrays").iterdir():
        (b / "arrays" / f.name).write_bytes(f.read_bytes())
    assert samecheck.differences(base, b) == []
