"""Host memory (docs/reliability.md): a size over the available memory is refused in one line,
against what is available rather than the total; a plan some of whose cells fit runs those and
records the others as skipped; the estimate bounds the worker's measured peak (the slow tier)."""
from __future__ import annotations

import json

import pytest
from pathlib import Path

from compare import cli, preflight, run_suite
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
    spec = {"scenario": "saxpy", "backend": "numba", "device": "cpu", "precision": "float32", "params": {}}
    with pytest.raises(run_suite.ParamError, match="available"):
        preflight.check_memory([spec])


def test_cells_over_the_available_memory_are_skipped_and_the_rest_run(work, monkeypatch, capsys):
    """A plan some of whose cells fit runs those and records the others as skipped with the
    memory they need (the plain `compare projectile --set batch=2^20` on a GPU machine: its CPU
    cells' tapes do not fit, its CUDA cells do)."""
    import psutil
    spec = lambda prec: {"scenario": "saxpy", "backend": "numpy", "device": "cpu",  # noqa: E731
                         "precision": prec, "params": {"n": 1 << 16}}
    small, big = preflight.cell_bytes(spec("float32"))[0], preflight.cell_bytes(spec("float64"))[0]
    assert small < big

    class Mem:
        total, available = 1 << 50, int((small + big) / 2)
    monkeypatch.setattr(psutil, "virtual_memory", lambda: Mem())
    out = work / "out"
    code = cli.main(["saxpy", "--set", "n=65536", "--backends", "numpy", "--devices", "cpu",
                     "--precision", "float32,float64", "--repeat", "3", "--out", str(out), "--no-plots"])
    assert code == 0, capsys.readouterr()
    recs = {r["precision"]: r for r in json.loads((out / "results.json").read_text())["records"]}
    assert recs["float32"]["status"] == "ok"
    assert recs["float64"]["status"] == "skipped"
    assert "host memory" in recs["float64"]["reason"] and "available" in recs["float64"]["reason"]


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
    from compare import engine
    specs = [{"scenario": sc, "backend": "warp", "device": "cpu", "precision": "float64", "params": p,
              "repeat": 1, "min_time": 0.0, "cache": "warm"} for sc, sizes in MEMORY_SIZES.items() for p in sizes]
    probes = engine.availability(["warp"])
    if probes["warp"]["available"]["cpu"]:
        pytest.skip(probes["warp"]["available"]["cpu"])
    results = engine.run_cells(specs, timeout=600, probes=probes, jobs=2)     # a process each: own peak
    ratios = []
    for spec, (rec, _) in zip(specs, results):
        assert rec.status == "ok", rec.reason
        peak = rec.memory["peak_host_rss_bytes"]
        estimate = preflight.cell_bytes(spec)[0]
        assert estimate >= peak, (spec["scenario"], spec["params"], peak / 2**20, estimate / 2**20)
        ratios.append(estimate / peak)
    FIGURES["memory"] = f"{len(specs)} cells, estimate/peak {min(ratios):.2f} to {max(ratios):.2f}"


def test_the_batched_tape_model_bounds_every_stored_cpu_horizon_slope():
    """The preflight's per-trajectory-step tape (scenarios/projectile.py TAPE_STEP_BYTES) is at
    least every CPU port's measured slope between horizons in the CPU store (fixed costs cancel)."""
    from compare.store import Store
    from scenarios.projectile import TAPE_STEP_BYTES
    store = Store.read(Path(__file__).resolve().parent.parent / "docs/results/cpu/sweep.json")
    groups: dict[tuple, dict[int, tuple[float, int]]] = {}
    for r in store.records:
        if (r.tags or {}).get("sweep") == "horizon" and r.status == "ok" and (r.memory or {}).get("host_bytes"):
            groups.setdefault((r.backend, r.variant, r.precision, r.params["contact"]), {})[r.params["steps"]] = (
                r.memory["host_bytes"], r.params["batch"])
    slopes = [(h1 - h0) / (b * (s1 - s0)) for g in groups.values()
              for (s0, (h0, b)), (s1, (h1, _)) in zip(sorted(g.items()), sorted(g.items())[1:])]
    assert len(slopes) > 20                         # the store has the sweep
    assert max(slopes) <= TAPE_STEP_BYTES[1], max(slopes)
