"""The stress suite: its pure verdict rules on synthetic data, and a quick CPU run of two experiments."""
from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from conftest import ROOT, require_device
from compare.stress import generic, host_loop, numerics, projectile_rules
from compare.suites import stress_context as context
from compare.stress import particles as particles_stress
from scenarios import particles

pytestmark = pytest.mark.cli


# ---- classifier -------------------------------------------------------------------------------

@pytest.mark.parametrize("history,expected", [
    ([100.0 * 0.5 ** k for k in range(40)], "converged"),         # 1e-12 of the start
    ([100.0, 50.0, 40.0, 35.0], "stalled"),                        # better, not 1e-6 of the start
    ([100.0] * 10, "stalled"),                                     # no progress, no growth
    ([100.0, 100.05], "stalled"),                                  # within 0.1 %: rounding, not growth
    ([100.0, 200.0, 400.0], "diverged"),                           # grew
    ([100.0, 1e3, 1e6, math.inf], "diverged"),                     # overflowed
    ([100.0, 1.0, math.nan, 0.0], "diverged"),                     # NaN anywhere
    ([100.0, 1e8, 1e-5], "converged"),                             # a spike does not matter at the end
    ([], "diverged"),
])
def test_classify(history, expected):
    assert projectile_rules.classify(history) == expected


def test_classify_gradient_descent_on_a_quadratic_matches_the_stability_bound():
    """GD on L = lam/2 v^2 contracts by |1 - lr lam| per step: stable iff lr < 2/lam."""
    lam = 40.5
    def hist(lr):
        v = 1.0
        out = []
        for _ in range(61):
            out.append(0.5 * lam * v * v)
            v -= lr * lam * v
        return out
    assert projectile_rules.classify(hist(0.01)) == "converged"
    assert projectile_rules.classify(hist(0.049)) == "stalled"          # |1 - lr lam| = 0.98: slow
    assert projectile_rules.classify(hist(0.08)) == "diverged"
    lrs = [0.01, 0.045, 0.055, 0.08]
    below, first = projectile_rules.observed_boundary(lrs, [projectile_rules.classify(hist(lr)) for lr in lrs])
    assert below == 0.045 and first == 0.055 and below < 2 / lam <= first


def test_observed_boundary_without_divergence():
    assert projectile_rules.observed_boundary([0.1, 0.2], ["stalled", "converged"]) == (0.2, None)


# ---- race detector ----------------------------------------------------------------------------

def _outputs(seed=0):
    rng = np.random.default_rng(seed)
    return {k: rng.standard_normal(100).astype(np.float32) for k in ("x", "y", "vx", "vy")}


def test_bitwise_differences_counts_elements_and_treats_equal_nans_as_equal():
    a = _outputs()
    b = {k: v.copy() for k, v in a.items()}
    assert numerics.bitwise_differences(a, b) == 0
    a["x"][3] = b["x"][3] = np.nan
    assert numerics.bitwise_differences(a, b) == 0
    b["y"][7] = np.nextafter(b["y"][7], np.float32(np.inf))      # one ulp
    b["vx"][0] = -b["vx"][0]
    assert numerics.bitwise_differences(a, b) == 2
    assert numerics.bitwise_differences({"z": np.float32([0.0])}, {"z": np.float32([-0.0])}) == 1
    assert numerics.bitwise_differences(a, {**b, "extra": b["x"]}) == -1
    assert numerics.bitwise_differences({"x": a["x"]}, {"x": a["x"][:5]}) == -1


@pytest.mark.parametrize("device,differing,oracle_ok,flagged", [
    ("cuda", 37, (True, True), True),           # runs disagree
    ("cuda", 0, (False, False), True),          # deterministic, but wrong
    ("cuda", 0, (True, False), True),
    ("cuda", -1, (True, True), True),           # shapes differ
    ("cuda", 0, (True, True), False),           # clean on a GPU: the control was missed
    ("cpu", 0, (True, True), False),            # clean on the CPU: threads ran in order
    ("cpu", 5, (True, True), True),
])
def test_race_verdict(device, differing, oracle_ok, flagged):
    verdict = generic.race_verdict(device, differing, oracle_ok)
    assert verdict.startswith("RACE DETECTED") == flagged
    if not flagged:
        assert verdict == ("race not observable on CPU" if device == "cpu" else "MISSED: race not flagged")


