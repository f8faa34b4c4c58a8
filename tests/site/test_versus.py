"""compare/site/versus.py: the closing block of ``compare all | run`` against a stored report
(fast tier). The block on a real quick run: tests/render/test_console.py."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from compare.options import UsageError
from compare.results.store import Store
from compare.site import versus

ROOT = Path(__file__).resolve().parents[2]
STORE = ROOT / "tests" / "data" / "site" / "results.json"


def slower(doc, scale):
    """Every time in a stored document ``scale`` times longer."""
    if isinstance(doc, dict):
        return {k: (v * scale if k.endswith("_s") and isinstance(v, (int, float)) and not isinstance(v, bool)
                    else [x * scale for x in v] if k == "values" and isinstance(v, list) else slower(v, scale))
                for k, v in doc.items()}
    if isinstance(doc, list):
        return [slower(x, scale) for x in doc]
    return doc


@pytest.fixture(scope="module")
def mine():
    store = Store.read(STORE)
    return list(store.records), store.runs[0]


def test_chosen_picks_the_report_of_the_machine_kind():
    assert versus.chosen("none", {}) is None and versus.chosen(" NONE ", {}) is None
    label, path = versus.chosen(None, {"gpus": [{"name": "NVIDIA H100"}]})
    assert label.startswith("the H100 report") and path == versus.REFERENCES / "h100"
    assert versus.chosen(None, {})[1] == versus.REFERENCES / "cpu"
    assert versus.chosen("/x/y", {}) == ("the report in /x/y", Path("/x/y"))


def test_an_h200_is_compared_with_the_h200_report_where_one_is_stored(tmp_path, monkeypatch):
    monkeypatch.setattr(versus, "REFERENCES", tmp_path)
    h200 = {"gpus": [{"name": "NVIDIA H200"}]}
    assert versus.chosen(None, h200)[1] == tmp_path / "h100"          # none stored: the H100's
    (tmp_path / "h200").mkdir()
    (tmp_path / "h200" / "results.json").write_text("{}")
    label, path = versus.chosen(None, h200)
    assert label.startswith("the H200 report") and path == tmp_path / "h200"
    assert versus.chosen(None, {"gpus": [{"name": "NVIDIA A100-SXM4-80GB"}]})[1] == tmp_path / "h100"
    assert versus.chosen(None, {"gpus": [{"name": "NVIDIA H100 80GB HBM3"}]})[1] == tmp_path / "h100"
    assert versus.chosen(None, {"gpus": [{"name": "NVIDIA GH200 480GB"}]})[1] == tmp_path / "h100"   # another kind


def test_check_refuses_a_reference_without_results(tmp_path):
    versus.check(None)
    versus.check("none")
    with pytest.raises(UsageError, match="empty"):
        versus.check("  ")
    with pytest.raises(UsageError, match="no results.json there"):
        versus.check(str(tmp_path))
    (tmp_path / "results.json").write_text("{}")
    versus.check(str(tmp_path))
    versus.check(str(tmp_path / "results.json"))


def _against_twice_slower(mine, tmp_path, monkeypatch) -> tuple[list[str], Path, Path]:
    """The block of this run against a reference whose every time (yardstick too) is twice as long."""
    records, env = mine
    ref = tmp_path / "ref"
    ref.mkdir()
    (ref / "results.json").write_text(json.dumps(slower(json.loads(STORE.read_text()), 2.0)))
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    return versus.block(records, env, out, against=str(ref)), ref, out


def test_every_ratio_of_a_twice_slower_reference_is_one_half(mine, tmp_path, monkeypatch):
    lines, ref, out = _against_twice_slower(mine, tmp_path, monkeypatch)
    assert lines[0].startswith(f"This run against the report in {ref}: NVIDIA H100") and "timed cells matched" in lines[0]
    assert lines[1].endswith("every cell: out/against.md")
    rows = [ln for ln in lines[2:] if ln.startswith("    ") and "cells," in ln]
    assert rows and all(ln.split()[2] == "0.50×" for ln in rows), rows
    assert (out / versus.PAGE).read_text().startswith("# This run against the reference")


def test_a_reference_slower_with_its_launch_floor_is_level_in_floors(mine, tmp_path, monkeypatch):
    """Every time twice as long there, its yardstick's launch floors too (``slower`` scales every
    ``*_s``): 0.50× in seconds, 1.00× in floors, and the block says which unit that is."""
    lines, _, _ = _against_twice_slower(mine, tmp_path, monkeypatch)
    assert "  'in floors': the same ratio in units of each run's own launch floor" in lines[2]
    rows = [ln for ln in lines if ln.startswith("    ") and "in floors" in ln]
    assert rows and all(ln.split()[2] == "0.50×" and "; 1.00× in floors," in ln for ln in rows), rows


def test_no_yardstick_no_floors(mine, tmp_path, monkeypatch):
    """Records without a launch yardstick (``hardware`` removed on both sides) give the raw ratio
    alone: no floors line, no division by a missing floor."""
    records, env = mine
    bare = [r.replace(hardware=None) for r in records]
    doc = json.loads(STORE.read_text())
    for r in doc["records"]:
        r.pop("hardware", None)
    ref = tmp_path / "ref"
    ref.mkdir()
    (ref / "results.json").write_text(json.dumps(doc))
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "out"
    out.mkdir()
    lines = versus.block(bare, env, out, against=str(ref))
    assert len(lines) > 2 and not any("in floors" in ln or "launch floor" in ln for ln in lines), lines


def test_nothing_to_compare_is_one_line(mine, tmp_path):
    records, env = mine
    assert versus.block(records, env, tmp_path, against="none") == []
    assert versus.block(records, env, STORE.parent, against=str(STORE))[0].endswith(
        "this run's --out is that report itself; nothing to compare")
    assert versus.block(records, env, tmp_path / "o", against=str(tmp_path))[0].endswith(
        "no stored report there (no results.json)")
    (tmp_path / "r").mkdir()
    (tmp_path / "r" / "results.json").write_text("not json")
    assert "cannot read it" in versus.block(records, env, tmp_path / "o", against=str(tmp_path / "r"))[0]
    other = [r.replace(params={**(r.params or {}), "seed": 12345}) for r in records]
    none = versus.block(other, env, tmp_path / "o", against=str(STORE.parent), quick=True)
    assert len(none) == 1 and "no timed cell of this run matches" in none[0] and "--quick never matches" in none[0]


@pytest.mark.cli
def test_bad_against_is_refused_in_one_line(tmp_path: Path) -> None:
    p = subprocess.run([sys.executable, "-m", "compare", "saxpy", "--quick", "--backends", "numpy",
                        "--out", str(tmp_path / "o"), "--against", str(tmp_path)],
                       cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert p.returncode == 2 and p.stderr.count("\n") == 1 and "--against" in p.stderr, p.stderr
    assert not (tmp_path / "o").exists()


def test_there_is_the_yardstick_of_the_runs_that_timed_the_matched_cells(mine, tmp_path, monkeypatch):
    """A store's runs may span hosts: the closing block's 'there' is the yardstick of the runs whose
    records it matched, not the median over every run of the store."""
    records, env = mine
    doc = json.loads(STORE.read_text())
    timed = doc["runs"][0]
    for r in doc["records"]:
        r["run"] = {"created": timed["created"], "commit": "abc1234", "dirty": False}
    other = {**timed, "created": "2026-12-01T00:00:00+00:00",
             "hardware": {"cuda": {**timed["hardware"]["cuda"], "copy_bytes_per_s": 1e15}}}
    doc["runs"] = [timed] + [{**other, "created": f"2026-12-0{i}T00:00:00+00:00"} for i in (1, 2, 3)]
    ref = tmp_path / "ref"
    ref.mkdir()
    (ref / "results.json").write_text(json.dumps(doc))
    monkeypatch.chdir(tmp_path)
    (tmp_path / "out").mkdir()
    text = " ".join(versus.block(records, env, tmp_path / "out", against=str(ref)))
    want = timed["hardware"]["cuda"]["copy_bytes_per_s"] * 1e-9
    assert f"GB/s here, {want:.3g} GB/s there" in text, text
