"""compare/render/run_plots.py: the run's speed pictures, the CPU speed-up and the scenarios' own
pictures, from synthetic records (no kernel runs; moved here from tests/render/test_charts.py)."""
from __future__ import annotations

import csv
from pathlib import Path

import pytest

from compare.render import run_plots
from compare.results.record import Record
from compare.suites import run as run_suite

pytestmark = pytest.mark.cli

FRAMEWORKS = ["warp", "taichi", "jax", "numba", "cupy", "torch", "quadrants", "numpy"]
# the tests that draw synthetic_records' pictures, on one worker in file order: the first draws
# them, the later ones' drawings in turn are the chart memo's (tests/conftest.py)
DRAWN = pytest.mark.xdist_group("run-plots-drawn")


def record(scenario: str, backend: str, device: str, precision: str, t: float | None,
           variant: str = "default", status: str = "ok", throughput: bool = True) -> Record:
    time = {}
    if t is not None:
        time = {"median_s": t * 1.3, "iqr_s": t * 0.1, "latency": {"median_s": t * 1.3, "iqr_s": t * 0.1}}
        time["wall"] = time["latency"]
        if throughput:
            time["throughput"] = {"median_s": t, "iqr_s": t * 0.05, "k": 10}
    return Record(scenario=scenario, backend=backend, device=device, precision=precision,
                  variant=variant, params={"n": 1000}, status=status,
                  reason="" if status == "ok" else "injected", time=time,
                  error={"vs_oracle": 1e-7 if precision == "float32" else 0.0} if t else None)


def synthetic_records() -> list[Record]:
    recs = []
    for scenario in ("saxpy", "sdf"):
        for prec in ("float32", "float64"):
            for i, b in enumerate(FRAMEWORKS):
                recs.append(record(scenario, b, "cpu", prec, 1e-4 * (i + 1), throughput=b != "jax"))
                if b != "numpy":
                    recs.append(record(scenario, b, "cuda", prec, 1e-5 * (i + 1)))
            recs.append(record(scenario, "taichi", "cpu", prec, 5e-5, variant="fastmath"))
            recs.append(record(scenario, "numba", "cuda", prec, None, status="error"))
            recs.append(record(scenario, "numpy", "cuda", prec, None, status="skipped"))
    return recs


@DRAWN
def test_run_writes_speed_pictures_and_the_cpu_speedup(tmp_path):
    recs = synthetic_records()
    run_suite.render(tmp_path, {"command": "test"}, recs, {}, plots=True)
    pngs = {p.stem for p in (tmp_path / "plots").glob("*.png")}
    assert {"speed_saxpy", "speed_sdf", "speedup_vs_numpy_cpu", "time_vs_error"} <= pngs
    speed = list(csv.DictReader((tmp_path / "plots" / "speed_saxpy.csv").open()))
    assert {r["panel"] for r in speed} == {"cpu float32", "cpu float64", "cuda float32", "cuda float64"}
    jax = next(r for r in speed if r["framework"] == "jax" and r["panel"] == "cpu float32")
    assert jax["mark"] == "latency regime" and float(jax["value"]) == pytest.approx(3e-4 * 1.3)
    assert next(r for r in speed if r["framework"] == "numba" and r["panel"] == "cuda float32"
                and r["variant"] == "default" and r["mark"] == "error")["value"] == ""
    up = list(csv.DictReader((tmp_path / "plots" / "speedup_vs_numpy_cpu.csv").open()))
    warp = next(r for r in up if r["framework"] == "warp" and r["panel"] == "saxpy: cpu float32")
    assert float(warp["value"]) == pytest.approx(8.0)                  # numpy 8e-4 s / warp 1e-4 s
    assert "numpy" not in {r["framework"] for r in up}
    md = (tmp_path / "results.md").read_text()
    assert "(plots/speed_saxpy.png)" in md and "(plots/speed_sdf.png)" in md


def test_no_numpy_no_speedup_and_no_plots_no_png(tmp_path):
    recs = [r for r in synthetic_records() if r.backend != "numpy"]
    assert not run_plots.plot_speedup_vs_baseline(recs, tmp_path / "up.png", "numpy")
    assert not (tmp_path / "up.png").exists()
    run_suite.render(tmp_path / "run", {}, recs, {}, plots=False)
    assert not list((tmp_path / "run").rglob("*.png"))


def test_speed_panels_name_only_what_differs():
    recs = [record("saxpy", "warp", "cpu", "float32", 1e-4), record("saxpy", "warp", "cuda", "float32", 1e-5),
            record("saxpy", "warp", "cuda", "float32", 1e-5).replace(params={"n": 2000})]
    assert list(run_plots.speed_panels(recs)) == ["cpu float32, n=1000", "cuda float32, n=1000", "cuda float32, n=2000"]
    assert list(run_plots.speed_panels(recs[:2])) == ["cpu float32", "cuda float32"]


