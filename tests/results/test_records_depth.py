"""Blocks nested past any reader's recursion (issue 41, item 6): a stored record whose ``info`` (or
a key no version names, or a run's environment) is nested hundreds of levels deep is one line
naming the block (exit 2, nothing written) from every reader, never a RecursionError traceback.
The bound is ``compare.results.records.MAX_DEPTH``; the corruption table lives in test_hostile_files.py."""
from __future__ import annotations

import copy
import json
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT
from test_records import BASE, ok, readers, run_main, snapshot

DEEPS = {"info": ("info", "info"), "unnamed-key": ("notes", "notes"), "run-environment": ("backends", "runs[0]")}


def deep_store(tmp: Path, case: str, levels: int) -> tuple[Path, str]:
    """A run store with one block nested ``levels`` deep (written as text: building it in Python
    would recurse too), and the words of its refusal."""
    key, named = DEEPS[case]
    doc = copy.deepcopy(BASE["run"])
    (doc["runs"][0] if case == "run-environment" else ok()(doc))[key] = "@DEEP@"
    (tmp / "store").mkdir()
    f = tmp / "store" / "results.json"
    f.write_text(json.dumps(doc).replace('"@DEEP@"', '{"a": ' * levels + "{}" + "}" * levels))
    return f, f"{named} is nested more than 64 levels deep"


@pytest.mark.parametrize("case", list(DEEPS))
def test_a_store_nested_past_the_bound_is_one_line_naming_where(tmp_path: Path, case: str) -> None:
    """Past the bound (64 levels; the stores hold 7) every reader refuses the file, --resume
    included, with one line naming the block; nothing is written."""
    f, needle = deep_store(tmp_path, case, 200)
    for argv in readers("run", f, tmp_path):
        before = snapshot(tmp_path)
        rc, lines = run_main(argv)
        assert rc == 2 and len(lines) == 1 and needle in lines[0] and str(f) in lines[0], (argv, rc, lines)
        assert snapshot(tmp_path) == before and not any(p.name.startswith("o-") for p in tmp_path.iterdir()), argv


@pytest.mark.parametrize("case,reader", [("info", 0), ("info", 1), ("info", 2), ("run-environment", 2)],
                         ids=["info-report", "info-site", "info-resume", "run-environment-resume"])
def test_a_store_nested_950_levels_is_refused_from_the_command_line(tmp_path: Path, case: str, reader: int) -> None:
    """The reported case, as a user meets it (a fresh interpreter, whose JSON parser takes 950
    levels that pytest's deeper stack would not): a RecursionError traceback before the bound."""
    f, needle = deep_store(tmp_path, case, 950)
    argv = readers("run", f, tmp_path)[reader]
    before = snapshot(tmp_path)
    p = subprocess.run([sys.executable, "-m", "compare", *argv], cwd=ROOT, capture_output=True, text=True,
                       timeout=300)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and needle in p.stderr, (argv, p.returncode, p.stderr)
    assert snapshot(tmp_path) == before
