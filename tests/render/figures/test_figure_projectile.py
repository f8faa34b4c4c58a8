"""compare/render/figures/projectile.py: the projectile picture of a run's outputs against its oracle (fast tier).
Named test_figure_projectile: pytest collects test files by basename, and other packages have a projectile too."""
from __future__ import annotations

import numpy as np
import pytest

from compare.render.figures import projectile
from compare.results.record import Record
from scenarios.base import Precision

SC = projectile.SC


@pytest.fixture(autouse=True)
def closed():
    import matplotlib.pyplot as plt
    yield
    plt.close("all")


PARAMS = {"steps": 40, "iters": 8}


def run(backend, precision="float32", scale=1.0, batch=1):
    p = SC.params({**PARAMS, "batch": 1})
    out = SC.oracle(p, SC.inputs(p, precision), Precision(precision))
    h = np.asarray(out["loss_history"]) * scale
    r = Record(scenario="projectile", backend=backend, device="cpu", precision=precision, status="ok",
               params={**PARAMS, "batch": batch})
    if batch > 1:                               # a batch: one column per case, row 0 the seed case
        return r, {"loss_history": np.repeat(h.reshape(-1, 1), batch, axis=1)}
    return r, {"loss_history": h}


def test_each_descent_over_the_oracles_and_its_distance_to_it():
    fig = projectile.figure([run("numpy"), run("warp", scale=1.01), run("jax", "float64")])
    left, right = fig.axes[:2]
    assert [t.get_text() for t in left.get_legend().get_texts()] == [
        "float64 oracle", "numpy/cpu/float32", "warp/cpu/float32", "jax/cpu/float64"]
    assert "40 steps" in left.get_title()
    lines = {ln.get_label(): ln for ln in right.get_lines()}
    assert {"derived bound, float32", "derived bound, float64"} <= set(lines)
    assert np.allclose(lines["warp/cpu/float32"].get_ydata(), 0.01, rtol=1e-3)     # 1 % off the oracle


def test_a_batch_draws_its_seed_case():
    fig = projectile.figure([run("numpy", batch=3)])
    rel = next(ln for ln in fig.axes[1].get_lines() if ln.get_label() == "numpy/cpu/float32")
    assert np.max(rel.get_ydata()) <= 1e-17
