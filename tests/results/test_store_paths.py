"""Hostile input: nothing followed through a symbolic link, no path built from a record leaves
its folder (issue 30's security items; the adversarial suite grows here)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from compare.running.lock import Busy, DirectoryLock
from compare.results.store import StoreError, array_file, load_arrays, save_arrays

ROOT = Path(__file__).resolve().parents[2]
CELL = {"scenario": "saxpy", "backend": "numpy", "device": "cpu", "precision": "float32"}


def test_lock_refuses_a_planted_symlink_and_leaves_its_target_alone(tmp_path: Path) -> None:
    target = tmp_path / "precious.txt"
    target.write_text("keep me\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / ".compare.running.lock").symlink_to(target)
    with pytest.raises(Busy, match="symbolic link"):
        DirectoryLock(out).acquire()
    assert target.read_text() == "keep me\n"


def test_a_command_refuses_the_symlinked_lock_in_one_line(tmp_path: Path) -> None:
    target = tmp_path / "precious.txt"
    target.write_text("keep me\n")
    out = tmp_path / "out"
    out.mkdir()
    (out / ".compare.running.lock").symlink_to(target)
    p = subprocess.run([sys.executable, "-m", "compare", "site", str(ROOT / "tests/data/site"), "--out", str(out)],
                       cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "symbolic link" in p.stderr, p.stderr
    assert target.read_text() == "keep me\n"
    assert sorted(os.listdir(out)) == [".compare.running.lock"]


@pytest.mark.parametrize("field,value", [("backend", "x/../../outside"), ("scenario", "../saxpy"),
                                         ("device", "cpu/.."), ("precision", ""), ("variant", "a b"),
                                         ("backend", None), ("variant", 3)])
def test_array_paths_from_records_stay_in_arrays(tmp_path: Path, field: str, value: object) -> None:
    rec = {**CELL, field: value}
    with pytest.raises(StoreError):
        array_file(tmp_path, rec)
    with pytest.raises(StoreError):
        save_arrays(tmp_path, rec, {"out": np.zeros(2)})
    assert load_arrays(tmp_path, rec, ["out"]) is None
    assert not any(tmp_path.rglob("*.npz"))


def test_a_plain_cell_round_trips_and_a_symlinked_array_is_not_read(tmp_path: Path) -> None:
    save_arrays(tmp_path, {**CELL, "variant": "fastmath"}, {"out": np.arange(3.0)})
    got = load_arrays(tmp_path, {**CELL, "variant": "fastmath"}, ["out"])
    assert got is not None and got["out"].tolist() == [0.0, 1.0, 2.0]
    outside = tmp_path / "outside.npz"
    np.savez(outside, out=np.ones(2))
    link = array_file(tmp_path, CELL)
    link.symlink_to(outside)
    assert load_arrays(tmp_path, CELL, ["out"]) is None


@pytest.mark.parametrize("argv", [["saxpy", "--repeat", "3", "--repeat", "4"],
                                  ["site", "tests/data/site", "--out", "a", "--out=b"],
                                  ["sweep", "report", "x.json", "--title", "a", "--title=b"],
                                  ["stress", "--only", "ulps", "--only", "races"]])
def test_a_single_valued_option_given_twice_is_refused(tmp_path: Path, argv: list[str]) -> None:
    p = subprocess.run([sys.executable, "-m", "compare", *argv], cwd=tmp_path, capture_output=True, text=True,
                       env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120)
    assert p.returncode == 2 and "given 2 times" in p.stderr and p.stderr.count("\n") == 1, p.stderr
    assert list(tmp_path.iterdir()) == []


def _special_files(tmp_path: Path) -> dict[str, Path]:
    fifo = tmp_path / "fifo.json"
    os.mkfifo(fifo)
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 100_000 + "]" * 100_000)
    real = tmp_path / "real.json"
    real.write_text((ROOT / "tests/data/site/results.json").read_text())
    link = tmp_path / "link.json"
    link.symlink_to(real)
    return {"a FIFO": fifo, "/dev/zero": Path("/dev/zero"), "deep nesting": deep, "a symlink": link,
            "a directory": tmp_path}


@pytest.mark.parametrize("what", ["a FIFO", "/dev/zero", "deep nesting", "a symlink", "a directory"])
def test_readers_refuse_special_files_at_once(tmp_path: Path, what: str) -> None:
    """No hang, no memory blow-up, no traceback: one line naming the file, exit 2."""
    path = _special_files(tmp_path)[what]
    for argv in (["report", str(path), "--out", str(tmp_path / "o1")],
                 ["site", str(path), "--out", str(tmp_path / "o2")],
                 ["sweep", "report", str(path), "--out", str(tmp_path / "o3")],
                 ["sweep", "report", str(ROOT / "tests/data/site/sweep.json"), "--notes", str(path),
                  "--out", str(tmp_path / "o4")]):
        if "--notes" in argv and what in ("a directory", "deep nesting"):   # text: fine notes
            continue
        p = subprocess.run([sys.executable, "-m", "compare", *argv], cwd=ROOT, capture_output=True, text=True,
                           timeout=60)
        assert p.returncode == 2 and p.stderr.count("\n") == 1 and "Traceback" not in p.stderr, (argv, p.stderr)
        assert "unrecognized" not in p.stderr and ("--notes" in p.stderr) == ("--notes" in argv), p.stderr
        assert not any((tmp_path / o).exists() for o in ("o1", "o2", "o3", "o4")), argv
