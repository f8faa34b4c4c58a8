"""Every bad input a one-line refusal (docs/reliability.md): output paths, free space, JSON of the
wrong shape for every reader, options that are out of range, duplicated, inapplicable or unknown,
a parameter not representable in a precision, a locked --out, run through ``compare.cli.main`` in
this process with stderr and warnings captured, each asserting exit 2, exactly one line, no
exception and nothing written (the working directory, which holds --out and the inputs, is
byte-for-byte and mtime unchanged); and a sample through ``python -m compare`` in real processes.
Property-based variants: tests/test_options_properties.py; sizes over the host's memory:
tests/planning/test_preflight.py."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from compare.running.lock import DirectoryLock
from reliability_checks import (BAD_JSON, FIGURES, QUICK, assert_refused, compare_proc, count_tried,
                                snapshot, working_directory)

pytestmark = pytest.mark.cli


@pytest.fixture()
def work(tmp_path, monkeypatch):
    return working_directory(tmp_path, monkeypatch)


# ---- the cases ---------------------------------------------------------------------------------
# (argv, needle); "OUT" is a fresh --out under the working directory, "IN/x" an input file
CASES = [
    # output paths: a file, under a file, a device, a read-only filesystem, empty, blank
    (["saxpy", *QUICK, "--out", "IN/afile"], "is a file"),
    (["saxpy", *QUICK, "--out", "IN/afile/sub"], "is a file"),
    (["saxpy", *QUICK, "--out", "/dev/null"], "is a file"),
    (["saxpy", *QUICK, "--out", "/proc/sys/compare-out"], "not writable"),
    (["saxpy", *QUICK, "--out", ""], "--out is empty"),
    (["saxpy", *QUICK, "--out", "  "], "--out is empty"),
    (["sweep", "bandwidth", "--quick", "--backends", "numba", "--devices", "cpu", "--out", "IN/afile"], "is a file"),
    (["stress", "--quick", "--only", "ulps", "--out", "IN/afile/x"], "is a file"),
    (["report", "IN/run.json", "--out", "IN/afile"], "is a file"),
    (["report", "IN/run.json", "--out", "OUT", "--page", "IN/afile/page.md"], "--page's directory"),
    (["sweep", "report", "IN/sweep.json", "--out", "/dev/null"], "is a file"),
    (["stress", "--merge", "IN/stress.json", "--out", "IN/afile"], "is a file"),
    # options out of range
    (["saxpy", "--timeout", "inf", "--out", "OUT"], "--timeout"),
    (["saxpy", "--timeout", "nan", "--out", "OUT"], "--timeout"),
    (["saxpy", "--timeout", "0", "--out", "OUT"], "--timeout"),
    (["saxpy", "--timeout", "-1", "--out", "OUT"], "--timeout"),
    (["saxpy", "--min-time", "-1", "--out", "OUT"], "--min-time"),
    (["saxpy", "--min-time", "nan", "--out", "OUT"], "--min-time"),
    (["saxpy", "--min-time", "inf", "--out", "OUT"], "--min-time"),
    (["saxpy", "--repeat", "0", "--out", "OUT"], "--repeat"),
    (["saxpy", "--repeat", "2.5", "--out", "OUT"], "--repeat"),
    (["stress", "--jobs", "0", "--out", "OUT"], "--jobs"),
    (["stress", "--timeout", "inf", "--out", "OUT"], "--timeout"),
    (["sweep", "error", "--timeout", "nan", "--out", "OUT"], "--timeout"),
    (["sweep", "scaling", "--record-every", "-1", "--out", "OUT"], "--record-every"),
    (["saxpy", "--scheduler", "", "--out", "OUT"], "--scheduler is empty"),
    # duplicates
    (["saxpy", "--backends", "numba,numba", "--out", "OUT"], "twice"),
    (["saxpy", "--devices", "cpu,cpu", "--out", "OUT"], "twice"),
    (["saxpy", "--precision", "float32,float32", "--out", "OUT"], "twice"),
    (["saxpy", "--variants", "default,default", "--out", "OUT"], "twice"),
    (["run", "saxpy", "saxpy", "--out", "OUT"], "twice"),
    (["saxpy", "--set", "n=10", "--set", "n=20", "--out", "OUT"], "twice"),
    (["report", "IN/run.json", "IN/run.json", "--out", "OUT"], "twice"),
    (["sweep", "report", "IN/sweep.json", "IN/sweep.json", "--out", "OUT"], "twice"),
    (["stress", "--merge", "IN/stress.json", "IN/stress.json", "--out", "OUT"], "twice"),
    (["stress", "--only", "ulps,ulps", "--out", "OUT"], "twice"),
    (["sweep", "error", "--scenarios", "saxpy,saxpy", "--out", "OUT"], "twice"),
    # options that do not apply to the command, extra words
    (["report", "IN/run.json", "--backends", "warp", "--out", "OUT"], "unrecognized"),
    (["report", "IN/run.json", "--title", "T", "--out", "OUT"], "--title applies only with --page"),
    (["list", "--backends", "warp"], "unrecognized"),
    (["list", "extra"], "unrecognized"),
    (["saxpy", "extra", "--out", "OUT"], "unrecognized"),
    (["all", "--quick", "extra", "--out", "OUT"], "unrecognized"),
    (["stress", "extra", "--out", "OUT"], "unrecognized"),
    (["sweep", "bandwidth", "extra", "--out", "OUT"], "unexpected argument"),
    (["sweep", "bandwidth", "--scenarios", "saxpy", "--out", "OUT"], "does not apply"),
    (["sweep", "bandwidth", "--record-every", "2", "--out", "OUT"], "does not apply"),
    (["sweep", "report", "IN/sweep.json", "--quick", "--out", "OUT"], "does not apply"),
    (["sweep", "report", "IN/sweep.json", "--backends", "warp", "--out", "OUT"], "does not apply"),
    (["sweep", "error", "--resume", "--fresh", "--out", "OUT"], "give one"),
    (["stress", "--merge", "IN/stress.json", "--only", "ulps", "--out", "OUT"], "does not apply"),
    (["stress", "--merge", "IN/stress.json", "--quick", "--out", "OUT"], "does not apply"),
    (["stress", "--precision", "float32", "--out", "OUT"], "does not apply"),
    # unknown names
    (["bogus"], "unknown scenario"),
    (["run", "saxpy", "bogus", "--out", "OUT"], "unknown scenario"),
    (["sweep", "bogus", "--out", "OUT"], "unknown sweep"),
    (["stress", "--only", "nope", "--out", "OUT"], "unknown"),
    (["saxpy", "--set", "nope=1", "--out", "OUT"], "unknown parameter"),
    (["all", "--backends", "fortran", "--out", "OUT"], "unknown backend"),
    (["saxpy", "--variants", "fastmath", "--backends", "warp", "--out", "OUT"], "unknown variant"),
    # parameters: out of range, and finite in float64 but not in a precision being run
    (["saxpy", "--set", "n=0", "--out", "OUT"], "n must be"),
    (["saxpy", "--set", "a=1e400", "--out", "OUT"], "a must be finite"),
    (["saxpy", "--set", "a=1e308", "--precision", "float32", "--out", "OUT"], "not representable in float32"),
    (["saxpy", "--set", "a=1e-50", "--out", "OUT"], "not representable in float32"),
    (["particles", "--set", "radius=1e-46", "--out", "OUT"], "not representable in float32"),
    (["projectile", "--set", "softness=1e-60", "--precision", "float32", "--out", "OUT"], "not representable"),
    (["sweep", "error", "--scenarios", "saxpy", "--set", "a=1e300", "--out", "OUT"], "not representable in float32"),
]
# every reader of a results file, given each bad JSON: exit 2, one line naming the file
READERS = {
    "report": lambda f: ["report", f, "--out", "OUT"],
    "sweep-report": lambda f: ["sweep", "report", f, "--out", "OUT"],
    "stress-merge": lambda f: ["stress", "--merge", f, "--out", "OUT"],
    "run-resume": None,            # the file is OUT/results.json, then --resume
    "sweep-resume": None,          # OUT/sweep.json
    "stress-out": None,            # OUT/stress.json (stress keeps other experiments' rows)
}


def _argv(args: list[str], work: Path) -> list[str]:
    return [a.replace("OUT", str(work / "out")).replace("IN/", str(work / "in") + "/") for a in args]


@pytest.mark.parametrize("args,needle", CASES, ids=[" ".join(a)[:60] for a, _ in CASES])
def test_bad_input_is_a_one_line_refusal(work, args, needle):
    assert_refused(_argv(args, work), work, needle)


@pytest.mark.parametrize("reader", list(READERS))
@pytest.mark.parametrize("shape", list(BAD_JSON))
def test_every_reader_refuses_every_bad_json(work, reader, shape):
    src = work / "in" / f"{shape}.json"
    if READERS[reader] is not None:
        line = assert_refused(_argv(READERS[reader](str(src)), work), work)
    else:
        out = work / "out"
        out.mkdir()
        name, argv = {"run-resume": ("results.json", ["saxpy", *QUICK, "--resume"]),
                      "sweep-resume": ("sweep.json", ["sweep", "bandwidth", "--quick", "--backends", "numba",
                                                      "--devices", "cpu", "--resume"]),
                      "stress-out": ("stress.json", ["stress", "--quick", "--only", "ulps"])}[reader]
        (out / name).write_bytes(src.read_bytes())
        line = assert_refused([*argv, "--out", str(out)], work)
        src = out / name
    assert str(src) in line


@pytest.mark.parametrize("reader,file", [("report", "sweep"), ("report", "stress"), ("sweep-report", "run"),
                                         ("stress-merge", "run"), ("report", "missing"), ("report", "in")])
def test_a_file_of_another_suite_or_none_is_refused(work, reader, file):
    f = str(work / "in" / f"{file}.json") if file != "in" else str(work / "in")
    assert_refused(_argv(READERS[reader](f), work), work)


def test_unwritable_out(work):
    if os.geteuid() == 0:
        pytest.skip("root writes anywhere (the read-only filesystem case covers it)")
    ro = work / "ro"
    ro.mkdir(mode=0o500)
    try:
        assert_refused(["saxpy", *QUICK, "--out", str(ro / "x")], work, "not writable")
    finally:
        ro.chmod(0o700)


# ---- refusals that need the availability probes (one numba probe each) -------------------------
@pytest.mark.parametrize("argv", [
    ["saxpy", *QUICK],
    ["sweep", "bandwidth", "--quick", "--backends", "numba", "--devices", "cpu"],
    ["stress", "--quick", "--only", "ulps", "--backends", "numba", "--devices", "cpu"],
], ids=["run", "sweep", "stress"])
def test_no_room_on_the_output_filesystem(work, monkeypatch, argv):
    monkeypatch.setenv("COMPARE_FAULT_FREE", "1000")
    assert_refused([*argv, "--out", str(work / "out")], work, "free")


def test_no_room_for_saved_arrays(work, monkeypatch):
    # 10M float64 saxpy elements: x, y and out are 240 MB of arrays; 100 MiB "free"
    monkeypatch.setenv("COMPARE_FAULT_FREE", str(100 * 2**20))
    argv = ["saxpy", "--set", "n=10000000", "--precision", "float64", "--backends", "numba", "--devices", "cpu",
            "--save-arrays", "--out", str(work / "out")]
    assert_refused(argv, work, "arrays")


def test_malformed_scheduler_address(work):
    pytest.importorskip("distributed")
    assert_refused(["saxpy", *QUICK, "--scheduler", "tcp://::::1", "--out", str(work / "out")], work,
                   "--scheduler")


def test_a_locked_out_is_refused_naming_the_holder(work):
    out = work / "out"
    out.mkdir()
    with DirectoryLock(out):
        line = assert_refused(["saxpy", *QUICK, "--out", str(out)], work, f"PID {os.getpid()}")
        assert "in use" in line
        for argv in (["stress", "--quick", "--only", "ulps"], ["report", str(work / "in" / "run.json")]):
            assert_refused([*argv, "--out", str(out)], work, f"PID {os.getpid()}")


# ---- real processes: the entry point itself ------------------------------------------------------
def test_entry_point_sample(tmp_path):
    """A sample of the cases through ``python -m compare`` (real stderr, warnings included)."""
    (tmp_path / "afile").write_text("x")
    (tmp_path / "list.json").write_text("[]")
    out = str(tmp_path / "out")
    cases = [["saxpy", "--out", str(tmp_path / "afile")], ["saxpy", "--timeout", "inf", "--out", out],
             ["saxpy", "--set", "a=1e308", "--precision", "float32", "--out", out],
             ["report", str(tmp_path / "list.json"), "--out", out], ["run", "saxpy", "saxpy", "--out", out],
             ["sweep", "report", "--out", out, str(tmp_path / "list.json")], ["list", "extra"],
             ["stress", "--merge", str(tmp_path / "list.json"), "--out", out]]
    before = snapshot(tmp_path)
    procs = [compare_proc(*c, cwd=tmp_path) for c in cases]
    for c, p in zip(cases, procs):
        _, err = p.communicate(timeout=120)
        lines = [ln for ln in err.splitlines() if ln.strip()]
        count_tried()
        assert p.returncode == 2 and len(lines) == 1 and "Traceback" not in err, (c, err)
        FIGURES["refused"] += 1
    assert snapshot(tmp_path) == before
