"""compare/stress/particles_plots.py: the dt sweep as small multiples (one panel per framework and
device, the discretisation line in each), legends clear of the data, and the sentence under each
plot (fast tier)."""
from __future__ import annotations

import io

from compare.render import figure_check
from compare.stress import particles_plots
from compare.stress.plots import _style


def dt_series() -> dict:
    dts = [0.02, 0.01, 0.005, 0.002, 0.001]
    lines = {f"{b}/cuda/{p}": {"dt": dts, "median": [(1e-6 if p == "float32" else 1e-15) * (1 + i) for i in range(5)]}
             for b in ("warp", "jax", "numba", "torch", "taichi", "cupy") for p in ("float32", "float64")}
    return {"lines": lines, "dt": dts, "discretisation": [0.5, 0.3, 0.1, 0.05, 0.02]}


def test_the_dt_plot_is_one_panel_per_framework_with_the_discretisation_in_each():
    import matplotlib.pyplot as plt
    saved = []
    real = plt.Figure.savefig
    def keep(self, *a, **k):
        saved.append(self)
        return real(self, *a, **k)
    plt.Figure.savefig = keep
    try:
        particles_plots.plot_particles_dt(dt_series(), io.BytesIO(), _style)
    finally:
        plt.Figure.savefig = real
    fig = saved[0]
    shown = [ax for ax in fig.axes if ax.get_visible()]
    assert sorted(ax.get_title() for ax in shown) == sorted(f"{b} cuda" for b in
                                                             ("warp", "jax", "numba", "torch", "taichi", "cupy"))
    for ax in shown:          # both precisions and the black discretisation line in every panel
        assert len(ax.get_lines()) == 3 and any(line.get_color() == "k" for line in ax.get_lines())
    assert figure_check.problems(fig) == []


def test_every_particles_plot_says_what_to_see():
    from compare.stress.particles import EXPERIMENTS
    for e in EXPERIMENTS.values():
        assert (e.plot is None) or e.look, e.name
