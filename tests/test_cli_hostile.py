"""Hostile command lines and faults (issue 30, items 3 and 4; docs/reliability.md).

CLI: a path or title that is not UTF-8, holds a control character or is too long; an
unreachable --scheduler; --page naming a directory; a plan with nothing to run. Each is refused
in one line (exit 2, no traceback) and leaves nothing behind: no lock, no --out.
Faults (real processes): a worker that saved its record but never exits, a yardstick child whose
driver is killed, a driver killed mid-run (results.csv/.md against results.json), a full disk
while saving arrays, then --resume: the arrays recreated and the yardstick filled in.
"""
from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from compare import cli
from compare.planning import outdir
from compare.options import UsageError
from compare.results.store import Store
from compare.suites import listing

ROOT = Path(__file__).resolve().parents[1]
FAULTY = ROOT / "tests" / "extra_backends"     # COMPARE_BACKENDS_EXTRA: the tests' faulty backend
NUMPY = ("--backends", "numpy", "--devices", "cpu", "--quick", "--precision", "float32")
FAST = ("--repeat", "1", "--min-time", "0", "--no-plots")
pytestmark = pytest.mark.cli


def snapshot(root: Path) -> dict[str, tuple]:
    """Every path under ``root``: kind, size, mtime, content hash."""
    out = {}
    for p in sorted(root.rglob("*")):
        st = p.lstat()
        digest = hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() and not p.is_symlink() else ""
        out[str(p.relative_to(root))] = (p.is_dir(), st.st_size, st.st_mtime_ns, digest)
    return out


def refused(argv: list, work: Path, needle: str = "") -> str:
    """compare.cli.main in this process: exit 2, one stderr line holding ``needle``, nothing
    written under ``work`` (which holds the inputs and every --out)."""
    before = snapshot(work)
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        rc = cli.main(argv)
    lines = err.getvalue().splitlines()
    assert rc == 2 and len(lines) == 1 and lines[0].startswith("error: "), (argv, rc, lines)
    assert needle in lines[0], (needle, lines[0])
    assert snapshot(work) == before, (argv, "wrote something")
    return lines[0]


def compare_proc(*args: str | bytes, env: dict | None = None, cwd: Path = ROOT) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "compare", *args], cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env={**os.environ, "PYTHONPATH": str(ROOT), "CI": "1",
                                                         **(env or {})})


def finished(p: subprocess.Popen, timeout: float = 300) -> tuple[int, str]:
    _, err = p.communicate(timeout=timeout)
    text = err.decode("utf-8", "backslashreplace")
    assert "Traceback" not in text, text
    return p.returncode, text


@pytest.fixture()
def work(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    w = tmp_path / "work"
    w.mkdir()
    (w / "run.json").write_text(json.dumps({"format_version": 2, "suite": "run", "runs": [{}], "records": []}))
    (w / "sweep.json").write_text(json.dumps({"format_version": 2, "suite": "sweep", "runs": [{}], "records": []}))
    (w / "a\nb").write_text("a file whose name holds a newline\n")
    (w / "adir").mkdir()
    monkeypatch.chdir(w)
    return w


# ---- CLI ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("argv", [
    ["saxpy", *NUMPY, "--out", b"out\xff"],
    ["saxpy", *NUMPY, b"--out=out\xff"],
    ["report", "run.json", "--out", "out", "--page", "p.md", "--title", b"T\xff"],
    ["sweep", "report", "sweep.json", "--out", b"o\xfe/x"],
], ids=["out", "out=", "title", "sweep-out"])
def test_non_utf8_words_are_refused_up_front(work: Path, argv: list) -> None:
    """Real argv bytes (decoded with surrogateescape): one line that shows the byte, nothing written."""
    before = snapshot(work)
    rc, err = finished(compare_proc(*argv, cwd=work))
    assert rc == 2 and err.count("\n") == 1 and "not valid UTF-8" in err and "\\x" in err, err
    assert snapshot(work) == before


@pytest.mark.parametrize("argv,needle", [
    (["saxpy", *NUMPY, "--out", "a\nb"], "--out a\\nb: is a file"),
    (["saxpy", *NUMPY, "--out", "a\nb/x\x1b[31m"], "a\\nb is a file"),
    (["report", "no\nsuch\x07.json", "--out", "out"], "no\\nsuch\\x07.json"),
    (["stress", "--merge", "x\ry\u2028.json", "--out", "out"], "x\\ry\\u2028.json"),
    (["report", "run.json", "--out", "out", "--page", "p.md", "--title", "two\nlines"], "--title two\\nlines"),
    (["saxpy", *NUMPY, "--out", "out\udcff"], "out\\xff"),
])
def test_control_characters_in_errors_are_escaped(work: Path, argv: list, needle: str) -> None:
    refused(argv, work, needle)


