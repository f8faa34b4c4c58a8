"""The stress suite (compare/suites/stress.py) from the command line: bad usage, a quick CPU run of
two experiments (NumPy's; Warp's in the long tier), and merging parts. The experiments' own rules are tested beside their modules
(tests/stress/: test_projectile_rules, test_generic, test_numerics, test_stress_particles,
test_host_loop, test_stress_context)."""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, require_device
from reliability_checks import run_main
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
def test_bad_usage_exits_2_with_one_line(args, needle, tmp_path, monkeypatch):
    # compare.cli.main in this process; the entry point in a real process:
    # tests/test_options.py::test_entry_point_sample
    monkeypatch.chdir(tmp_path)
    rc, lines = run_main(["stress", *args])
    assert rc == 2
    assert len(lines) == 1 and needle in lines[0], lines


def quick_two_experiments(out, backend, first, again):
    """``first`` (two experiments) in quick mode on one CPU backend; then ``again`` (one of them)
    alone, which keeps the other's rows; then the parts merged into one report. Each cell record
    a run stores is stamped with that run (created, commit, dirty), as a results record is, and
    names an entry of the file's runs; the merge keeps it. The rows."""
    from compare.results.stamps import flat_runs, unstamped
    from compare.results.store import Store
    p = run_stress("--quick", "--backends", backend, "--devices", "cpu", "--only", ",".join(first),
                   "--out", str(out), "--jobs", "2")
    assert p.returncode == 0, p.stderr[-3000:]
    part = Store.read(out / "stress.json", "stress")
    assert part.records and unstamped(part.records, part.runs) == []
    env = part.runs[-1]
    assert {tuple(r.run.items()) for r in part.records} == \
        {(("created", env["created"]), ("commit", env.get("git_commit") or None), ("dirty", env.get("git_dirty")))}
    data = json.loads((out / "stress.json").read_text())
    assert data["format_version"] == 2 and data["suite"] == "stress"
    assert data["records"] and {r["backend"] for r in data["records"]} == {backend}   # the cells it ran
    for rec in data["records"]:   # stress figures are not timings: the first call and one more
        assert rec["time"]["warmup"] == 0 and rec["time"]["repeats"] == 1, rec["time"]
    rows = data["analysis"]["rows"]
    assert {r["experiment"] for r in rows} == set(first)
    for r in rows:
        assert set(numerics.COLUMNS) <= set(r) and r["verdict"]
    assert all(r["verdict"] == "bitwise reproducible" for r in rows
               if r["experiment"] == "races" and "racy" not in r["setting"])
    md = (out / "stress.md").read_text()
    assert all(f"## {e}" in md for e in first)
    # a second run of one experiment keeps the other's rows (this one and the merge through
    # compare.cli.main in this process: no interpreter to start)
    rc, lines = run_main(["stress", "--quick", "--backends", backend, "--devices", "cpu", "--only", again,
                          "--out", str(out), "--no-plots"])
    assert rc == 0, lines
    again_rows = json.loads((out / "stress.json").read_text())["analysis"]["rows"]
    assert {r["experiment"] for r in again_rows} == set(first)
    # parts run separately (one GPU call each) merge into one report
    rc, lines = run_main(["stress", "--merge", str(out / "stress.json"), "--out", str(out / "merged"), "--no-plots"])
    assert rc == 0, lines
    merged = json.loads((out / "merged" / "stress.json").read_text())["analysis"]["rows"]
    assert len(merged) == len(again_rows) and (out / "merged" / "stress.md").exists()
    kept = Store.read(out / "stress.json", "stress")             # the first run's records and the second's
    assert unstamped(kept.records, kept.runs) == []
    both = Store.read(out / "merged" / "stress.json", "stress")
    assert len(both.records) == len(kept.records) and unstamped(both.records, both.runs) == []
    assert {env["created"], kept.runs[-1]["created"]} <= {e.get("created") for e in flat_runs(both.runs)}
    return rows


def test_quick_numpy_cpu_two_experiments(tmp_path):
    """The suite's command on the cheapest backend (no kernel to compile) and its two cheapest
    experiments; Warp's, with particles-inf and the racy control kernel, is the long tier's."""
    require_device("numpy", "cpu")
    rows = quick_two_experiments(tmp_path, "numpy", ("races", "ulps"), "ulps")
    assert {r["setting"].split(" (")[0] for r in rows if r["experiment"] == "races"} >= {"saxpy", "particles"}


@pytest.mark.slow
def test_quick_warp_cpu_two_experiments(tmp_path):
    require_device("warp", "cpu")
    rows = quick_two_experiments(tmp_path, "warp", ("particles-inf", "races"), "particles-inf")
    inf = [r for r in rows if r["experiment"] == "particles-inf"]
    assert {r["precision"] for r in inf} == {"float32", "float64"}
    for r in inf:   # the overflow step is found and agrees with the NumPy emulation
        assert isinstance(r["value"], int) and "= NumPy emulation" in r["verdict"], r
    racy = [r for r in rows if "racy" in r["setting"]]
    assert len(racy) == 1 and racy[0]["verdict"] == "race not observable on CPU"


# ---- host-loop tasks and scheduling -------------------------------------------------------------


