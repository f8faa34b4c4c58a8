"""What the reliability tests share (docs/reliability.md): the figures printed after the run,
the one-line refusal contract for bad input, the working directory of inputs and the entry
point in a real process. The tests: tests/test_options.py (bad input, one case at a time),
tests/test_options_properties.py (property-based bad input, fuzzed JSON), tests/planning/test_preflight.py
(host memory), tests/running/test_lock.py (locks, full disks, a killed driver)."""
from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

import adversarial
from conftest import ROOT

from compare import cli

# What the tests measured, printed after the run by tests/conftest.py (docs/reliability.md):
# bad inputs tried and refused cleanly, JSON documents fuzzed through Store.read, faults survived,
# records lost (saved before a fault and missing after it).
FIGURES = {"tried": 0, "refused": 0, "json_fuzzed": 0, "json_clean": 0, "faults": [], "records_lost": 0,
           "by_test": {}}
QUICK = ("--quick", "--backends", "numba", "--devices", "cpu", "--precision", "float32")


# ---- helpers ---------------------------------------------------------------------------------
def count_tried() -> None:
    """One more bad input tried by the running test (FIGURES and the adversarial tally)."""
    adversarial.case()
    FIGURES["tried"] += 1
    test = os.environ.get("PYTEST_CURRENT_TEST", "?").split("::")[-1].split("[")[0].split(" ")[0]
    FIGURES["by_test"][test] = FIGURES["by_test"].get(test, 0) + 1


def snapshot(root: Path) -> dict[str, tuple]:
    """Every path under ``root`` with its kind, size, mtime and content hash."""
    out = {}
    for p in sorted(root.rglob("*")):
        st_ = p.lstat()
        digest = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else ""
        out[str(p.relative_to(root))] = (p.is_dir(), st_.st_size if p.is_file() else 0, st_.st_mtime_ns, digest)
    return out


def run_main(argv: list[str]) -> tuple[int, list[str]]:
    """compare.cli.main in this process: (exit status, stderr lines + any warning raised)."""
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err), \
            warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rc = cli.main(argv)
    lines = [ln for ln in err.getvalue().splitlines() if ln.strip()]
    return rc, lines + [f"warning: {w.message}" for w in caught]


def assert_refused(argv: list[str], work: Path, needle: str = "") -> str:
    """Exit 2, one line (``needle`` in it), no exception, nothing written under ``work``."""
    before = snapshot(work)
    count_tried()
    rc, lines = run_main(argv)
    assert rc == 2 and len(lines) == 1, (argv, rc, lines)
    assert lines[0].startswith("error: ") and needle in lines[0], (argv, lines)
    assert snapshot(work) == before, (argv, "wrote something")
    FIGURES["refused"] += 1
    return lines[0]


def results_file(suite: str = "run", records: list | None = None) -> str:
    return json.dumps({"format_version": 2, "suite": suite, "runs": [{}], "records": records or []})


GOOD_RECORD = {"scenario": "saxpy", "backend": "warp", "device": "cpu", "precision": "float32",
               "status": "ok", "params": {"n": 16}, "time": None, "error": None}
# JSON of the wrong shape, as the issue tried it (and more)
BAD_JSON = {
    "list": "[]",
    "records-5": '{"records": 5}',
    "list-of-empty": "[{}]",
    "record-bad-type": results_file(records=[{**GOOD_RECORD, "time": 5}]),
    "record-memory-int": results_file(records=[{**GOOD_RECORD, "memory": 5}]),
    "record-no-status": results_file(records=[{k: v for k, v in GOOD_RECORD.items() if k != "status"}]),
    "record-median-text": results_file(records=[{**GOOD_RECORD, "time": {"median_s": "fast"}}]),
    "future-version": json.dumps({"format_version": 99, "suite": "run", "runs": [], "records": []}),
    "unknown-suite": json.dumps({"format_version": 2, "suite": "bench", "runs": [], "records": []}),
    "runs-not-list": json.dumps({"format_version": 2, "suite": "run", "runs": 3, "records": []}),
    "truncated": results_file(records=[GOOD_RECORD])[:40],
    "empty": "",
    "binary": "\x00\x01PK\x03\x04",
    "nan-top": "NaN",
}


def working_directory(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The tests' ``work`` fixture: a working directory (cwd) holding the inputs, a regular file
    and the bad JSON files."""
    w = tmp_path / "work"
    (w / "in").mkdir(parents=True)
    (w / "in" / "afile").write_text("not a directory\n")
    for name, text in BAD_JSON.items():
        (w / "in" / f"{name}.json").write_text(text)
    (w / "in" / "run.json").write_text(results_file("run", [GOOD_RECORD]))
    (w / "in" / "sweep.json").write_text(results_file("sweep"))
    (w / "in" / "stress.json").write_text(results_file("stress"))
    monkeypatch.chdir(w)
    return w


def compare_proc(*args: str, env: dict | None = None, cwd: Path = ROOT) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "compare", *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": str(ROOT),
                                                                     **(env or {})})