LONG = "a" * 300


@pytest.mark.parametrize("argv,needle", [
    (["saxpy", *NUMPY, "--out", LONG], "300 bytes long"),
    (["saxpy", *NUMPY, "--out", "/".join(["b" * 200] * 21)], "too long"),
    (["sweep", "bandwidth", "--quick", "--out", f"x/{LONG}"], "300 bytes long"),
    (["report", "run.json", "--out", "out", "--page", f"{LONG}.md"], "--page"),
    (["report", "run.json", "--out", "out", "--page", f"adir/{LONG}/p.md"], "--page adir/aaa"),
    (["report", f"{LONG}.json", "--out", "out"], "File name too long"),
    (["stress", "--only", "ulps", "--out", LONG], "--out"),
])
def test_a_too_long_path_is_a_usage_error(work: Path, argv: list, needle: str) -> None:
    line = refused(argv, work, needle)
    assert "free some space" not in line and "--resume" not in line


def test_a_name_too_long_mid_run_is_exit_2_without_disk_advice(capsys: pytest.CaptureFixture) -> None:
    """The safety net in cli.main: ENAMETOOLONG from any write is bad usage, not a full disk."""
    def boom(*_: object) -> int:
        raise OSError(36, "File name too long", "/x/" + LONG)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(listing.Listing, "run", boom)
        assert cli.main(["list"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "name too long" in err[0] and "free some space" not in err[0], err


@pytest.mark.parametrize("argv", [["saxpy", *NUMPY],
                                  ["sweep", "bandwidth", "--quick", "--backends", "numpy", "--devices", "cpu"]],
                         ids=["run", "sweep"])
def test_an_unreachable_scheduler_leaves_no_lock_and_no_out(work: Path, monkeypatch: pytest.MonkeyPatch,
                                                              argv: list) -> None:
    distributed = pytest.importorskip("distributed")
    real = distributed.Client
    monkeypatch.setattr(distributed, "Client", lambda *a, **k: real(*a, **{**k, "timeout": "1s"}))
    refused([*argv, "--scheduler", "tcp://127.0.0.1:1", "--out", "out/deep"], work,
            "--scheduler tcp://127.0.0.1:1: cannot connect")
    assert not (work / "out").exists()


@pytest.mark.parametrize("argv", [
    ["report", "run.json", "--out", "out", "--page", "adir"],
    ["report", "run.json", "--out", "out", "--page", "."],
    ["sweep", "report", "sweep.json", "--out", "out", "--page", "adir"],
    ["sweep", "bandwidth", "--quick", "--backends", "numpy", "--devices", "cpu", "--out", "out", "--page", "adir"],
    ["sweep", "report", "sweep.json", "--out", "adir/.."],          # its default page is adir/../measurement.md
], ids=["report", "report-dot", "sweep-report", "sweep", "sweep-default-page"])
def test_a_page_naming_a_directory_is_refused_before_out_exists(work: Path, argv: list) -> None:
    if argv[-1] == "adir/..":
        (work / "measurement.md").mkdir()
    refused(argv, work, "is a directory")
    assert not (work / "out").exists()


@pytest.mark.parametrize("argv", [
    ["report", "run.json", "--out", "out", "--page", "/proc/x.md"],
    ["sweep", "report", "sweep.json", "--out", "out", "--page", "/proc/x.md"],
], ids=["report", "sweep-report"])
@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="no /proc on this system")
def test_a_page_in_a_directory_that_takes_no_file_is_refused_before_out_exists(work: Path, argv: list) -> None:
    """/proc passes a permission check (as root) but creates no file: tried, not assumed."""
    refused(argv, work, "--page /proc/x.md: cannot write there")
    assert not (work / "out").exists()


@pytest.mark.parametrize("argv", [
    ["sweep", "scaling", "--scenarios", "saxpy", "--devices", "cuda", "--quick"],      # no points
    ["sweep", "horizon", "--backends", "numpy", "--devices", "cuda", "--quick"],       # every cell skipped
    ["saxpy", "--backends", "numpy", "--devices", "cuda", "--quick"],
    ["run", "saxpy", "sdf", "--backends", "numpy", "--devices", "cuda", "--quick", "--resume"],
    ["stress", "--backends", "numpy", "--devices", "cuda", "--quick", "--only", "ulps"],
], ids=["sweep-empty", "sweep-skipped", "run-skipped", "run-resume-skipped", "stress-skipped"])
def test_nothing_to_run_is_exit_2_and_writes_nothing(work: Path, argv: list) -> None:
    refused([*argv, "--out", "out"], work, "nothing to run")
    assert not (work / "out").exists()


def test_a_refusal_under_the_lock_removes_the_directories_its_claim_made(work: Path) -> None:
    out, lock = outdir.claim_output("new/a/b")
    with pytest.raises(UsageError):
        with lock:
            assert (out / ".compare.running.lock").is_file()
            raise UsageError("refused after the claim")
    assert not (work / "new").exists()
    (work / "kept").mkdir()
    out, lock = outdir.claim_output("kept/x")           # existing directories are never removed
    with pytest.raises(KeyboardInterrupt):
        with lock:
            raise KeyboardInterrupt
    assert sorted(os.listdir(work / "kept")) == []
    out, lock = outdir.claim_output("done")              # a normal exit keeps what it made
    with lock:
        pass
    assert (work / "done").is_dir()


# ---- faults ---------------------------------------------------------------------------------------
def running(marker: str) -> list[int]:
    """PIDs of the processes whose command line holds ``marker``."""
    found = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if marker in (d / "cmdline").read_bytes().decode(errors="replace"):
                    found.append(int(d.name))
            except OSError:
                pass
    return found


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_timeout_covers_a_worker_that_saved_its_record_but_never_exits(work: Path, monkeypatch) -> None:
    from compare.running import lifeline
    real = lifeline.command
    marker = "hangs-at-exit-" + str(os.getpid())
    hang = f"import atexit, sys, time; atexit.register(time.sleep, 600); from compare.running import lifeline; " \
           f"lifeline.main(sys.argv[1:])  # {marker}"
    monkeypatch.setattr(lifeline, "command",
                        lambda *a: [sys.executable, "-c", hang, *a] if a[:1] == ("compare.running.worker",) else real(*a))
    err = io.StringIO()
    t0 = time.monotonic()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        # warm: a cold cell's worker skips its exit handlers (compare/running/caches.py, leave)
        rc = cli.main(["saxpy", *NUMPY, *FAST, "--cache", "warm", "--timeout", "5", "--out", "out"])
    took = time.monotonic() - t0
    assert rc == 0, err.getvalue()
    assert "did not exit within --timeout 5 s" in err.getvalue() and "Traceback" not in err.getvalue()
    assert [r.status for r in Store.read(work / "out" / "results.json").records] == ["ok"]
    assert took < 5 + 20, took                   # probes and yardstick, then at most the timeout
    assert not running(marker)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
def test_the_yardstick_child_dies_with_its_driver(tmp_path: Path) -> None:
    marker = f"yardstick-sleeps-{os.getpid()}"
    driver = subprocess.Popen([sys.executable, "-c", f"""
import sys
from compare.running import hardware, lifeline
real = lifeline.command
child = "import time; time.sleep(600)  # " + "yardstick" + "-sleeps-{os.getpid()}"   # marker not in this line
lifeline.command = lambda *a: real("-c", child) if a[:1] == ("compare.running.hardware",) else real(*a)
print(hardware.measure("cpu"))
"""], cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT), "TMPDIR": str(tmp_path)})
    try:
        deadline = time.monotonic() + 60
        while not running(marker) and time.monotonic() < deadline:
            assert driver.poll() is None
            time.sleep(0.1)
        assert running(marker), "no yardstick child started through compare.running.lifeline"
        driver.send_signal(signal.SIGKILL)
        driver.wait()
        deadline = time.monotonic() + 10
        while running(marker) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not running(marker), "the yardstick outlived its driver"
    finally:
        for pid in running(marker):          # only if the test failed: no sleeper left behind
            os.kill(pid, signal.SIGKILL)
        if driver.poll() is None:
            driver.kill()


