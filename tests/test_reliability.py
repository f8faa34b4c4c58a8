"""Nothing lost, nothing leaked, every bad input a one-line refusal (docs/reliability.md).

Bad inputs: every case of the issue (output paths, free space, JSON of the wrong shape for every
reader, options that are out of range, duplicated, inapplicable or unknown, a parameter not
representable in a precision, a size over the available memory, a locked --out), run through
``compare.cli.main`` in this process with stderr and warnings captured, each asserting exit 2,
exactly one line, no exception and nothing written (the working directory, which holds --out
and the inputs, is byte-for-byte and mtime unchanged); property-based variants with hypothesis;
and a sample through ``python -m compare`` in real processes.
Faults (real processes): a full disk mid-run (COMPARE_FAULT_DISK), a driver killed with SIGKILL
while its worker hangs, a second driver on a locked --out, a stale lock.
"""
from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import adversarial
from conftest import ROOT

from compare import cli, options, run_suite
from compare.lock import Busy, DirectoryLock
from compare.store import Store, StoreError, atomic_write

pytestmark = pytest.mark.cli

# What the tests measured, printed after the run by tests/conftest.py (docs/reliability.md):
# bad inputs tried and refused cleanly, JSON documents fuzzed through Store.read, faults survived,
# records lost (saved before a fault and missing after it).
FIGURES = {"tried": 0, "refused": 0, "json_fuzzed": 0, "json_clean": 0, "faults": [], "records_lost": 0,
           "by_test": {}}


def count_tried() -> None:
    adversarial.case()
    FIGURES["tried"] += 1
    test = os.environ.get("PYTEST_CURRENT_TEST", "?").split("::")[-1].split("[")[0].split(" ")[0]
    FIGURES["by_test"][test] = FIGURES["by_test"].get(test, 0) + 1

QUICK = ("--quick", "--backends", "numba", "--devices", "cpu", "--precision", "float32")


# ---- helpers ---------------------------------------------------------------------------------
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


@pytest.fixture()
def work(tmp_path, monkeypatch):
    """A working directory (cwd) holding the inputs: a regular file and the bad JSON files."""
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


def test_a_size_over_the_available_memory_is_refused(work):
    import psutil
    sc = run_suite.scenarios.get("saxpy")
    per_item = sc.footprint(sc.params({"n": 1 << 20}), "float64") / (1 << 20)
    n = int(psutil.virtual_memory().available / per_item * 1.5)
    if n > 2**31 - 1:
        pytest.skip("more memory available than the largest saxpy needs")
    assert_refused(["saxpy", "--set", f"n={n}", "--precision", "float64", "--out", str(work / "out")],
                   work, "available")


def test_memory_is_compared_with_available_not_total(monkeypatch):
    import psutil

    class Mem:
        total, available = 1 << 50, 1 << 20
    monkeypatch.setattr(psutil, "virtual_memory", lambda: Mem())
    spec = {"scenario": "saxpy", "backend": "numba", "device": "cpu", "precision": "float32", "params": {}}
    with pytest.raises(run_suite.ParamError, match="available"):
        run_suite.check_memory([spec])


def test_cells_over_the_available_memory_are_skipped_and_the_rest_run(work, monkeypatch, capsys):
    """A plan some of whose cells fit runs those and records the others as skipped with the
    memory they need (the plain `compare projectile --set batch=2^20` on a GPU machine: its CPU
    cells' tapes do not fit, its CUDA cells do)."""
    import psutil
    spec = lambda prec: {"scenario": "saxpy", "backend": "numpy", "device": "cpu",  # noqa: E731
                         "precision": prec, "params": {"n": 1 << 16}}
    small, big = run_suite.cell_bytes(spec("float32"))[0], run_suite.cell_bytes(spec("float64"))[0]
    assert small < big

    class Mem:
        total, available = 1 << 50, int((small + big) / 2)
    monkeypatch.setattr(psutil, "virtual_memory", lambda: Mem())
    out = work / "out"
    code = cli.main(["saxpy", "--set", "n=65536", "--backends", "numpy", "--devices", "cpu",
                     "--precision", "float32,float64", "--repeat", "3", "--out", str(out), "--no-plots"])
    assert code == 0, capsys.readouterr()
    recs = {r["precision"]: r for r in json.loads((out / "results.json").read_text())["records"]}
    assert recs["float32"]["status"] == "ok"
    assert recs["float64"]["status"] == "skipped"
    assert "host memory" in recs["float64"]["reason"] and "available" in recs["float64"]["reason"]


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


