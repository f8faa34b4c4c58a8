"""compare/stress/page.py: stress.md leads with one line per experiment (fast tier): how many cases
it measured, how many it skipped, how many verdicts flag a problem (CAPITALS, docs/stress.md) and
its worst row, before every experiment's rows under its heading. Named test_stress_page: pytest
collects test files by basename, and compare/sweep/ has a page module too. The site's stability
page that folds those rows: tests/site/test_pages_stability.py."""
from __future__ import annotations

import json
import subprocess
import sys
from typing import Any

import pytest

from conftest import ROOT

from compare.stress import page
from compare.stress.numerics import Experiment


def row(exp: str, verdict: str, value: Any, figure: str = "gradient rel. error vs float64",
        backend: str = "warp") -> dict[str, Any]:
    return {"experiment": exp, "backend": backend, "device": "cuda", "precision": "float32",
            "setting": "s", "figure": figure, "value": value, "verdict": verdict, "detail": ""}


@pytest.mark.parametrize("verdict, flag", [
    ("EXCEEDS derived bound", True), ("RACE DETECTED (outside the oracle's bound)", True),
    ("within derived bound at every horizon; float32 gradient OFF BY 62% at steps=720", True),
    ("race not observable on CPU", False), ("GD locally stable iff lr < 0.05", False),
    ("unstable, reported: Inf/NaN from step 12", False), ("within derived bound", False)])
def test_capitals_flag_a_verdict_and_names_do_not(verdict: str, flag: bool):
    assert page.flagged(verdict) is flag


REG = {"a": Experiment("a", "first", lambda ctx: ([], {})), "b": Experiment("b", "second", lambda ctx: ([], {})),
       "c": Experiment("c", "never ran", lambda ctx: ([], {}))}


def test_one_summary_line_per_experiment_with_its_worst_row():
    rows = [row("a", "within derived bound", 0.9, backend="jax"),
            row("a", "EXCEEDS derived bound", 1.5, backend="torch"),
            row("a", "EXCEEDS derived bound", 3.0, backend="mlx"),
            row("a", "skipped", None, figure="-"),
            row("b", "within derived bound", 0.2), row("b", "within derived bound", 0.7, backend="cupy")]
    lines = page.summary(rows, REG)
    assert [ln[:5] for ln in lines] == [("a", "first", "3", "1", "2"), ("b", "second", "2", "0", "0")]
    assert lines[0][5].startswith("mlx cuda float32 s: gradient rel. error vs float64 = 3 (EXCEEDS")
    assert lines[1][5].startswith("cupy ")         # nothing flagged: the largest error of all


def test_a_figure_without_a_worse_direction_gives_the_first_flagged_row_or_none():
    first = "first step with a non-finite state"
    rows = [row("a", "LOSS JUMPS", 7, figure=first, backend="jax"), row("a", "LOSS JUMPS", 9, figure=first),
            row("b", "unstable, reported", 3, figure=first)]
    lines = page.summary(rows, REG)
    assert lines[0][5].startswith("jax ") and lines[1][5] == "-"


def test_stress_md_leads_with_the_summary(tmp_path):
    rows = [row("a", "EXCEEDS derived bound", 3.0), row("b", "within derived bound", 0.2)]
    md = page.markdown({"environment": {}, "rows": rows, "_out": str(tmp_path)}, REG)
    assert md.index("## Summary") < md.index("| a ") < md.index("## a: first")