def _tables(out: Path) -> tuple[list[tuple], list[tuple], str]:
    """(cells in results.json, cells in results.csv, results.md)."""
    cell = ("scenario", "backend", "device", "precision", "status")
    js = sorted(tuple(getattr(r, k) for k in cell) for r in Store.read(out / "results.json").records)
    with open(out / "results.csv", newline="") as f:
        rows = sorted(tuple(r[k] for k in cell) for r in csv.DictReader(f))
    return js, rows, (out / "results.md").read_text()


def test_tables_agree_with_results_json_after_a_kill_and_resume(tmp_path: Path) -> None:
    out = tmp_path / "out"
    args = ["run", "saxpy", "sdf", *NUMPY, *FAST, "--out", str(out)]
    args[args.index("numpy")] = "faulty"          # the tests' backend: NumPy's kernels, sdf's hangs
    driver = compare_proc(*args, env={"COMPARE_BACKENDS_EXTRA": str(FAULTY), "COMPARE_FAULT": "sdf:hang"})
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:            # saxpy saved; the sdf worker hangs
        if (out / "results.md").exists() and "\n## saxpy (" in (out / "results.md").read_text():
            break
        assert driver.poll() is None, driver.communicate()
        time.sleep(0.1)
    driver.send_signal(signal.SIGKILL)
    driver.communicate()
    js, rows, md = _tables(out)
    assert js == rows == [("saxpy", "faulty", "cpu", "float32", "ok")]
    assert "\n## saxpy (" in md and "\n## sdf (" not in md
    rc, err = finished(compare_proc(*args, "--resume", env={"COMPARE_BACKENDS_EXTRA": str(FAULTY)}))
    assert rc == 0, err
    js, rows, md = _tables(out)
    assert js == rows and [c[0] for c in js] == ["saxpy", "sdf"] and "\n## sdf (" in md
    assert not (out / ".compare.running.lock").exists()