# ---- property-based ------------------------------------------------------------------------------
# derandomized: the same examples every run, so the figures in docs/reliability.md reproduce
HYPO = settings(max_examples=40, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])
bad_seconds = st.one_of(st.sampled_from(["inf", "-inf", "nan", "-0.5", "0x", "", "1e999", "-1e-9"]),
                        st.floats(max_value=-1e-12).map(repr),
                        st.text(alphabet="abcxyz!?%", min_size=1, max_size=6))


@HYPO
@given(opt=st.sampled_from(["--timeout", "--min-time"]), value=bad_seconds)
def test_property_bad_seconds(work, opt, value):
    assert_refused(["saxpy", f"{opt}={value}", "--out", str(work / "out")], work)


@HYPO
@given(value=st.one_of(st.integers(max_value=0).map(str), st.floats(allow_nan=True).filter(
    lambda f: not (f == f and f.is_integer() and f >= 1)).map(repr), st.text(alphabet="ab.-e", min_size=1, max_size=5)))
def test_property_bad_repeat(work, value):
    assert_refused(["saxpy", f"--repeat={value}", "--out", str(work / "out")], work)


def _float_fields():
    import dataclasses
    out = []
    for sc in run_suite.scenarios.SCENARIOS.values():
        if not sc.in_all:
            continue
        for f in dataclasses.fields(sc.Params):
            if f.type in (float, "float"):
                out.append((sc.name, f.name))
    return out


@HYPO
@given(field=st.sampled_from(_float_fields()),
       value=st.one_of(st.floats(min_value=3.5e38, max_value=1.7e308), st.floats(min_value=-1.7e308, max_value=-3.5e38),
                       st.floats(min_value=1e-320, max_value=1e-46)))
def test_property_not_representable_in_float32(work, field, value):
    """Every float parameter of every scenario: a value float32 cannot hold is refused for a
    float32 run (by the scenario's range check or the precision check), never run."""
    scenario, name = field
    assert_refused([scenario, "--precision", "float32", "--set", f"{name}={value!r}", "--out", str(work / "out")], work)


@HYPO
@given(opt=st.sampled_from(["--backends", "--devices", "--precision"]), data=st.data())
def test_property_duplicated_names(work, opt, data):
    import backends
    allowed = {"--backends": list(backends.BACKENDS), "--devices": list(backends.DEVICES),
               "--precision": ["float32", "float64"]}[opt]
    items = data.draw(st.lists(st.sampled_from(allowed), min_size=1, max_size=3))
    items = data.draw(st.permutations(items + [items[0]]))
    assert_refused(["saxpy", opt, ",".join(items), "--out", str(work / "out")], work, "twice")


@HYPO
@given(word=st.text(alphabet="abcdefghijklmnopqrstuvwxyz0123456789_.", min_size=1, max_size=12),
       command=st.sampled_from(["saxpy", "all", "list", "stress"]))
def test_property_extra_words(work, word, command):
    assert_refused([command, word, "--out", str(work / "out")] if command != "list" else [command, word], work)


@HYPO
@given(opt=st.sampled_from(["--backends", "--devices", "--precision", "--variants", "--set", "--only", "--jobs",
                            "--scenarios"]),
       value=st.text(alphabet="!#%&*()0123456789=,:;.+-~ ", max_size=8))
def test_property_junk_option_values(work, opt, value):
    """Junk for any list, name or parameter option (never a valid name): refused in one line."""
    command = {"--only": ["stress"], "--jobs": ["stress"], "--scenarios": ["sweep", "error"]}.get(opt, ["saxpy"])
    if opt == "--jobs":
        with contextlib.suppress(Exception):
            options.positive_int(value)
            return                                       # a valid job count
    assert_refused([*command, f"{opt}={value}", "--out", str(work / "out")], work)