# ---- merging parts (``compare stress --merge``: page.merge) ----------------------------------------
def run_stress(*args):
    return subprocess.run([sys.executable, "-m", "compare", "stress", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=900)


def stress_part(path, command, rows, series):
    """A saved stress.json as one run of the suite writes it (rows, plot series, provenance)."""
    from compare.results.store import Store
    numpy = "2.4" if command == "old run" else "2.5"
    store = Store(path / "stress.json", "stress", runs=[{"command": command, "created": "t", "git_commit": "c",
                                                        "git_dirty": command == "old run",
                                                        "packages": {command: "1", "numpy": numpy}}])
    store.analysis = {"provenance": {e: {"command": command, "created": "t", "git_commit": "c"}
                                     for e in {r["experiment"] for r in rows}},
                      "rows": rows, "series": series}
    path.mkdir(parents=True, exist_ok=True)
    store.save()
    return str(path / "stress.json")


def stress_row(exp, backend, device, figure, value):
    return {"experiment": exp, "backend": backend, "device": device, "precision": "float32", "setting": "s",
            "figure": figure, "value": value, "verdict": "ok", "detail": ""}


@pytest.mark.cli
def test_merge_replaces_per_backend_and_device_and_keeps_the_other_backends(tmp_path):
    """New backends run later join an earlier run's experiment: the later part wins only for the
    backends and devices it ran; rows, plot series and provenance of the others are kept. A
    backend the later part skipped wholly erases nothing; one it ran keeps that part's skips."""
    old = stress_part(tmp_path / "old", "old run", [
        stress_row("particles-inf", "physics", "host", "predicted step", 6),
        stress_row("particles-inf", "warp", "cuda", "overflow step", 1),
        stress_row("particles-inf", "taichi", "cuda", "overflow step", 2),
        stress_row("particles-inf", "warp", "cuda", "flips vs warp", 0),
        stress_row("particles-inf", "taichi", "cuda", "flips vs warp", 5),
        stress_row("races", "taichi", "cuda", "differing values", 0),
    ], {"particles-inf": {"lines": {"warp/cuda": [1], "taichi/cuda": [2]}, "shared": [0]}})
    new = stress_part(tmp_path / "new", "new run", [
        stress_row("particles-inf", "warp", "cuda", "overflow step", 10),
        stress_row("particles-inf", "torch", "cuda", "overflow step", 30),
        stress_row("particles-inf", "torch", "cuda", "flips vs warp", 7),
        stress_row("particles-inf", "warp", "cpu", "overflow step", 11),
        {**stress_row("particles-inf", "taichi", "cuda", "-", None), "verdict": "skipped"},   # not installed there
        {**stress_row("particles-inf", "warp", "cuda", "-", None), "verdict": "skipped"},     # a variant it lacks
        stress_row("particles-inf", "physics", "host", "predicted step", 60),
    ], {"particles-inf": {"lines": {"warp/cuda": [10], "torch/cuda": [30]}, "shared": [9]}})
    p = run_stress("--merge", old, new, "--out", str(tmp_path / "merged"), "--no-plots")
    assert p.returncode == 0, p.stderr
    got = json.loads((tmp_path / "merged" / "stress.json").read_text())
    a = got["analysis"]
    table = [(r["experiment"], r["backend"], r["device"], r["figure"], r["value"]) for r in a["rows"]]
    assert table == [   # each kind of figure together, where the parts first showed it; backends in registry order
        ("particles-inf", "physics", "host", "predicted step", 60),  # replaced, in its old place
        ("particles-inf", "warp", "cuda", "overflow step", 10),      # replaced by the later part
        ("particles-inf", "warp", "cpu", "overflow step", 11),       # new device
        ("particles-inf", "taichi", "cuda", "overflow step", 2),     # kept: the later part skipped it
        ("particles-inf", "torch", "cuda", "overflow step", 30),     # new backend
        ("particles-inf", "taichi", "cuda", "flips vs warp", 5),     # kept, though warp's was replaced
        ("particles-inf", "torch", "cuda", "flips vs warp", 7),
        ("particles-inf", "warp", "cuda", "-", None),                # kept: the part ran warp, skipped a variant
        ("races", "taichi", "cuda", "differing values", 0),          # an experiment the later part skipped
    ]
    assert a["series"]["particles-inf"] == {"lines": {"warp/cuda": [10], "taichi/cuda": [2], "torch/cuda": [30]},
                                            "shared": [9]}
    runs = a["provenance"]["particles-inf"]
    assert [(r["command"], r["backends"]) for r in runs] == [("old run", ["taichi"]),
                                                             ("new run", ["physics", "torch", "warp"])]
    assert a["provenance"]["races"]["command"] == "old run"
    # each run's tree state is carried into the provenance, and the merged entry keeps every run
    assert [r["git_dirty"] for r in runs] == [True, False] and a["provenance"]["races"]["git_dirty"] is True
    assert got["runs"][-1]["packages"] == {"old run": "1", "new run": "1", "numpy": "2.4 / 2.5"}
    assert [(e["command"], e["git_dirty"]) for e in got["runs"][-1]["environments"]] == [("old run", True),
                                                                                         ("new run", False)]
    md = (tmp_path / "merged" / "stress.md").read_text()
    lines = {ln.split("`")[1]: ln.split(": ", 1)[1] for ln in md.splitlines() if ln.startswith("  - `")}
    assert sorted(lines["old run"].split(", ")) == ["particles-inf (taichi)", "races"]
    assert lines["new run"] == "particles-inf (physics, torch, warp)"
    whole = {ln.split("`")[1]: ln for ln in md.splitlines() if ln.startswith("  - `")}   # each run's tree state
    assert "(t, commit c, dirty tree): " in whole["old run"] and "(t, commit c): " in whole["new run"]
    # merging the merged file again with the later part changes nothing
    p = run_stress("--merge", str(tmp_path / "merged" / "stress.json"), new, "--out", str(tmp_path / "again"),
                   "--no-plots")
    assert p.returncode == 0, p.stderr
    again = json.loads((tmp_path / "again" / "stress.json").read_text())["analysis"]
    assert again["rows"] == a["rows"] and again["provenance"] == a["provenance"]


@pytest.mark.cli
def test_a_part_cut_off_before_its_findings_is_not_merged(tmp_path):
    """A stress part whose run was cut off holds records and no rows: merged, its records would
    replace cells whose findings the page still gives from an earlier run, so it is left out with
    one line on stderr, and the other parts merge as before."""
    from compare.results.record import Record
    from compare.results.store import Store
    old = stress_part(tmp_path / "old", "old run", [stress_row("particles-inf", "torch", "cuda", "overflow step", 2)],
                      {})
    cut = Store(tmp_path / "cut" / "stress.json", "stress", runs=[{"command": "cut run", "created": "t"}])
    cut.put(Record(scenario="particles", backend="torch", device="cuda", precision="float32", status="ok",
                   params={"n": 256, "steps": 6669}, variant="compile"))
    (tmp_path / "cut").mkdir()
    cut.save()
    p = run_stress("--merge", old, str(tmp_path / "cut" / "stress.json"), "--out", str(tmp_path / "merged"),
                   "--no-plots")
    assert p.returncode == 0, p.stderr
    assert "1 record and no findings (cut off before its experiment ended): not merged" in p.stderr
    got = json.loads((tmp_path / "merged" / "stress.json").read_text())
    assert got["records"] == [] and [r["value"] for r in got["analysis"]["rows"]] == [2]


@pytest.mark.parametrize("v,text", [(3, "3"), (0.123456, "0.1235"), (0.0, "0"), (True, "True"), (None, "-")])
def test_fmt_value(v, text):
    assert page.fmt_value(v) == text


def test_worst_is_none_without_flags_or_a_worse_direction():
    assert page.worst([row("a", "ok", 1, figure="first step")]) is None
    assert page.worst([row("a", "skipped", None)]) is None
    assert page.measured(row("a", "ok", float("inf"))) is None and page.measured(row("a", "ok", True)) is None


def test_deep_merge_joins_series_and_takes_the_later_leaf():
    a = {"lines": {"warp/cuda": [1], "jax/cuda": [2]}, "shared": [0]}
    b = {"lines": {"warp/cuda": [9]}, "shared": [5], "new": 1}
    assert page.deep_merge(a, b) == {"lines": {"warp/cuda": [9], "jax/cuda": [2]}, "shared": [5], "new": 1}
    assert page.deep_merge([1], [2]) == [2]


def test_provenance_of_a_file_without_one_is_its_environments_run():
    data = {"environment": {"command": "stress", "created": "t", "git_commit": "c"},
            "rows": [row("a", "ok", 1), row("b", "ok", 2)]}
    assert page.provenance(data) == {e: {"command": "stress", "created": "t", "git_commit": "c", "git_dirty": None}
                                     for e in "ab"}
    old = {"environment": {"merged_from": ["x", "y"], "git_dirty": False}, "rows": [row("a", "ok", 1)]}
    assert page.provenance(old)["a"]["command"] == "merge of 2 parts (commands not recorded)"
    assert page.provenance(old)["a"]["git_dirty"] is None           # its parts' trees were not kept
    assert page.produced_by(data) == ["- produced by", "  - `stress` (t, commit c, tree state unknown): a, b"]
    clean = {**data, "environment": {**data["environment"], "git_dirty": False}}
    assert page.produced_by(clean) == ["- produced by", "  - `stress` (t, commit c): a, b"]
    assert page.with_backends({"command": "x"}, ["warp"]) == {"command": "x", "backends": ["warp"]}
    assert page.row_key(row("a", "ok", 1)) == ("a", "warp", "cuda")


def test_a_merge_names_every_run_its_rows_come_from_even_those_an_old_merge_kept_no_environment_of():
    """A file merged before environments were kept has only its last part's environment; the runs
    its provenance names besides are kept as what it names, tree state unknown, so no run that
    gave rows is hidden behind the last part's clean tree."""
    last = {"command": "last", "created": "t2", "git_commit": "c2", "git_dirty": False, "merged_from": ["p", "q"]}
    prov = {"a": [{"command": "first", "created": "t1", "git_commit": "c1", "backends": ["warp"]}],
            "b": [{"command": "last", "created": "t2", "git_commit": "c2", "backends": ["jax"]}]}
    envs = page.environments(page.part_environments([last]), prov)
    assert [(e["command"], e["git_dirty"]) for e in envs] == [("first", None), ("last", False)]
    assert envs[0]["git_note"] == page.OLD_MERGE and "merged_from" not in envs[1]
    assert prov["b"][0]["git_dirty"] is False and prov["a"][0].get("git_dirty") is None


def test_a_merged_part_inside_the_output_folder_is_named_relative_to_it(tmp_path):
    out = tmp_path / "pub"
    assert page.named(str(out / "stress-parts" / "ulps" / "stress.json"), out) == "stress-parts/ulps/stress.json"
    assert page.named("docs/results/cpu/stress.json", out) == "docs/results/cpu/stress.json"
