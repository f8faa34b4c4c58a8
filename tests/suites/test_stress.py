"""The stress suite (compare/suites/stress.py) from the command line: bad usage, a quick CPU run of
two experiments, and merging parts. The experiments' own rules are tested beside their modules
(tests/stress/: test_projectile_rules, test_generic, test_numerics, test_stress_particles,
test_host_loop, test_stress_context)."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, require_device
from compare.stress import numerics
from scenarios import particles

pytestmark = pytest.mark.cli


# ---- the scenario's bound on the stress suite's long rollouts ---------------------------------------

def test_energy_bound_holds_for_the_float64_oracle():
    """The derived per-particle bound (bounce < 1) holds along the oracle's own long rollout."""
    import scenarios
    sc = scenarios.get("particles")
    p = sc.params({"n": 64, "steps": 2000, "bounce": 0.95})
    inp = sc.inputs(p, "float64")
    ref = sc.oracle(p, inp, "float64")
    g, r = float(inp["gravity"]), float(inp["radius"])
    e = particles.energy(ref["x"], ref["y"], ref["vx"], ref["vy"], g, r)
    assert np.all(e <= particles.energy_bound(inp))


# ---- command line -----------------------------------------------------------------------------

def run_stress(*args):
    return subprocess.run([sys.executable, "-m", "compare", "stress", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=900)


@pytest.mark.parametrize("args,needle", [
    (("--only", "bogus"), "unknown only"),
    (("--backends", "fortran"), "unknown backend"),
    (("--devices", "tpu"), "unknown device"),
    (("--jobs", "0"), "--jobs"),
    (("--merge", "/nonexistent/stress.json"), "cannot read"),
    (("--frobnicate",), "unrecognized"),
])
def test_bad_usage_exits_2_with_one_line(args, needle):
    p = run_stress(*args)
    assert p.returncode == 2
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], p.stderr


@pytest.mark.early
def test_quick_warp_cpu_two_experiments(tmp_path):
    require_device("warp", "cpu")
    p = run_stress("--quick", "--backends", "warp", "--devices", "cpu", "--only",
                   "particles-inf,races", "--out", str(tmp_path), "--jobs", "2")
    assert p.returncode == 0, p.stderr[-3000:]
    data = json.loads((tmp_path / "stress.json").read_text())
    assert data["format_version"] == 2 and data["suite"] == "stress"
    assert {r["scenario"] for r in data["records"]} >= {"particles"}    # the cells it ran
    for rec in data["records"]:   # stress figures are not timings: the first call and one more
        assert rec["time"]["warmup"] == 0 and rec["time"]["repeats"] == 1, rec["time"]
    rows = data["analysis"]["rows"]
    assert {r["experiment"] for r in rows} == {"particles-inf", "races"}
    for r in rows:
        assert set(numerics.COLUMNS) <= set(r) and r["verdict"]
    inf = [r for r in rows if r["experiment"] == "particles-inf"]
    assert {r["precision"] for r in inf} == {"float32", "float64"}
    for r in inf:   # the overflow step is found and agrees with the NumPy emulation
        assert isinstance(r["value"], int) and "= NumPy emulation" in r["verdict"], r
    racy = [r for r in rows if "racy" in r["setting"]]
    assert len(racy) == 1 and racy[0]["verdict"] == "race not observable on CPU"
    assert all(r["verdict"] == "bitwise reproducible" for r in rows
               if r["experiment"] == "races" and "racy" not in r["setting"])
    md = (tmp_path / "stress.md").read_text()
    assert "## particles-inf" in md and "## races" in md
    # a second run of one experiment keeps the other's rows
    p = run_stress("--quick", "--backends", "warp", "--devices", "cpu", "--only", "particles-inf",
                   "--out", str(tmp_path), "--no-plots")
    assert p.returncode == 0, p.stderr[-3000:]
    again = json.loads((tmp_path / "stress.json").read_text())["analysis"]["rows"]
    assert {r["experiment"] for r in again} == {"particles-inf", "races"}
    # parts run separately (one GPU call each) merge into one report
    p = run_stress("--merge", str(tmp_path / "stress.json"), "--out", str(tmp_path / "merged"), "--no-plots")
    assert p.returncode == 0, p.stderr
    merged = json.loads((tmp_path / "merged" / "stress.json").read_text())["analysis"]["rows"]
    assert len(merged) == len(again) and (tmp_path / "merged" / "stress.md").exists()


# ---- host-loop tasks and scheduling -------------------------------------------------------------


def stress_part(path, command, rows, series):
    """A saved stress.json as one run of the suite writes it (rows, plot series, provenance)."""
    from compare.results.store import Store
    numpy = "2.4" if command == "old run" else "2.5"
    store = Store(path / "stress.json", "stress", runs=[{"command": command, "created": "t", "git_commit": "c",
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


def test_merge_replaces_per_backend_and_device_and_keeps_the_other_backends(tmp_path):
    """New backends run later join an earlier run's experiment: the later part wins only for the
    backends and devices it ran; rows, plot series and provenance of the others are kept."""
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
        ("races", "taichi", "cuda", "differing values", 0),          # an experiment the later part skipped
    ]
    assert a["series"]["particles-inf"] == {"lines": {"warp/cuda": [10], "taichi/cuda": [2], "torch/cuda": [30]},
                                            "shared": [9]}
    runs = a["provenance"]["particles-inf"]
    assert [(r["command"], r["backends"]) for r in runs] == [("old run", ["taichi"]),
                                                             ("new run", ["physics", "torch", "warp"])]
    assert a["provenance"]["races"]["command"] == "old run"
    assert got["runs"][-1]["packages"] == {"old run": "1", "new run": "1", "numpy": "2.4 / 2.5"}
    md = (tmp_path / "merged" / "stress.md").read_text()
    lines = {ln.split("`")[1]: ln.split(": ", 1)[1] for ln in md.splitlines() if ln.startswith("  - `")}
    assert sorted(lines["old run"].split(", ")) == ["particles-inf (taichi)", "races"]
    assert lines["new run"] == "particles-inf (physics, torch, warp)"
    # merging the merged file again with the later part changes nothing
    p = run_stress("--merge", str(tmp_path / "merged" / "stress.json"), new, "--out", str(tmp_path / "again"),
                   "--no-plots")
    assert p.returncode == 0, p.stderr
    again = json.loads((tmp_path / "again" / "stress.json").read_text())["analysis"]
    assert again["rows"] == a["rows"] and again["provenance"] == a["provenance"]


