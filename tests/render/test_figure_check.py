"""The layout check of every saved figure (compare/render/figure_check.py, fast tier): texts outside
the canvas, two texts' boxes overlapping and a legend over data points are found from
matplotlib's renderer; the verdict rides in the PNG; legends are placed clear of the data and
data labels kept apart; the charts and the site's figures are saved through it."""
from __future__ import annotations

import io
from pathlib import Path

import pytest

from compare.render import charts, figure_check

pytestmark = pytest.mark.cli


@pytest.fixture
def plt():
    return charts.pyplot()


def test_a_clean_figure_has_no_problems(plt):
    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    ax.plot([1, 2, 3], [1, 4, 9], label="squares")
    ax.set_title("clean"); ax.set_xlabel("x"); ax.legend(loc="upper left")
    assert figure_check.problems(fig) == []


def test_overlapping_texts_are_found(plt):
    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    ax.text(0.5, 0.5, "first label"); ax.text(0.52, 0.5, "second label")
    found = figure_check.problems(fig)
    assert len(found) == 1 and "'first label' overlaps text 'second label'" in found[0]


def test_a_text_outside_the_canvas_is_found(plt):
    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    ax.set_xlabel("a very long x label " * 8)
    assert any("outside the canvas" in p for p in figure_check.problems(fig))


def test_a_legend_over_data_points_is_found_and_placing_it_clears_them(plt):
    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    xs = [i / 20 for i in range(21)]
    for k in range(4):       # data everywhere: no corner is free
        ax.plot(xs, [(x + k / 4) % 1 for x in xs], "o", ms=2, label=f"series {k}")
    ax.legend(loc="center")
    assert any("legend of an axes covers" in p for p in figure_check.problems(fig))
    figure_check.place_legends([ax])
    assert figure_check.problems(fig) == []


def test_labels_at_points_are_kept_apart(plt):
    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    notes = [ax.annotate(f"dt={v}", (0.5, 0.5 + i * 0.001)) for i, v in enumerate((0.025, 0.00625))]
    kept = figure_check.keep_apart(notes)
    assert [t.get_text() for t in kept] == ["dt=0.025"] and figure_check.problems(fig) == []


def test_the_verdict_rides_in_the_png_and_the_png_still_decodes(plt, tmp_path: Path):
    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    ax.text(0.5, 0.5, "one"); ax.text(0.5, 0.5, "two")
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    png = tmp_path / "f.png"
    png.write_bytes(figure_check.save_checked(fig, buf.getvalue()))
    assert figure_check.read(png) == figure_check.problems(fig) != []
    assert plt.imread(png).shape[:2] == (300, 400)
    png.write_bytes(buf.getvalue())
    assert figure_check.read(png) is None                 # saved without the check


def test_charts_and_figures_saved_by_plot_functions_are_stamped(plt, tmp_path: Path):
    bars = tmp_path / "bars.png"
    charts.bars(bars, "t", "seconds", [charts.Bar("warp", "default", 1e-3), charts.Bar("jax", "default", 2e-3)],
                data=False)
    assert figure_check.read(bars) == []

    def own_save(path: Path) -> None:      # a plot that saves and closes its own figure
        fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
        ax.text(0.5, 0.5, "one"); ax.text(0.5, 0.5, "two")
        fig.savefig(path); plt.close(fig)
    png = tmp_path / "own.png"
    figure_check.checked(lambda: own_save(png), png)
    assert len(figure_check.read(png)) == 1


def test_a_legend_over_a_line_between_its_vertices_is_found(plt):
    """A line of two vertices in the corners crosses the middle: a legend there hides it, though
    it covers neither vertex (the stability dt figure's legend hid the discretisation line so)."""
    fig, ax = plt.subplots(figsize=(4, 3), layout="constrained")
    ax.plot([0, 1], [0, 1], "k-", label="a diagonal line")
    ax.plot([0, 1], [1, 0], "o", ls="none", label="two points")
    ax.legend(loc="center")
    found = figure_check.problems(fig)
    assert len(found) == 1 and "covers" in found[0]
    ax.legend(loc="upper center", fontsize=6)        # above the diagonal, between the two points
    assert figure_check.problems(fig) == []