def test_full_disk_while_saving_arrays_then_resume_recreates_them_and_fills_the_yardstick(tmp_path: Path) -> None:
    out = tmp_path / "out"
    arrays = out / "arrays"
    args = ["saxpy", "--backends", "numpy", "--devices", "cpu", "--quick", *FAST, "--save-arrays", "--out", str(out)]
    # writes of the first cell: its .npz, results.json, .csv, .md; the second cell's .npz fails
    rc, err = finished(compare_proc(*args, env={"COMPARE_FAULT_DISK": "4"}))
    assert rc == 1 and err.strip().splitlines()[-1].startswith(
        f"error: cannot write {arrays / 'saxpy-numpy-cpu-float64.npz'}: No space left on device"), err
    assert [r.precision for r in Store.read(out / "results.json").records] == ["float32"]
    assert sorted(p.name for p in arrays.iterdir()) == ["saxpy-numpy-cpu-float32.npz"]
    assert not list(out.rglob(".*.tmp")) and not (out / ".compare.running.lock").exists()
    js, rows, _ = _tables(out)
    assert js == rows

    rc, err = finished(compare_proc(*args, "--resume", env={"COMPARE_FAULT_DISK": "0"}))   # still full
    assert rc == 1 and "No space left on device" in err.strip().splitlines()[-1], err
    assert sorted(p.name for p in arrays.iterdir()) == ["saxpy-numpy-cpu-float32.npz"]

    # a kept cell without its yardstick (as older versions left a killed run's) keeps none: it is
    # never judged against a later run's, which did not measure it (issue 40)
    data = json.loads((out / "results.json").read_text())
    rec = data["records"][0]
    rec.pop("hardware")
    for k in ("floor_s", "floor_kind", "floor", "hw_fraction"):
        rec["throughput"].pop(k)
    (out / "results.json").write_text(json.dumps(data))
    rc, err = finished(compare_proc(*args, "--resume"))
    assert rc == 0, err
    recs = {r.precision: r.to_json() for r in Store.read(out / "results.json").records}
    assert recs["float32"]["time"] == rec["time"]                  # kept, not rerun
    assert "hardware" not in recs["float32"] and "hw_fraction" not in recs["float32"]["throughput"]
    assert "hardware" in recs["float64"] and recs["float64"]["throughput"]["hw_fraction"] > 0
    assert sorted(p.name for p in arrays.iterdir()) == ["saxpy-numpy-cpu-float32.npz", "saxpy-numpy-cpu-float64.npz"]

    (arrays / "saxpy-numpy-cpu-float32.npz").unlink()              # a kept cell's arrays gone: run again
    rc, err = finished(compare_proc(*args, "--resume", "--verbose"))
    ran = [ln.split("] ", 1)[-1] for ln in err.splitlines() if ": ok" in ln]     # "  [i/n] cell: ok"
    assert rc == 0 and ran == ["saxpy/numpy/cpu/float32/default: ok"], err
    assert (arrays / "saxpy-numpy-cpu-float32.npz").is_file()
    js, rows, _ = _tables(out)
    assert js == rows and len(js) == 2


def test_a_closed_output_pipe_is_not_a_full_disk() -> None:
    """`compare agree A B | head`: the reader gone is no write failure to explain (no disk advice,
    no traceback from the last flush); a command that measures nothing says nothing."""
    store = str(ROOT / "tests" / "data" / "site")
    r, w = os.pipe()
    os.close(r)
    try:
        p = subprocess.run([sys.executable, "-m", "compare", "agree", store, store], stdout=w,
                           stderr=subprocess.PIPE, text=True, cwd=ROOT, timeout=120)
    finally:
        os.close(w)
    assert p.returncode == 1 and p.stderr == "", p.stderr
    assert not cli._records(["agree"]) and not cli._records(["site"]) and cli._records(["saxpy"])
