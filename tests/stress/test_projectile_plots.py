"""compare/stress/projectile_plots.py: the lr matrix above projectile-lr's table, the rows that
table keeps, and the three plots from stored series (fast tier)."""
from __future__ import annotations

import io

import pytest

from compare.stress import projectile_plots as pp
from compare.stress.plots import _style


def row(setting, verdict, backend="warp", experiment="projectile-lr"):
    return {"experiment": experiment, "backend": backend, "device": "cuda", "precision": "float32",
            "setting": setting, "figure": "f", "value": 1.0, "verdict": verdict, "detail": ""}


ROWS = [row("gd, contact=hard, lr=0.01, iters=60", "converged"), row("gd, contact=hard, lr=0.2, iters=60", "diverged"),
        row("gd, contact=hard, lr=0.08, iters=60", "stalled"), row("adam, contact=soft, lr=0.01, iters=60", "error"),
        row("gd, contact=hard", "agrees with predicted lr* = 0.05"),
        row("gd, contact=hard, lr=0.5", "diverged", experiment="other")]


def test_the_lr_matrix_has_one_line_per_optimiser_and_contact_and_one_column_per_lr():
    text = pp.lr_matrix(ROWS)
    lines = [ln for ln in text.splitlines() if ln.startswith("| warp")]
    assert "lr 0.01 " in text and "lr 0.08" in text and "lr 0.2 " in text and "lr 0.5" not in text
    gd = next(ln for ln in lines if "| gd " in ln)
    assert [c.strip() for c in gd.split("|")[6:9]] == ["C", "S", "**D**"]
    adam = next(ln for ln in lines if "| adam " in ln)
    assert [c.strip() for c in adam.split("|")[6:9]] == ["E", "", ""]
    assert pp.lr_matrix([]).endswith("\n\n")                  # the legend alone


def test_the_table_keeps_the_boundaries_not_the_per_lr_rows():
    assert pp.lr_table_rows(ROWS) == [ROWS[4]]


@pytest.fixture(autouse=True)
def closed():
    import matplotlib.pyplot as plt
    yield
    plt.close("all")


SERIES = {
    pp.plot_projectile_lr: {"histories": {"warp/cuda/gd/hard/0.01": [1.0, 0.5, 0.1],
                                          "oracle64/host/adam/soft/0.2": [1.0, 2.0, 4.0]}},
    pp.plot_projectile_gradient: {"h": [1e-4, 1e-3], "lines": {"warp/cuda/float32/hard": [1e-3, 1e-2]},
                                  "gd_step": {"hard": 1e-3},
                                  "scans": {f"warp/cuda/{c}": {"vy": [6.0, 6.5], "loss": [1.0, 2.0], "dvy": [0.1, 0.2]}
                                            for c in ("hard", "soft")}},
    pp.plot_projectile_horizon: {"warp/cuda/hard": {"steps": [10, 100], "grad": [1.0, 10.0], "rel": [1e-6, 1e-3]}},
}


@pytest.mark.parametrize("plot", list(SERIES), ids=lambda f: f.__name__)
def test_each_plot_draws_its_series_into_a_png(plot):
    buf = io.BytesIO()
    plot(SERIES[plot], buf, _style)
    assert buf.getvalue().startswith(b"\x89PNG")
