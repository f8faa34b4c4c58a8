"""compare/sweep/horizon_panels.py: the horizon sweep as small multiples, one panel per framework
(memory, time) and the gradient quality alone, each laid out clear of its data (fast tier), on the
site's test store."""
from __future__ import annotations

from pathlib import Path

import pytest

from compare.render import figure_check
from compare.results.store import Store
from compare.sweep import horizon_panels, plots

STORE = Path(__file__).resolve().parents[2] / "tests" / "data" / "site" / "sweep.json"


@pytest.mark.parametrize("part", ["memory", "time", "quality"])
def test_each_part_draws_one_panel_per_framework_clear_of_its_data(tmp_path, part):
    from compare.suites import formats
    formats.register()
    recs = list(Store.read(STORE, "sweep").records)
    png = tmp_path / f"{part}.png"
    drawn: list = []
    real = plots._plt()
    class Spy:                     # the figure the part draws, kept for its layout check
        def __getattr__(self, name):
            return getattr(real, name)
        def subplots(self, *a, **k):
            fig, axes = real.subplots(*a, **k)
            drawn.append(fig)
            return fig, axes
        def close(self, fig=None):
            pass
    import unittest.mock
    with unittest.mock.patch.object(plots, "_plt", lambda: Spy()):
        assert plots.plot_horizon(recs, "cuda", png, "projectile", part)
    assert png.read_bytes().startswith(b"\x89PNG")
    fig = drawn[0]
    assert figure_check.problems(fig) == []
    if part != "quality":
        backends = {r.backend for r in recs if (r.tags or {}).get("sweep") == "horizon" and r.device == "cuda"}
        titled = {ax.get_title() for ax in fig.axes if ax.get_visible()}
        assert titled == backends
    assert horizon_panels.LOOK[part]
    assert not plots.plot_horizon(recs, "cpu", tmp_path / "none.png", "projectile", part)
