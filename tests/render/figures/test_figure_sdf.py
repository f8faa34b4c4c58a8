"""compare/render/figures/sdf.py: the sdf picture of a run's outputs against its oracle (fast tier).
Named test_figure_sdf: pytest collects test files by basename, and other packages have a sdf too."""
from __future__ import annotations

import numpy as np
import pytest

from compare.render.figures import sdf
from compare.results.record import Record
from scenarios.base import Precision

SC = sdf.SC


@pytest.fixture(autouse=True)
def closed():
    import matplotlib.pyplot as plt
    yield
    plt.close("all")


PARAMS = {"width": 32, "height": 24}


def run(backend, error=0.0, shape=None):
    p = SC.params(PARAMS)
    img = np.asarray(SC.oracle(p, {}, Precision.FLOAT32)["image"], np.float64) + error
    if shape:
        img = np.zeros(shape)
    r = Record(scenario="sdf", backend=backend, device="cpu", precision="float32", status="ok", params=PARAMS)
    return r, {"image": img}


def test_the_oracle_then_one_panel_per_run_with_its_largest_difference():
    fig = sdf.figure([run("numpy"), run("warp", 1e-3), run("jax", shape=(3, 3))])
    titles = [ax.get_title() for ax in fig.axes if ax.get_visible() and ax.get_title()]
    assert titles[0] == "float64 oracle, 32x24"
    warp = next(t for t in titles if t.startswith("warp/cpu/float32"))
    assert "max 0.001 = " in warp and "x derived tolerance" in warp
    assert "jax/cpu/float32: shape differs" in titles


def test_runs_without_an_image_draw_nothing():
    r, _ = run("numpy")
    assert sdf.figure([(r, {"out": np.zeros(3)})]) is None
