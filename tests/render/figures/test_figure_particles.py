"""compare/render/figures/particles.py: the particles picture of a run's outputs against its oracle (fast tier).
Named test_figure_particles: pytest collects test files by basename, and other packages have a particles too."""
from __future__ import annotations

import numpy as np
import pytest

from compare.render.figures import particles
from compare.results.record import Record
from scenarios.base import Precision

SC = particles.SC


@pytest.fixture(autouse=True)
def closed():
    import matplotlib.pyplot as plt
    yield
    plt.close("all")


PARAMS = {"n": 16, "steps": 20}


def run(backend, precision="float32", shift=0.0):
    p = SC.params(PARAMS)
    out = SC.oracle(p, SC.inputs(p, precision), Precision(precision))
    r = Record(scenario="particles", backend=backend, device="cpu", precision=precision, status="ok", params=PARAMS)
    return r, {k: np.asarray(v) + (shift if k in ("x", "y") else 0) for k, v in out.items()
               if k in ("x", "y", "vx", "vy")}


def test_trajectories_and_the_error_of_each_run_against_the_bound():
    fig = particles.figure([run("numpy"), run("warp", shift=1e-3)])
    left, right = fig.axes[:2]
    assert "of 16 trajectories over 20 steps" in left.get_title()
    assert [t.get_text() for t in left.get_legend().get_texts()] == ["numpy/cpu/float32 final", "warp/cpu/float32 final"]
    legend = [t.get_text() for t in right.get_legend().get_texts()]
    assert "derived bound (float32)" in legend and right.get_yscale() == "log"
    warp = next(c for c in right.collections if c.get_label() == "warp/cpu/float32")
    assert np.min(warp.get_offsets()[:, 1]) >= 1e-3 * 0.99          # the shifted run's error shows


def test_an_oracle_too_big_for_a_picture_draws_nothing():
    r, o = run("numpy")
    assert particles.figure([(r.replace(params={"n": 10**6, "steps": 100}), o)]) is None
