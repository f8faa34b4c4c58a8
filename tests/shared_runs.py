"""The quick run of every scenario on NumPy, made once per test process for the tests that read
it (or a copy of its folder): tests/test_cli.py's results, arrays, pictures, report and --resume,
tests/running/test_overlap.py's timed windows, tests/planning/test_outdir.py's earlier run and
tests/suites/test_publish.py's store of other sizes. They carry ``QUICK_RUN``, so that under
xdist one worker runs it.

NumPy's cells (no kernel to compile: seconds); warm kernel caches and no minimum time: the
records' contract, not their first calls nor the timings' precision; two workers set up ahead of
the timed one (--overlap 2), whose windows test_overlap checks.
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT

QUICK_RUN = pytest.mark.xdist_group("quick_run")
_RUN: dict[str, tuple[subprocess.CompletedProcess, Path]] = {}      # made once per process


def quick_argv(out: Path, backend: str) -> list[str]:
    """``compare all --quick`` of ``backend`` on the CPU into ``out`` (the words after ``compare``)."""
    return ["all", "--quick", "--backends", backend, "--devices", "cpu", "--repeat", "2", "--min-time", "0",
            "--cache", "warm", "--overlap", "2", "--save-arrays", "--out", str(out)]


def quick_all(out: Path, backend: str) -> subprocess.CompletedProcess:
    """``quick_argv`` in its own process."""
    return subprocess.run([sys.executable, "-m", "compare", *quick_argv(out, backend)],
                          cwd=ROOT, capture_output=True, text=True, timeout=1200)


def numpy_quick_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess, Path]:
    """(the run's process, its --out), the run made on first use."""
    if "numpy" not in _RUN:
        out = tmp_path_factory.mktemp("run")
        _RUN["numpy"] = (quick_all(out, "numpy"), out)
    return _RUN["numpy"]
