"""The sweep suite (issue 6, compare/suites/sweep.py): the sweep command on NumPy/CPU in quick
mode (on Warp/CPU in the long tier), its plan, record shape, page and plots; its metrics, page,
plots, points, converged references and stored format are tested beside their modules in
tests/sweep/, the measurements it is made of in tests/measuring/test_timing.py."""
from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys

import pytest

import backends
import scenarios
from compare.suites import sweep
from compare.sweep.points import sweeps
from conftest import ROOT, require_device
from reliability_checks import run_main

pytestmark = pytest.mark.cli


# ---- the sweep command ----------------------------------------------------------------------
def run_sweep(*args):
    return subprocess.run([sys.executable, "-m", "compare", "sweep", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=1200)


def sweep_all(out, backend):
    """Every sweep in quick mode on one backend (CPU, float32), warm caches and no minimum time:
    the suite's plan, records, page and plots, not its timings."""
    return run_sweep("all", "--quick", "--backends", backend, "--devices", "cpu", "--precision",
                     "float32", "--cache", "warm", "--min-time", "0", "--out", str(out))


@pytest.fixture(scope="module")
def quick_sweep(tmp_path_factory):
    """NumPy's (no kernel to compile: seconds); Warp's, the reference, is the long tier's."""
    require_device("numpy", "cpu")
    out = tmp_path_factory.mktemp("sweep")
    return sweep_all(out, "numpy"), out


def assert_every_sweep_ok(p, out):
    assert p.returncode == 0, p.stdout + p.stderr
    data = json.loads((out / "sweep.json").read_text())
    recs = data["records"]
    assert all(r["status"] == "ok" for r in recs), [r.get("reason") for r in recs]
    assert not any(k in r for r in recs for k in ("sweep", "role", "knob"))   # all under tags
    roles = {(r["tags"]["sweep"], r["tags"]["role"], r["scenario"]) for r in recs}
    assert {("bandwidth", "launch", "launch"), ("bandwidth", "copy", "copy"),
            ("bandwidth", "bandwidth", "saxpy"), ("error", "sdf", "sdf"),
            ("error", "particles", "particles"), ("error", "projectile", "projectile"),
            ("scaling", "particles", "particles"), ("scaling", "projectile", "projectile"),
            ("horizon", "projectile", "projectile")} <= roles
    for r in recs:
        if r["tags"]["sweep"] == "error":
            c = r["converged"]
            assert c["metric"] and math.isfinite(c["error"]) and c["error"] >= 0
            if r["scenario"] in ("particles", "projectile"):    # the reference is far finer
                assert c["reference"]["self_difference"] < c["error"]
    for name in ("bandwidth_cpu.png", "time_vs_error_cpu.png", "scaling_particles_cpu.png",
                 "scaling_projectile_cpu.png", "horizon_cpu.png", "measurement.md"):
        assert (out / name).stat().st_size > 0
    md = (out / "measurement.md").read_text()
    assert "Roofline for this device" in md and "python -m compare sweep all --quick" in md
    return recs


@pytest.mark.xdist_group("quick_sweep")
def test_sweep_quick_runs_every_sweep_ok(quick_sweep):
    assert {r["backend"] for r in assert_every_sweep_ok(*quick_sweep)} == {"numpy"}


@pytest.mark.slow
def test_sweep_quick_runs_everything_ok(tmp_path):
    """The same on Warp, with its own variants (compiling each cell's kernels: the long tier)."""
    require_device("warp", "cpu")
    recs = assert_every_sweep_ok(sweep_all(tmp_path, "warp"), tmp_path)
    assert {r["variant"] for r in recs if r["tags"]["sweep"] == "horizon"} == \
        {"default", "checkpoint", "unrolled"}                  # tape_zero: an A/B only, not swept


@pytest.mark.xdist_group("quick_sweep")
def test_every_sweep_record_names_its_run(quick_sweep):
    """Each record a sweep stores is stamped with its run (created, commit, dirty), an entry of
    the file's runs, as a results record is."""
    from compare.results.stamps import unstamped
    from compare.results.store import Store
    store = Store.read(quick_sweep[1] / "sweep.json", "sweep")
    assert store.records and unstamped(store.records, store.runs) == []
    assert {r.run["created"] for r in store.records} == {store.runs[-1]["created"]}


@pytest.mark.xdist_group("quick_sweep")
def test_sweep_report_rebuilds_without_running(quick_sweep, tmp_path):
    _, out = quick_sweep
    page = tmp_path / "page.md"
    # compare.cli.main in this process (no interpreter to start); the entry point in a real
    # process: tests/test_options.py::test_entry_point_sample
    rc, lines = run_main(["sweep", "report", str(out / "sweep.json"), "--out", str(tmp_path / "plots"),
                          "--page", str(page), "--title", "Rebuilt"])
    assert rc == 0, lines
    text = page.read_text()
    assert text.startswith("# Rebuilt") and "(plots/bandwidth_cpu.png)" in text


@pytest.mark.xdist_group("quick_sweep")
def test_sweep_resume_skips_ok_cells(quick_sweep, tmp_path):
    out = tmp_path / "sweep"
    shutil.copytree(quick_sweep[1], out)          # the module's run stays as it ran
    rc, lines = run_main(["sweep", "scaling", "--quick", "--backends", "numpy", "--devices", "cpu", "--precision",
                          "float32", "--out", str(out), "--resume", "--no-plots"])
    assert rc == 0, lines
    assert not any("scaling particles" in ln for ln in lines)          # nothing rerun


@pytest.mark.parametrize("args,needle", [
    ((), "required"),
    (("bogus",), "unknown sweep"),
    (("bandwidth", "--backends", "fortran"), "unknown backend"),
    (("error", "--scenarios", "launch"), "unknown scenario"),
    (("scaling", "--precision", "float16"), "unknown precision"),
    (("bandwidth", "--repeat", "0"), "--repeat"),
    (("report",), "at least one"),
    (("report", "/nonexistent/sweep.json"), "cannot read"),
    (("error", "--set", "contact=sticky"), "contact must be one of"),
    (("bandwidth", "--set", "contact=soft"), "unknown parameter 'contact'"),
    (("error", "--scenarios", "particles", "--set", "dt=0.1"), "varies it"),
    (("error", "--set", "contact"), "KEY=VALUE"),
])
def test_sweep_bad_usage_exits_2_with_one_line(args, needle, tmp_path, monkeypatch):
    # compare.cli.main in this process; the entry point in a real process:
    # tests/test_options.py::test_entry_point_sample
    monkeypatch.chdir(tmp_path)
    rc, lines = run_main(["sweep", *args])
    assert rc == 2
    assert len(lines) == 1 and needle in lines[0], lines


# ---- the suite's plan, record shape and page, without running cells --------------------------
def plan_of(*argv):
    from compare import options
    p = options.Parser()
    sweep.add_arguments(p)
    return sweep.plan(p.parse_args(list(argv)))


def test_plan_comes_from_the_scenarios_sweeps():
    import scenarios
    specs = [s for s, _ in plan_of("bandwidth", "--quick", "--backends", "warp", "--devices", "cpu")]
    assert [s.tags["role"] for s in specs[:2]] == ["launch", "copy"]      # yardsticks first
    assert {s.scenario for s in specs if s.tags["role"] == "bandwidth"} == {
        name for name in scenarios.SCENARIOS if sweeps(name).measures == "bandwidth"}
    assert all(s.check_sample for s in specs if s.tags["role"] != "launch")
    assert not any(s.own_timer for s in specs)        # the clock's cross-check is the matrix's
    # a scenario's own variants join the size sweep of that scenario only (Warp's tiled SAXPY; its
    # recorded launches of SAXPY and of the copy and launch yardsticks), never another's
    own = backends.get("warp").scenario_variants
    assert {(s.scenario, s.variant) for s in specs if s.variant != "default"} == {
        (sc, v) for sc in {s.scenario for s in specs} for v in own.get(sc, ())}
    assert {s.variant for s in specs if s.scenario == "saxpy"} == {"default", "tile", "record_cmd"}
    assert "tile" not in {s.variant for s in specs if s.scenario == "copy"}
    err = plan_of("error", "--quick", "--backends", "warp", "--devices", "cpu", "--precision", "float32")
    assert {s.scenario for s, _ in err} == set(sweep.error_scenarios()) == {
        "saxpy", "sdf", "particles", "projectile"}
    proj = [(s, ref) for s, ref in err if s.scenario == "projectile"]
    assert {s.params.contact for s, _ in proj} == {"soft"}             # the sweep's default
    assert all(ref.dt == min(s.params.dt for s, _ in proj) / 16 for _, ref in proj)
    assert all("reference" not in s.tags for s, _ in err)                 # not the cell's identity
    hard = plan_of("error", "--quick", "--backends", "warp", "--devices", "cpu", "--set", "contact=hard",
                   "--scenarios", "projectile,saxpy")
    assert {s.params.contact for s, _ in hard if s.scenario == "projectile"} == {"hard"}
    assert [s.scenario for s, _ in hard][:3] == ["projectile"] * 2 + ["saxpy"]   # the given order
    scal = plan_of("scaling", "--quick", "--backends", "warp", "--devices", "cpu", "--record-every", "50")
    assert {s.params.record_every for s, _ in scal if s.scenario == "particles"} == {50}
    assert [s.params.batch for s, _ in scal if s.scenario == "projectile"] == [1, 256]
    hz = plan_of("horizon", "--quick", "--backends", "warp,numba", "--devices", "cpu")
    assert {(s.backend, s.variant) for s, _ in hz} == {("warp", "default"), ("warp", "checkpoint"),
                                                       ("warp", "unrolled"), ("numba", "default")}
    assert {s.params.iters for s, _ in hz} == {0} and {s.precision for s, _ in hz} == {"float32", "float64"}


def test_sweep_stress_and_site_suites_name_no_framework_and_no_scenario():
    """The sweep, stress and site suites name no framework and no scenario in their code: each
    scenario's sweep points (compare/sweep/points/<scenario>.py), stress experiments
    (compare/stress/<scenario>.py), ulp cases and site questions and pages
    (compare/site/topics/<scenario>.py) are found by the module's or function's name (issue 29:
    suites hold their per-scenario parts, compare/ names no framework)."""
    import re
    frameworks = re.compile(r"['\"](" + "|".join(backends.BACKENDS) + r")['\"]")
    # 'launch' and 'copy' are also the names of the roles the bandwidth page draws
    names = re.compile(r"['\"](" + "|".join(n for n in scenarios.SCENARIOS if n not in ("launch", "copy")) + r")['\"]")
    for suite in ("sweep", "stress", "site"):
        for f in (ROOT / "compare" / suite).rglob("*.py"):
            for i, line in enumerate(f.read_text().splitlines(), 1):
                code = line.split("#", 1)[0]
                assert not frameworks.search(code), f"{f.name}:{i}: {line.strip()}"
                assert not names.search(code), f"{f.name}:{i}: {line.strip()}"