def test_race_detector_flags_a_synthetic_read_before_write():
    """What the seed's one-launch kernel does when step s is read before step s-1 is written: the
    detector must flag the result through the oracle check and through run-to-run differences."""
    clean = _outputs()
    stale = {k: v.copy() for k, v in clean.items()}
    stale["y"][::3] = 0.0                       # some threads read the zeroed history
    differing = numerics.bitwise_differences(clean, stale)
    assert differing > 0
    assert generic.race_verdict("cuda", differing, (True, False)).startswith("RACE DETECTED")


# ---- other rules ------------------------------------------------------------------------------

def test_contacts_and_first_flips():
    radius = 0.03
    lo = float(np.float32(-1) + np.float32(radius))
    ty = np.array([[0.5, radius], [radius, 0.4], [0.2, 0.1]])
    tx = np.array([[0.0, 0.0], [0.0, 0.0], [lo, 0.0]])
    c = particles_stress.contacts(tx, ty, radius, np.float32)
    assert c.tolist() == [[False, True], [True, False], [True, False]]
    other = c.copy(); other[1, 0] = False
    assert particles_stress.first_flips(c, other).tolist() == [1, -1]


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


def test_loss_mispredictions_separates_jumps_from_curvature_and_rounding():
    vy = np.linspace(0.0, 1.0, 11)
    smooth = [[0.0, 2 * v] for v in vy]                      # L = v^2, exact gradient
    assert projectile_rules.loss_mispredictions(vy, vy ** 2, smooth) == (0, 0)
    jump = vy ** 2 + (vy > 0.55)                             # a step the gradient cannot see
    assert projectile_rules.loss_mispredictions(vy, jump, smooth) == (1, 0)
    flat = np.full(11, 25.0) + 1e-7 * (-1.0) ** np.arange(11)  # rounding noise on a flat loss
    assert projectile_rules.loss_mispredictions(vy, flat, [[0.0, 0.0]] * 11, noise_rel=2 ** -23) == (0, 10)


def test_ulps_of_correctly_rounded_results_are_at_most_half():
    ref = np.random.default_rng(1).standard_normal(1000)
    assert np.max(numerics.ulps(ref.astype(np.float32), ref)) <= 0.5
    assert numerics.ulps(np.float32([1.0 + 2 ** -23]), np.array([1.0]))[0] == 1.0


def test_emulation_finds_the_overflow_step():
    """bounce > 1 at the walls: the horizontal speed overflows sooner in float32 than in float64."""
    s32 = particles_stress.first_nonfinite_step({"n": 16, "bounce": 3.0}, "float32", 5000)
    s64 = particles_stress.first_nonfinite_step({"n": 16, "bounce": 3.0}, "float64", 5000)
    assert s32 is not None and s64 is not None and s32 < s64
    assert particles_stress.first_nonfinite_step({"n": 16, "bounce": 0.5}, "float32", 500) is None


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

@pytest.mark.parametrize("backend", [pytest.param(b, marks=getattr(pytest.mark, b))
                                     for b in ("warp", "taichi", "jax", "numba")])
