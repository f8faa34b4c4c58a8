"""compare/render/charts.py and the run's speed pictures, from synthetic data (no kernel runs)."""
from __future__ import annotations

import csv
from pathlib import Path

import pytest

from compare.render import charts, colors, report, run_plots
from compare.suites import run as run_suite
from compare.results.record import Record

pytestmark = pytest.mark.cli

# the eight registered backends and three the registry does not know
FRAMEWORKS = ["warp", "taichi", "jax", "numba", "cupy", "torch", "quadrants", "numpy", "mlx", "dace", "triton"]
VARIANTS = {"taichi": ["fastmath"], "jax": ["graph"], "torch": ["compile"], "warp": ["tile", "record_cmd"]}
PNG = b"\x89PNG\r\n\x1a\n"


def synthetic_bars() -> list[charts.Bar]:
    out = []
    for i, f in enumerate(FRAMEWORKS):
        for j, v in enumerate(["default", *VARIANTS.get(f, [])]):
            if f == "dace":
                out.append(charts.Bar(f, v, None, mark="error"))
            elif f == "triton":
                out.append(charts.Bar(f, v, None, mark="skipped"))
            else:
                t = 1e-5 * 1.7 ** (i + j)
                out.append(charts.Bar(f, v, t, t * 0.9, t * 1.2, "mismatch" if f == "mlx" else ""))
    return out


def draw_all(out: Path) -> list[Path]:
    bs = synthetic_bars()
    charts.bars(out / "bars.png", "saxpy (cuda float32): time per call, throughput regime", "time [s]", bs,
                log=True, fmt=report.fmt_time, ratios=True, note="whiskers: one IQR")
    charts.bar_panels(out / "panels.png", "speed-up", "ratio", [charts.Panel("cpu float32", bs),
                      charts.Panel("cpu float64", bs[:5]), charts.Panel("empty", [])],
                      log=None, better="higher", reference=(3e-5, "baseline"))
    series = [charts.Series(f, f, [1e3, 1e4, 1e5], [i + 1.0, i + 2.0, i + 5.0], [i + 0.5] * 3, [i + 6.0] * 3)
              for i, f in enumerate(FRAMEWORKS)]
    series.append(charts.Series("warp tile", "warp", [1e3, 1e4, 1e5], [3.0, 4.0, 9.0], dashed=True))
    charts.curves(out / "curves.png", "rate against n", "n", "items/s", series)
    pts = [(f, lab, 1e-4 * (i + 1), 10.0 ** -(i + k)) for i, f in enumerate(FRAMEWORKS)
           for k, lab in enumerate(["float32", "float64", "float32 fastmath"])]
    charts.pareto(out / "pareto.png", "time against error", "time [s]", "error", pts)
    return [out / f"{n}.png" for n in ("bars", "panels", "curves", "pareto")]


def test_every_chart_writes_a_png_and_its_data_and_is_deterministic(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    for d in (a, b):
        d.mkdir()
        written = draw_all(d)
    for p in written:
        assert p.read_bytes().startswith(PNG), p
        assert p.with_suffix(".csv").exists(), p
        assert p.read_bytes() == (a / p.name).read_bytes(), f"{p.name}: same input, different bytes"
        assert p.with_suffix(".csv").read_text() == (a / p.name).with_suffix(".csv").read_text()
    rows = list(csv.DictReader((a / "bars.csv").open()))
    assert len(rows) == len(synthetic_bars())
    assert sorted(r["mark"] for r in rows[-2:]) == ["error", "skipped"]     # failed cells last
    times = [float(r["value"]) for r in rows if r["value"]]
    assert times == sorted(times)                                            # best first
    pareto = list(csv.DictReader((a / "pareto.csv").open()))
    assert sum(int(r["on_front"]) for r in pareto) >= 1


def test_colours_are_distinct_and_stable_and_variants_are_hatched():
    cmap = charts.colors(FRAMEWORKS)
    assert len(set(cmap.values())) == len(FRAMEWORKS)
    assert all(cmap[f] == colors.backend_color(f) for f in FRAMEWORKS[:8])
    # an unknown framework's colour does not depend on the registered backends drawn beside it
    assert charts.colors(["mlx"])["mlx"] == charts.colors(["mlx", *FRAMEWORKS[:8]])["mlx"]
    assert charts.hatch("default") == "" and charts.hatch("fastmath") != charts.hatch("graph")
    assert charts.hatch("anything-new") != ""


def test_write_csv_formats_floats_stably(tmp_path):
    charts.write_csv(tmp_path / "x.csv", ("a", "b", "c"), [(0.1 + 0.2, None, "s"), (1e-30, 3, float("nan"))])
    assert (tmp_path / "x.csv").read_text() == "a,b,c\n0.3,,s\n1e-30,3,nan\n"


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
            for i, b in enumerate(FRAMEWORKS[:8]):
                recs.append(record(scenario, b, "cpu", prec, 1e-4 * (i + 1), throughput=b != "jax"))
                if b != "numpy":
                    recs.append(record(scenario, b, "cuda", prec, 1e-5 * (i + 1)))
            recs.append(record(scenario, "taichi", "cpu", prec, 5e-5, variant="fastmath"))
            recs.append(record(scenario, "numba", "cuda", prec, None, status="error"))
            recs.append(record(scenario, "numpy", "cuda", prec, None, status="skipped"))
    return recs


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
