"""Faults (docs/reliability.md): nothing lost, nothing leaked. In this process: a second holder of
a lock, a stale lock, a filesystem without flock, a full disk in an atomic write, temporaries a
killed driver left. In real processes: a driver killed with SIGKILL while its worker hangs, a
second driver on a locked --out, a full disk mid-run (COMPARE_FAULT_DISK) and while saving
arrays, each followed by --resume."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from compare.planning import outdir
from compare.running.lock import Busy, DirectoryLock
from compare.results.store import Store, atomic_write
from conftest import FAULTY
from reliability_checks import FIGURES, QUICK, compare_proc

pytestmark = pytest.mark.cli


# ---- locks and atomic writes, in this process ----------------------------------------------------
def test_lock_refuses_a_second_holder_and_takes_over_a_stale_one(tmp_path, monkeypatch):
    a = DirectoryLock(tmp_path).acquire()
    with pytest.raises(Busy, match=f"PID {os.getpid()}"):
        DirectoryLock(tmp_path).acquire()
    a.release()
    assert not (tmp_path / ".compare.running.lock").exists()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    (tmp_path / ".compare.running.lock").write_text(f"{dead.pid}\n")        # left by a dead driver
    with DirectoryLock(tmp_path) as lock:
        assert (tmp_path / ".compare.running.lock").read_text().strip() == str(os.getpid()) and lock.held
    # a filesystem without flock: exclusive creation, a dead PID's file taken over
    import fcntl

    def no_flock(*a):
        raise OSError(37, "No locks available")
    monkeypatch.setattr(fcntl, "flock", no_flock)
    (tmp_path / ".compare.running.lock").write_text(f"{dead.pid}\n")
    b = DirectoryLock(tmp_path).acquire()
    with pytest.raises(Busy, match=f"PID {os.getpid()}"):
        DirectoryLock(tmp_path).acquire()
    b.release()
    assert not (tmp_path / ".compare.running.lock").exists()
    FIGURES["faults"] += ["a second holder of a lock", "a stale lock of a dead PID",
                          "a filesystem without flock"]


def test_atomic_write_on_a_full_disk_keeps_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    from compare import files
    f = tmp_path / "results.json"
    atomic_write(f, "old")
    monkeypatch.setenv("COMPARE_FAULT_DISK", "0")
    monkeypatch.setattr(files, "_WRITES", [0])
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
    out, lock = outdir.claim_output(str(tmp_path))
    with lock:
        assert not any(p.exists() for p in left) and all(p.exists() for p in users)
    FIGURES["faults"].append("temporaries left by a killed driver")


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
    # the tests' faulty backend as Numba (a compiled worker), its saxpy cell hanging after the run
    env = {"TMPDIR": str(tmp), "COMPARE_BACKENDS_EXTRA": str(FAULTY), "COMPARE_FAULTY_WRAPS": "numba"}
    args = ["saxpy", *QUICK, "--set", "n=1000", "--repeat", "1", "--min-time", "0", "--no-plots", "--out", str(out)]
    args[args.index("numba")] = "faulty"
    driver = compare_proc(*args, env={**env, "COMPARE_FAULT": "saxpy:hang"})
    deadline = time.monotonic() + 120
    while not worker_pids(str(tmp)) and time.monotonic() < deadline:
        assert driver.poll() is None, driver.communicate()
        time.sleep(0.1)
    assert worker_pids(str(tmp)), "no worker started"
    second = compare_proc(*args, env=env)
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
    assert (out / ".compare.running.lock").read_text().strip() == str(driver.pid)       # stale
    # the cell on NumPy's kernels (none to compile): the dead driver's lock taken over is the subject
    again = compare_proc(*args, "--resume", env={k: v for k, v in env.items() if k != "COMPARE_FAULTY_WRAPS"})
    _, err = again.communicate(timeout=300)
    assert again.returncode == 0, err
    assert [r.status for r in Store.read(out / "results.json").records] == ["ok"]
    deadline = time.monotonic() + 10          # the reaper removes the root as the driver exits
    while list(tmp.iterdir()) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not (out / ".compare.running.lock").exists() and not list(tmp.iterdir())
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
    # the first two cells to finish (in plan order, or as overlapped set-ups let them finish)
    assert len(kept) == 2 and all(r.status == "ok" for r in kept)
    missing = ({"saxpy", "sdf", "projectile"} - {r.scenario for r in kept}).pop()
    assert sorted(p.name for p in out.iterdir()) == ["results.csv", "results.json", "results.md"]
    p = compare_proc(*args, "--resume", "--verbose", env={"CI": "1"})     # --verbose: a line per cell
    _, err = p.communicate(timeout=600)
    assert p.returncode == 0, err
    ran = [ln for ln in err.splitlines() if ln.startswith("  [") and ": ok" in ln]
    assert len(ran) == 1 and f"{missing}/numba" in ran[0], err
    recs = Store.read(out / "results.json").records
    FIGURES["records_lost"] += sum(1 for r in kept if r.scenario not in {q.scenario for q in recs})
    assert sorted(r.scenario for r in recs) == ["projectile", "saxpy", "sdf"]
    same = {r.scenario: {k: getattr(r, k) for k in ("time", "params")} for r in recs}
    assert [same[r.scenario] for r in kept] == [{k: getattr(r, k) for k in ("time", "params")} for r in kept]
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
