"""compare/sweep/plots.py: the sweep's plots (moved here in part from tests/suites/test_sweep.py).
Named test_sweep_plots: pytest collects test files by basename, and compare/stress/ has a plots
module too."""
from __future__ import annotations

import backends
from compare.results.record import Record
from compare.sweep import plots as sweep_plots


def test_plot_colours_belong_to_the_backend():
    recs = [Record(scenario="saxpy", backend=b, device="cpu", precision="float32", status="ok")
            for b in ("numba", "warp", "elsewhere")]
    c = sweep_plots.colors(recs)
    assert c["numba"] == backends.get("numba").color and c["warp"] == backends.get("warp").color
    assert list(c)[:2] == ["warp", "numba"] and c["elsewhere"] not in (c["warp"], c["numba"])
