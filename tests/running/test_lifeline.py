"""compare/running/lifeline.py: workers die with their driver, and temporary roots with them
(fast tier: a few short processes)."""
from __future__ import annotations

import fcntl
import os
import subprocess
import sys
import time
from pathlib import Path

from compare.running import lifeline

ROOT = Path(__file__).resolve().parents[2]


def run(*args, env=None):
    return subprocess.run(lifeline.command(*args), cwd=ROOT, capture_output=True, text=True, timeout=60,
                          env={**os.environ, **(env or {})})


def test_command_and_environment_name_the_parent_and_its_temporaries(tmp_path):
    assert lifeline.command("compare.running.worker", "a") == [sys.executable, "-m", "compare.running.lifeline",
                                                               "compare.running.worker", "a"]
    env = lifeline.child_environment({"X": "1"}, tmp_path)
    assert env["X"] == "1" and env[lifeline.PARENT_ENV] == str(os.getpid())
    assert env["TMPDIR"] == env["TEMP"] == env["TMP"] == str(tmp_path)


def test_a_worker_runs_code_or_a_module_with_its_arguments():
    p = run("-c", "import sys; print(sys.argv[1:])", "a", "b")
    assert p.returncode == 0 and p.stdout.strip() == "['a', 'b']", p.stderr
    p = run("json.tool", "--help")
    assert p.returncode == 0 and "json.tool" in p.stdout
    p = run()
    assert p.returncode != 0 and "usage: python -m compare.running.lifeline" in p.stderr


def test_a_worker_whose_parent_is_already_gone_exits_at_once():
    p = run("-c", "print('ran')", env={lifeline.PARENT_ENV: "1"})       # pid 1 is not its parent
    assert p.returncode == 137 and p.stdout == ""
    p = run("-c", "import os; print(os.environ.get('COMPARE_PARENT_PID'))",
            env={lifeline.PARENT_ENV: str(os.getpid())})
    assert p.returncode == 0 and p.stdout.strip() == "None"              # read once, not passed on


def test_only_roots_whose_driver_is_gone_are_cleaned(tmp_path):
    gone, alive, making = (tmp_path / f"{lifeline.PREFIX}{n}" for n in ("1-a", "2-b", "3-c"))
    for d in (gone, alive, making):
        d.mkdir()
    (gone / ".owner").write_text("1\n")
    (alive / ".owner").write_text("2\n")
    (tmp_path / "other").mkdir()
    fd = os.open(alive / ".owner", os.O_RDONLY)
    fcntl.flock(fd, fcntl.LOCK_EX)
    try:
        assert lifeline.clean_stale(tmp_path) == [gone]
    finally:
        os.close(fd)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["compare-2-b", "compare-3-c", "other"]
    assert lifeline.clean_stale(tmp_path / "absent") == []


def test_a_drivers_root_goes_when_the_driver_exits(tmp_path):
    code = ("from compare.running import lifeline; r = lifeline.temp_root(); "
            "d = lifeline.temp_dir('cell-'); print(r, d.name, r == lifeline.temp_root(), sep='|')")
    p = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=60,
                       env={**os.environ, "TMPDIR": str(tmp_path)})
    assert p.returncode == 0, p.stderr
    root, cell, same = p.stdout.strip().split("|")
    assert Path(root).parent == tmp_path and Path(root).name.startswith(lifeline.PREFIX)
    assert Path(cell).parent == Path(root) and same == "True"
    deadline = time.monotonic() + 20                  # the reaper sees the pipe close, then deletes
    while Path(root).exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not Path(root).exists()