def _nested(children):
    return st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=8), children, max_size=4)


json_values = st.recursive(st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=5),
                           _nested, max_leaves=12)
record_like = st.fixed_dictionaries({}, optional={k: json_values for k in (
    "scenario", "backend", "device", "precision", "variant", "status", "reason", "params", "time", "error",
    "memory", "work", "throughput", "info", "gradient", "tags")}).map(
    lambda d: {**GOOD_RECORD, **d})


@settings(max_examples=150, deadline=None, derandomize=True, database=None)
@given(data=st.one_of(json_values, st.builds(lambda recs: {"format_version": 2, "suite": "run", "runs": [{}],
                                                           "records": recs}, st.lists(record_like, max_size=3))))
def test_property_store_read_validates_or_refuses(tmp_path_factory, data):
    """Any JSON: Store.read gives a store or a one-line StoreError naming the file, never another
    exception; a record it accepts renders (tables) without an exception."""
    from compare import report
    f = tmp_path_factory.mktemp("json") / "results.json"
    f.write_text(json.dumps(data))
    FIGURES["json_fuzzed"] += 1
    adversarial.case()
    try:
        store = Store.read(f)
    except StoreError as exc:
        assert "\n" not in str(exc) and str(f) in str(exc)
        FIGURES["json_clean"] += 1
        return
    if store.suite == "run":
        report.tables(store.records)
    FIGURES["json_clean"] += 1


# ---- real processes: the entry point itself ------------------------------------------------------
def compare_proc(*args: str, env: dict | None = None, cwd: Path = ROOT) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "compare", *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": str(ROOT),
                                                                     **(env or {})})


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


# ---- locks and atomic writes, in this process ----------------------------------------------------
def test_lock_refuses_a_second_holder_and_takes_over_a_stale_one(tmp_path, monkeypatch):
    a = DirectoryLock(tmp_path).acquire()
    with pytest.raises(Busy, match=f"PID {os.getpid()}"):
        DirectoryLock(tmp_path).acquire()
    a.release()
    assert not (tmp_path / ".compare.lock").exists()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (tmp_path / ".compare.lock").write_text(f"{dead.pid}\n")        # left by a dead driver
    with DirectoryLock(tmp_path) as lock:
        assert (tmp_path / ".compare.lock").read_text().strip() == str(os.getpid()) and lock.held
    # a filesystem without flock: exclusive creation, a dead PID's file taken over
    import fcntl

    def no_flock(*a):
        raise OSError(37, "No locks available")
    monkeypatch.setattr(fcntl, "flock", no_flock)
    (tmp_path / ".compare.lock").write_text(f"{dead.pid}\n")
    b = DirectoryLock(tmp_path).acquire()
    with pytest.raises(Busy, match=f"PID {os.getpid()}"):
        DirectoryLock(tmp_path).acquire()
    b.release()
    assert not (tmp_path / ".compare.lock").exists()
    FIGURES["faults"] += ["a second holder of a lock", "a stale lock of a dead PID",
                          "a filesystem without flock"]


def test_atomic_write_on_a_full_disk_keeps_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    from compare import store
    f = tmp_path / "results.json"
    atomic_write(f, "old")
    monkeypatch.setenv("COMPARE_FAULT_DISK", "0")
    monkeypatch.setattr(store, "_WRITES", [0])
    with pytest.raises(OSError) as exc:
        atomic_write(f, "new" * 1000)
    assert exc.value.errno == 28 and exc.value.filename == str(f)
    assert f.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["results.json"]
    FIGURES["faults"].append("a full disk in an atomic write")


def test_claiming_out_removes_temporaries_a_killed_driver_left(tmp_path):
    (tmp_path / "arrays").mkdir()
    left = [tmp_path / ".results.json.compare-abc123.tmp",
            tmp_path / "arrays" / ".saxpy-warp-cpu-float32.npz.compare-x.tmp"]
    for p in left:
        p.write_text("half")
    users = [tmp_path / "keep.tmp", tmp_path / ".notes.tmp", tmp_path / ".results.json.abc123.tmp"]
    for p in users:
        p.write_text("a user's file")
    out, lock = options.claim_output(str(tmp_path))
    with lock:
        assert not any(p.exists() for p in left) and all(p.exists() for p in users)
    FIGURES["faults"].append("temporaries left by a killed driver")


