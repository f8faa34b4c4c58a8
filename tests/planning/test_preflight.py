"""Host memory (docs/reliability.md): a size over the available memory is refused in one line,
against what is available rather than the total; a plan some of whose cells fit runs those and
records the others as skipped; the estimate bounds the worker's measured peak (the slow tier)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pytest
from pathlib import Path

from compare import cli
from compare.planning import outdir, preflight
from compare.suites import run as run_suite
from compare.spec import Cell
from scenarios.base import ParamError
from conftest import ROOT
from reliability_checks import FIGURES, assert_refused, working_directory

pytestmark = pytest.mark.cli


@pytest.fixture()
def work(tmp_path, monkeypatch):
    return working_directory(tmp_path, monkeypatch)


# ---- refusals and skips --------------------------------------------------------------------------
def test_a_size_over_the_available_memory_is_refused(work):
    import psutil
    sc = run_suite.scenarios.get("saxpy")
    per_item = sc.footprint(sc.params({"n": 1 << 20}), "float64") / (1 << 20)
    n = int(psutil.virtual_memory().available / per_item * 1.5)
    if n > 2**31 - 1:
        pytest.skip("more memory available than the largest saxpy needs")
    assert_refused(["saxpy", "--set", f"n={n}", "--precision", "float64", "--out", str(work / "out")],
                   work, "available")


def test_memory_is_compared_with_available_not_total(monkeypatch):
    import psutil

    class Mem:
        total, available = 1 << 50, 1 << 20
    monkeypatch.setattr(psutil, "virtual_memory", lambda: Mem())
    spec = Cell.make("saxpy", "numba", "cpu", "float32", params={})
    with pytest.raises(ParamError, match="available"):
        preflight.check_memory([spec])


def test_cells_over_the_available_memory_are_skipped_and_the_rest_run(work, monkeypatch, capsys):
    """A plan some of whose cells fit runs those and records the others as skipped with the
    memory they need (the plain `compare projectile --set batch=2^20` on a GPU machine: its CPU
    cells' tapes do not fit, its CUDA cells do)."""
    import psutil
    spec = lambda prec: Cell.make("saxpy", "numpy", "cpu", prec, params={"n": 1 << 16})  # noqa: E731
    small, big = preflight.cell_bytes(spec("float32"))[0], preflight.cell_bytes(spec("float64"))[0]
    assert small < big

    class Mem:
        total, available = 1 << 50, int((small + big) / 2)
    monkeypatch.setattr(psutil, "virtual_memory", lambda: Mem())
    out = work / "out"
    code = cli.main(["saxpy", "--set", "n=65536", "--backends", "numpy", "--devices", "cpu",
                     "--precision", "float32,float64", "--repeat", "3", "--min-time", "0", "--out", str(out),
                     "--no-plots"])
    assert code == 0, capsys.readouterr()
    recs = {r["precision"]: r for r in json.loads((out / "results.json").read_text())["records"]}
    assert recs["float32"]["status"] == "ok"
    assert recs["float64"]["status"] == "skipped"
    assert "host memory" in recs["float64"]["reason"] and "available" in recs["float64"]["reason"]


# ---- each big cell judged by its own framework's miniatures ---------------------------------------
GIB = float(1 << 30)


def fake_miniatures(per_item: dict[str, float], seen: list | None = None, fixed: float = 200 * 2**20):
    """A miniature runner: the peak of ``fixed`` bytes plus ``per_item[backend]`` per work item."""
    from compare.planning import calibrate

    def run(small):
        if seen is not None:
            seen.append((small.backend, small.params.batch))
        peak = fixed + per_item[small.backend] * calibrate.items(small)
        return {"status": "ok", "time": {"median_s": 1e-3, "first_call_s": 2e-3},
                "memory": {"peak_host_rss_bytes": peak}}, None
    return run


def available_memory(monkeypatch, have: float) -> None:
    import psutil

    class Mem:
        total, available = 1 << 50, int(have)
    monkeypatch.setattr(psutil, "virtual_memory", lambda: Mem())


def test_big_cells_are_judged_by_their_own_frameworks_miniatures(monkeypatch):
    """At B = 2^20 the scenario's model bounds every framework alike (the largest tape any port
    keeps: 72 GiB): each cell is estimated instead from its own miniatures at 1/64 and 1/256 of
    its size, and only the one whose estimate exceeds what is available is skipped, with it."""
    from compare.planning import calibrate
    from compare.spec import Cell
    have = 8 * GIB
    available_memory(monkeypatch, have)
    plan = [Cell.make("projectile", b, "cpu", "float32", params={"batch": 1 << 20}) for b in ("numba", "torch")]
    assert all(preflight.cell_bytes(c)[0] > 60 * GIB for c in plan)
    assert [preflight.memory_refusal()(c) for c in plan] == [None, None]     # not judged yet
    per_item = {"numba": 0.05, "torch": 1.0}
    seen: list = []
    need = preflight.measured_need(plan, 600.0, run=fake_miniatures(per_item, seen))
    assert sorted(seen) == sorted((b, (1 << 20) // f) for b in per_item for f in (64, 256))
    sc = run_suite.scenarios.get("projectile")
    expected = {}
    for c in plan:      # the 1/64 peak + twice the slope up to the full size + the check's arrays
        n1, n = calibrate.items(calibrate.miniature(c, 64)), calibrate.items(c)
        expected[c.backend] = (200 * 2**20 + per_item[c.backend] * n1 + 2.0 * per_item[c.backend] * (n - n1)
                               + sc.footprint(c.params, "float32", "cuda"))
        assert need(c) == pytest.approx(expected[c.backend])
    assert expected["numba"] < have < expected["torch"]
    refuse = preflight.memory_refusal(need)
    assert refuse(plan[0]) is None
    status, why = refuse(plan[1])
    assert status == "skipped" and f"needs about {outdir.gib(expected['torch'])}" in why, why
    assert f"{outdir.gib(have)} is available" in why and "1/64 and 1/256" in why, why


def test_a_miniature_that_failed_leaves_the_model_bound_to_decide(monkeypatch):
    from compare.spec import Cell
    available_memory(monkeypatch, 8 * GIB)
    cell = Cell.make("projectile", "numba", "cpu", "float32", params={"batch": 1 << 20})
    seen: list = []
    need = preflight.measured_need([cell], 600.0, run=lambda small: (seen.append(small.params.batch),
                                                                     ({"status": "error", "reason": "x"}, None))[1])
    assert need(cell) is None and seen == [(1 << 20) // 64]      # the one at 1/256 is not run after it
    status, why = preflight.memory_refusal(need)(cell)
    assert status == "skipped" and preflight.outdir.gib(preflight.cell_bytes(cell)[0]) in why


# a big cell (B >= 2^16) that runs in a second: the preflight judges it, the real cell runs
CHEAP_BIG = ["projectile", "--set", "batch=65536", "--set", "steps=4", "--set", "iters=1", "--devices", "cpu",
             "--precision", "float32", "--repeat", "3", "--min-time", "0", "--no-plots"]


def test_the_cells_that_fit_run_and_the_others_are_skipped_with_their_estimate(work, monkeypatch, capsys):
    from compare.planning import calibrate
    from compare.spec import Cell
    bound = preflight.cell_bytes(Cell.make("projectile", "numpy", "cpu", "float32",
                                           params={"batch": 65536, "steps": 4, "iters": 1}))[0]
    available_memory(monkeypatch, 0.9 * bound)        # the model's bound fits neither
    real = calibrate.run_miniatures
    runner = fake_miniatures({"numpy": 0.0, "numba": 2000.0}, fixed=2**20)
    monkeypatch.setattr(calibrate, "run_miniatures",
                        lambda plan, timeout, factor=64, run=None: real(plan, timeout, factor, runner))
    out = work / "out"
    code = cli.main([*CHEAP_BIG, "--backends", "numpy,numba", "--out", str(out)])
    assert code == 0, capsys.readouterr()
    recs = {r["backend"]: r for r in json.loads((out / "results.json").read_text())["records"]}
    assert recs["numpy"]["status"] == "ok", recs["numpy"]
    assert recs["numba"]["status"] == "skipped", recs["numba"]
    assert "needs about" in recs["numba"]["reason"] and "1/64 and 1/256" in recs["numba"]["reason"]


def test_a_plan_none_of_whose_cells_fits_is_refused_with_its_estimate(work, monkeypatch):
    from compare.planning import calibrate
    from compare.spec import Cell
    bound = preflight.cell_bytes(Cell.make("projectile", "numpy", "cpu", "float32",
                                           params={"batch": 65536, "steps": 4, "iters": 1}))[0]
    available_memory(monkeypatch, 0.9 * bound)
    real = calibrate.run_miniatures
    runner = fake_miniatures({"numpy": 2000.0, "numba": 2000.0}, fixed=2**20)
    monkeypatch.setattr(calibrate, "run_miniatures",
                        lambda plan, timeout, factor=64, run=None: real(plan, timeout, factor, runner))
    line = assert_refused([*CHEAP_BIG, "--backends", "numpy,numba", "--out", str(work / "out")], work,
                          "nothing fits this machine's memory")
    assert "needs about" in line and "1/64 and 1/256" in line, line


# ---- a hopeless cell: refused from the model before any miniature runs ----------------------------
HOPELESS = ["projectile", "--quick", "--backends", "numpy", "--devices", "cpu", "--set", "steps=1e7",
            "--set", "batch=16777216"]


def hopeless_or_skip() -> Cell:
    import psutil
    cell = Cell.make("projectile", "numpy", "cpu", "float32", params={"steps": 10**7, "batch": 1 << 24})
    if preflight.floor_bytes(cell) <= psutil.virtual_memory().available:
        pytest.skip("this machine has the memory the hopeless cell's check needs")
    return cell


def test_a_cell_over_its_floor_runs_no_miniature_and_is_skipped_with_it(monkeypatch):
    """Every estimate includes the framework-independent part (``floor_bytes``: the check's arrays,
    inputs, outputs): a cell over it is refused at once; one under it is still judged by its own."""
    from compare.spec import Cell
    have = 8 * GIB
    available_memory(monkeypatch, have)
    hopeless = Cell.make("projectile", "numpy", "cpu", "float32", params={"steps": 10**7, "batch": 1 << 24})
    big = Cell.make("projectile", "numpy", "cpu", "float32", params={"batch": 1 << 20})
    assert preflight.floor_bytes(hopeless) > have > preflight.floor_bytes(big)
    assert preflight.cell_bytes(big)[0] > have and preflight.measured_later(hopeless, have)
    status, why = preflight.memory_refusal()(hopeless)            # before any miniature: skipped
    assert status == "skipped" and "whatever its framework" in why and preflight.outdir.gib(have) in why, why
    assert preflight.memory_refusal()(big) is None                # its miniatures decide
    seen: list = []
    need = preflight.measured_need([hopeless, big], 600.0, run=fake_miniatures({"numpy": 0.0}, seen))
    assert sorted(seen) == [("numpy", (1 << 20) // 256), ("numpy", (1 << 20) // 64)]
    assert preflight.memory_refusal(need)(big) is None and preflight.memory_refusal(need)(hopeless)[0] == "skipped"


def test_a_hopeless_plan_is_refused_in_one_line_before_any_miniature(work, monkeypatch):
    from compare.planning import calibrate
    hopeless_or_skip()

    def never(*a, **k):
        raise AssertionError("a miniature ran")
    monkeypatch.setattr(calibrate, "run_miniatures", never)
    line = assert_refused([*HOPELESS, "--out", str(work / "out")], work, "whatever its framework")
    assert "GiB is available" in line, line


def test_the_hopeless_cell_of_issue_58_is_refused_within_seconds(work):
    """``compare projectile --set steps=1e7 --set batch=16777216`` on the CPU printed nothing for
    30 minutes (two miniatures bounded by --timeout alone): now exit 2 and one line, in a real
    process. Target under 10 s (about 1 s on the 2-core box); 30 s here for a loaded machine."""
    hopeless_or_skip()
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "compare", *HOPELESS, "--out", str(work / "out")],
                          capture_output=True, text=True, timeout=300, cwd=work,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    took = time.perf_counter() - t0
    lines = [ln for ln in done.stderr.splitlines() if ln.strip()]
    assert done.returncode == 2 and len(lines) == 1 and lines[0].startswith("error: "), done.stderr
    assert "whatever its framework" in lines[0] and "Traceback" not in done.stderr, lines
    assert took < 30.0, took
    assert not (work / "out").exists()


# ---- the memory estimate against measured peaks ---------------------------------------------------
MEMORY_SIZES = {"saxpy": ({"n": 1 << 16}, {"n": 1 << 23}),
                "sdf": ({"width": 256, "height": 256}, {"width": 2048, "height": 2048}),
                "particles": ({"n": 1 << 12, "steps": 20}, {"n": 1 << 20, "steps": 10, "record_every": 5},
                              {"n": 1 << 14, "steps": 200, "record_every": 1}),
                "projectile": ({"steps": 180, "iters": 2}, {"steps": 100_000, "iters": 1},
                               {"batch": 4096, "steps": 1000, "iters": 0})}


@pytest.mark.slow
def test_memory_estimate_bounds_measured_peaks():
    """WORKER_BASELINE_BYTES + Scenario.footprint >= the worker's measured peak RSS, for every
    scenario at two sizes (warp on CPU, float64: the larger arrays; warm caches)."""
    from compare.running import engine
    specs = [{"scenario": sc, "backend": "warp", "device": "cpu", "precision": "float64", "params": p,
              "repeat": 1, "min_time": 0.0, "cache": "warm"} for sc, sizes in MEMORY_SIZES.items() for p in sizes]
    probes = engine.availability(["warp"])
    if probes["warp"]["available"]["cpu"]:
        pytest.skip(probes["warp"]["available"]["cpu"])
    results = engine.run_cells([Cell.from_dict(s) for s in specs], timeout=600, probes=probes, jobs=2)     # a process each: own peak
    ratios = []
    for spec, (rec, _) in zip(specs, results):
        assert rec.status == "ok", rec.reason
        peak = rec.memory["peak_host_rss_bytes"]
        estimate = preflight.cell_bytes(Cell.from_dict(spec))[0]
        assert estimate >= peak, (spec["scenario"], spec["params"], peak / 2**20, estimate / 2**20)
        ratios.append(estimate / peak)
    FIGURES["memory"] = f"{len(specs)} cells, estimate/peak {min(ratios):.2f} to {max(ratios):.2f}"


def test_the_batched_tape_model_bounds_every_stored_cpu_horizon_slope():
    """The preflight's per-trajectory-step tape (scenarios/projectile.py TAPE_STEP_BYTES) is at
    least every CPU port's measured slope between horizons in the CPU store (fixed costs cancel)."""
    from compare.results.store import Store
    from scenarios.projectile import TAPE_STEP_BYTES
    store = Store.read(Path(__file__).resolve().parents[2] / "docs/results/cpu/sweep.json")
    groups: dict[tuple, dict[int, tuple[float, int]]] = {}
    for r in store.records:
        if (r.tags or {}).get("sweep") == "horizon" and r.status == "ok" and (r.memory or {}).get("host_bytes"):
            groups.setdefault((r.backend, r.variant, r.precision, r.params["contact"]), {})[r.params["steps"]] = (
                r.memory["host_bytes"], r.params["batch"])
    slopes = [(h1 - h0) / (b * (s1 - s0)) for g in groups.values()
              for (s0, (h0, b)), (s1, (h1, _)) in zip(sorted(g.items()), sorted(g.items())[1:])]
    assert len(slopes) > 20                         # the store has the sweep
    assert max(slopes) <= TAPE_STEP_BYTES[1], max(slopes)