def test_host_loop_scan_reuses_one_kernel_and_matches_the_oracle(backend):
    """A scan moves v0 in place (set_input); in float64 every point must match the float64 adjoint,
    so a stale v0 (the kernel not seeing the new input) fails here."""
    from compare.stress import projectile_tasks
    require_device(backend, "cpu")
    scans = {"s": [6.3, 6.45, 6.5, 6.7]}
    task = projectile_tasks.Task("scan", backend, "cpu", "float64", ("hard", "soft"), 600.0, scans=scans)
    got = host_loop.run(task, timeout=600)
    assert got.why_not is None and got.scans, got
    ref = projectile_tasks.execute(dataclasses.replace(task, backend="oracle64", device="host"))
    for g, r in zip(got.scans, ref.scans):
        assert g.contact == r.contact
        assert len(set(g.loss)) == len(scans["s"])            # every point really evaluated
        np.testing.assert_allclose(g.loss, r.loss, rtol=1e-10)
        np.testing.assert_allclose(g.grad, r.grad, rtol=1e-8, atol=1e-8)


def test_pool_map_runs_one_gpu_item_per_backend_at_a_time():
    import threading
    import time
    ctx = context.Ctx(["a", "b"], ["cpu", "cuda"], True, 8, 1.0, {})
    items = [(b, d, str(i)) for i in range(4) for b in ("a", "b") for d in ("cpu", "cuda")]
    busy: dict = {}
    peak: dict = {}
    lock = threading.Lock()

    def fn(it):
        key = it[:2]
        with lock:
            busy[key] = busy.get(key, 0) + 1
            peak[key] = max(peak.get(key, 0), busy[key])
        time.sleep(0.02)
        with lock:
            busy[key] -= 1
        return it[2]

    assert ctx.map(fn, items) == [it[2] for it in items]    # order kept
    assert peak[("a", "cuda")] == peak[("b", "cuda")] == 1
    assert peak[("a", "cpu")] > 1                                          # CPU items overlap


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


def test_targets_leave_out_variants_the_framework_lacks_on_a_device_and_say_why():
    """A variant a backend declares unavailable on a device (a capability, e.g. graphs on CUDA
    only) is no target there: its stress rows are 'skipped' with the reason, never CRASHED."""
    import backends
    limited = [(b, v, d) for b, be in backends.BACKENDS.items() for v in be.variants for d in ("cpu", "cuda")
               if be.variant_unavailable(v, d)]
    if not limited:
        pytest.skip("no backend declares a variant unavailable on a device")
    b, v, d = limited[0]
    probes = {b: {"available": {"cpu": None, "cuda": None}}}
    ctx = context.Ctx([b], [d], True, 1, 1.0, probes)
    assert (b, d, v) not in ctx.targets(variants=True) and (b, d, "default") in ctx.targets(variants=True)
    skips = ctx.skip_rows("ulps", variants=True)
    assert [(r.backend, r.device, r.setting, r.verdict) for r in skips] == [(b, d, f"variant={v}", "skipped")]
    assert skips[0].detail == backends.get(b).variant_unavailable(v, d)
    assert ctx.skip_rows("ulps") == []


def test_precisions_a_framework_lacks_on_a_device_are_skipped_rows_not_errors():
    """A precision a backend declares unavailable on a device (MLX: no float64 on a GPU) is never
    asked for there: the experiments take ``ctx.precisions`` and skip_rows says why, once per
    backend, device and precision."""
    import backends
    limited = [(b, p, d) for b, be in backends.BACKENDS.items() for p in ("float32", "float64")
               for d in ("cpu", "cuda") if be.precision_unavailable(p, d)]
    if not limited:
        pytest.skip("no backend declares a precision unavailable on a device")
    b, p, d = limited[0]
    probes = {b: {"available": {"cpu": None, "cuda": None}}}
    ctx = context.Ctx([b], [d], False, 1, 1.0, probes)
    both = ("float32", "float64")
    assert p not in ctx.precisions(b, d, both) and len(ctx.precisions(b, d, both)) == 1
    skips = ctx.skip_rows("particles-dt", precisions=both)
    assert [(r.backend, r.device, r.precision, r.verdict) for r in skips] == [(b, d, p, "skipped")]
    assert skips[0].detail == backends.get(b).precision_unavailable(p, d)
    assert ctx.skip_rows("particles-dt") == []