# ---- the memory estimate against measured peaks ---------------------------------------------------
MEMORY_SIZES = {"saxpy": ({"n": 1 << 16}, {"n": 1 << 23}),
                "sdf": ({"width": 256, "height": 256}, {"width": 2048, "height": 2048}),
                "particles": ({"n": 1 << 12, "steps": 20}, {"n": 1 << 20, "steps": 10, "record_every": 5},
                              {"n": 1 << 14, "steps": 200, "record_every": 1}),
                "projectile": ({"steps": 180, "iters": 2}, {"steps": 100_000, "iters": 1})}


@pytest.mark.slow
def test_memory_estimate_bounds_measured_peaks():
    """WORKER_BASELINE_BYTES + Scenario.footprint >= the worker's measured peak RSS, for every
    scenario at two sizes (warp on CPU, float64: the larger arrays; warm caches)."""
    from compare import engine
    specs = [{"scenario": sc, "backend": "warp", "device": "cpu", "precision": "float64", "params": p,
              "repeat": 1, "min_time": 0.0, "cache": "warm"} for sc, sizes in MEMORY_SIZES.items() for p in sizes]
    probes = engine.availability(["warp"])
    if probes["warp"]["available"]["cpu"]:
        pytest.skip(probes["warp"]["available"]["cpu"])
    results = engine.run_cells(specs, timeout=600, probes=probes, jobs=2)     # a process each: own peak
    ratios = []
    for spec, (rec, _) in zip(specs, results):
        assert rec.status == "ok", rec.reason
        peak = rec.memory["peak_host_rss_bytes"]
        estimate = run_suite.cell_bytes(spec)[0]
        assert estimate >= peak, (spec["scenario"], spec["params"], peak / 2**20, estimate / 2**20)
        ratios.append(estimate / peak)
    FIGURES["memory"] = f"{len(specs)} cells, estimate/peak {min(ratios):.2f} to {max(ratios):.2f}"


# ---- faults in real processes ---------------------------------------------------------------------
def worker_pids(marker: str) -> list[int]:
    """PIDs of compare worker processes whose command line mentions ``marker``."""
    found = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if "compare." in cmd and marker in cmd:
            found.append(int(d.name))
    return found


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_sigkilled_driver_leaves_no_worker_no_temp_dir_and_a_stale_lock(tmp_path):
    """A driver killed with SIGKILL while its worker hangs: within seconds no worker of it runs and
    its temporary directory is gone; a second driver meanwhile is refused naming its PID; a
    later --resume takes the dead driver's lock over and runs the cell."""
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    out = tmp_path / "out"
    env = {"TMPDIR": str(tmp), "COMPARE_FAULT": "saxpy/numba:hang"}
    args = ["saxpy", *QUICK, "--set", "n=1000", "--repeat", "1", "--min-time", "0", "--no-plots", "--out", str(out)]
    driver = compare_proc(*args, env=env)
    deadline = time.monotonic() + 120
    while not worker_pids(str(tmp)) and time.monotonic() < deadline:
        assert driver.poll() is None, driver.communicate()
        time.sleep(0.1)
    assert worker_pids(str(tmp)), "no worker started"
    second = compare_proc(*args, env={"TMPDIR": str(tmp)})
    _, err = second.communicate(timeout=120)
    assert second.returncode == 2 and err.strip() == (
        f"error: --out {out}: in use by another compare driver (PID {driver.pid}); "
        "wait for it to finish or give another --out"), err
    driver.send_signal(signal.SIGKILL)
    driver.communicate()
    deadline = time.monotonic() + 10
    while (worker_pids(str(tmp)) or list(tmp.iterdir())) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not worker_pids(str(tmp)), "a worker outlived its driver"
    assert not list(tmp.iterdir()), f"temporary files left: {list(tmp.iterdir())}"
    assert (out / ".compare.lock").read_text().strip() == str(driver.pid)       # stale
    again = compare_proc(*args, "--resume", env={"TMPDIR": str(tmp)})
    _, err = again.communicate(timeout=300)
    assert again.returncode == 0, err
    assert [r.status for r in Store.read(out / "results.json").records] == ["ok"]
    deadline = time.monotonic() + 10          # the reaper removes the root as the driver exits
    while list(tmp.iterdir()) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not (out / ".compare.lock").exists() and not list(tmp.iterdir())
    FIGURES["faults"] += ["a driver killed with SIGKILL (worker, temporaries)", "a second driver on one --out",
                          "a dead driver's lock (--resume)"]


