"""compare/render/charts.py from synthetic data (no kernel runs); the run's speed pictures:
tests/render/test_run_plots.py."""
from __future__ import annotations

import csv
from pathlib import Path

import pytest

from compare.render import chart_memo, charts, colors, report

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
    return [out / f"{n}.png" for n in ("bars", "panels", "curves")]


def test_every_chart_writes_a_png_and_its_data_and_is_deterministic(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    for d in (a, b):
        d.mkdir()
        chart_memo.forget()                  # each drawn, not the second written from memory
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
