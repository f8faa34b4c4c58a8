"""compare/render/figures/saxpy.py: each float32 run's error in ulps (fast tier). Named
test_figure_saxpy: pytest collects test files by basename, and other packages have a saxpy too."""
from __future__ import annotations

import numpy as np
import pytest

from compare.render import figures
from compare.render.figures import saxpy
from compare.results.record import Record
from scenarios.base import Precision

SC = saxpy.SC


def run(backend, precision="float32", scale=1.0):
    p = SC.params({"n": 4096})
    r = Record(scenario="saxpy", backend=backend, device="cpu", precision=precision, status="ok",
               params={"n": 4096})
    out = SC.oracle(p, SC.inputs(p, precision), Precision(precision))["out"]
    return r, {"out": (np.asarray(out) * scale).astype(np.float32)}


@pytest.fixture(autouse=True)
def closed():
    import matplotlib.pyplot as plt
    yield
    plt.close("all")


def test_one_histogram_per_float32_run_with_its_largest_error():
    fig = saxpy.figure([run("numpy"), run("warp", scale=1 + 2e-7), run("jax", "float64")])
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert len(labels) == 2 and labels[0].startswith("numpy/cpu/float32 (max ") and labels[1].startswith("warp/cpu/float32")
    worst = [float(x.split("max ")[1].rstrip(")")) for x in labels]
    assert worst[0] <= 0.5 < worst[1]              # the oracle rounded once; the scaled run is ulps off
    assert "n=4096" in ax.get_title() and ax.get_yscale() == "log"


def test_no_float32_run_no_figure_and_the_registry_draws_it():
    assert saxpy.figure([run("jax", "float64")]) is None
    assert figures.FIGURES["saxpy"] is saxpy.figure and figures.figure("saxpy", []) is None