@pytest.mark.slow
def test_full_disk_mid_run_keeps_every_saved_record_and_resume_finishes(tmp_path):
    """COMPARE_FAULT_DISK=6: the seventh write fails as a full disk does (each cell's record is
    saved as results.json, .csv and .md). The records saved before stay in results.json, no
    temporary file is left, one line and exit 1; --resume runs exactly the missing cells."""
    out = tmp_path / "out"
    args = ["run", "saxpy", "sdf", "projectile", "--quick", "--backends", "numba", "--devices", "cpu",
            "--precision", "float32", "--repeat", "1", "--min-time", "0", "--no-plots", "--out", str(out)]
    p = compare_proc(*args, env={"COMPARE_FAULT_DISK": "6", "CI": "1"})
    _, err = p.communicate(timeout=600)
    assert p.returncode == 1, err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"error: cannot write {out / 'results.json'}: No space left on device") and \
        "--resume" in last, err
    assert "Traceback" not in err
    kept = Store.read(out / "results.json").records
    assert [r.scenario for r in kept] == ["saxpy", "sdf"] and all(r.status == "ok" for r in kept)
    assert sorted(p.name for p in out.iterdir()) == ["results.csv", "results.json", "results.md"]
    p = compare_proc(*args, "--resume", env={"CI": "1"})
    _, err = p.communicate(timeout=600)
    assert p.returncode == 0, err
    ran = [ln for ln in err.splitlines() if ln.startswith("  ") and ": ok" in ln]
    assert len(ran) == 1 and "projectile/numba" in ran[0], err
    recs = Store.read(out / "results.json").records
    FIGURES["records_lost"] += sum(1 for r in kept if r.scenario not in {q.scenario for q in recs})
    assert [r.scenario for r in recs] == ["saxpy", "sdf", "projectile"]
    assert [{k: getattr(r, k) for k in ("time", "params")} for r in recs[:2]] == \
        [{k: getattr(r, k) for k in ("time", "params")} for r in kept]
    assert not [q for q in out.rglob(".*.tmp")]
    FIGURES["faults"].append("a full disk mid-run (then --resume)")


@pytest.mark.slow
def test_full_disk_while_saving_arrays_leaves_no_partial_npz(tmp_path):
    """The disk fills while --save-arrays files are written: no truncated .npz, no temporary,
    exit 1 with one line; the cell whose arrays failed has no record (--resume runs it again),
    the results saved before are complete and a report of them works."""
    out = tmp_path / "out"
    # writes: the first cell's .npz, results.json, .csv, .md (4), then the second cell's .npz fails
    p = compare_proc("saxpy", "--quick", "--backends", "numba", "--devices", "cpu", "--repeat", "1",
                     "--min-time", "0", "--no-plots", "--save-arrays", "--out", str(out),
                     env={"COMPARE_FAULT_DISK": "4", "CI": "1"})
    _, err = p.communicate(timeout=600)
    assert p.returncode == 1 and "Traceback" not in err, err
    assert "No space left on device" in err.strip().splitlines()[-1]
    assert len(Store.read(out / "results.json").records) == 1
    assert [f.name for f in out.rglob("*.npz")] == ["saxpy-numba-cpu-float32.npz"] and not list(out.rglob(".*.tmp"))
    r = compare_proc("report", str(out / "results.json"), "--out", str(tmp_path / "rep"), "--no-plots")
    _, err = r.communicate(timeout=300)
    assert r.returncode == 0, err
    FIGURES["faults"].append("a full disk while saving arrays")