def test_speed_bar_is_the_time_per_call_or_the_speed_up_over_a_base():
    fast, slow = record("saxpy", "warp", "cpu", "float32", 1e-4), record("saxpy", "numpy", "cpu", "float32", 4e-4)
    bar = run_plots.speed_bar(fast)
    assert (bar.framework, bar.value, bar.mark) == ("warp", 1e-4, "")
    assert bar.lo == pytest.approx(1e-4 - 2.5e-6) and bar.hi == pytest.approx(1e-4 + 2.5e-6)
    assert run_plots.speed_bar(fast, slow).value == pytest.approx(4.0)
    assert run_plots.speed_bar(record("saxpy", "jax", "cpu", "float32", 1e-4, throughput=False)).mark == "latency regime"
    failed = run_plots.speed_bar(record("saxpy", "numba", "cpu", "float32", None, status="error"))
    assert failed.value is None and failed.mark == "error"


def test_remove_pictures_removes_only_a_runs_own_names(tmp_path):
    for name in ("speed_saxpy.png", "speed_saxpy.csv", "speedup_vs_numpy_cpu.png", "time_vs_error.png",
                 "sdf.png", "mine.png", "notes.csv"):
        (tmp_path / name).write_text("x")
    run_plots.remove_pictures(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["mine.png", "notes.csv"]
    run_plots.remove_pictures(tmp_path / "absent")          # no folder: nothing to do


def test_remove_pictures_follows_no_symlink(tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    (real / "speed_saxpy.png").write_text("x")
    (tmp_path / "plots").symlink_to(real)
    run_plots.remove_pictures(tmp_path / "plots")
    assert (real / "speed_saxpy.png").exists()


FORKED = """
import concurrent.futures, sys
from pathlib import Path
sys.path.insert(0, "tests/render")
from test_run_plots import synthetic_records
from compare.render import chart_memo, run_plots
pools = []
class Pool(concurrent.futures.ProcessPoolExecutor):
    def __init__(self, *a, **k):
        pools.append(a)
        super().__init__(*a, **k)
concurrent.futures.ProcessPoolExecutor = Pool
out = Path(sys.argv[1])
recs = synthetic_records()
run_plots.write_plots(recs, {}, out / "turn", workers=1)
chart_memo.forget()                  # the side-by-side pictures drawn, not written from memory
run_plots.write_plots(recs, {}, out / "side", workers=2)
assert pools and not run_plots._jobs, (pools, run_plots._jobs)     # forked; nothing left for a later fork
print("RESULT", run_plots.frameworks_loaded())
"""


@DRAWN
def test_pictures_drawn_side_by_side_are_the_ones_drawn_in_turn(tmp_path):
    """write_plots' forked drawing processes write the same files, byte for byte, as one
    process drawing them in turn (each job its own files): in a fresh interpreter, as the
    driver's, which loads no framework (a test process may have, and then draws in turn)."""
    import subprocess
    import sys
    p = subprocess.run([sys.executable, "-c", FORKED, str(tmp_path)], cwd=Path(__file__).parents[2],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0 and "RESULT []" in p.stdout, p.stdout + p.stderr[-3000:]
    turn = {f.name: f.read_bytes() for f in (tmp_path / "turn").iterdir()}
    assert {"speed_saxpy.png", "speed_sdf.png", "speedup_vs_numpy_cpu.png", "time_vs_error.png"} <= set(turn)
    assert turn == {f.name: f.read_bytes() for f in (tmp_path / "side").iterdir()}


@DRAWN
def test_a_process_with_a_framework_loaded_draws_in_turn(tmp_path, monkeypatch):
    """A framework's own native threads are invisible to threading: where one is loaded, no fork."""
    import concurrent.futures
    import importlib.metadata
    import sys
    import backends
    dists = {b.package for b in backends.BACKENDS.values() if not b.is_cpu_baseline}
    installed = sorted(m for m, ds in importlib.metadata.packages_distributions().items() if dists & set(ds))
    assert installed, "no framework's distribution installed (the base install has several)"
    monkeypatch.setitem(sys.modules, installed[0], sys.modules.get(installed[0]) or object())
    monkeypatch.setattr(concurrent.futures, "ProcessPoolExecutor",
                        lambda *a, **k: pytest.fail("forked with a framework loaded"))
    run_plots.write_plots(synthetic_records(), {}, tmp_path / "turn", workers=2)
    assert (tmp_path / "turn" / "speed_saxpy.png").exists()
