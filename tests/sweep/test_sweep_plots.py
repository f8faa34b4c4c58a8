"""compare/sweep/plots.py: the sweep's plots (moved here in part from tests/suites/test_sweep.py).
Named test_sweep_plots: pytest collects test files by basename, and compare/stress/ has a plots
module too."""
from __future__ import annotations

from pathlib import Path

import pytest

import backends
from compare.results.record import Record
from compare.results.store import Store
from compare.sweep import plots as sweep_plots

ROOT = Path(__file__).resolve().parents[2]
SITE = ROOT / "tests" / "data" / "site" / "sweep.json"     # CUDA: scaling, horizon and error points
CPU = ROOT / "docs" / "results" / "cpu" / "sweep.json"      # the bandwidth sweep with its yardsticks


def test_plot_colours_belong_to_the_backend():
    recs = [Record(scenario="saxpy", backend=b, device="cpu", precision="float32", status="ok")
            for b in ("numba", "warp", "elsewhere")]
    c = sweep_plots.colors(recs)
    assert c["numba"] == backends.get("numba").color and c["warp"] == backends.get("warp").color
    assert list(c)[:2] == ["warp", "numba"] and c["elsewhere"] not in (c["warp"], c["numba"])


# ---- the plots, from stored sweeps --------------------------------------------------------------
@pytest.fixture(autouse=True)
def closed():
    import matplotlib.pyplot as plt
    yield
    plt.close("all")


def test_the_bandwidth_plot_of_a_stored_sweep(tmp_path):
    recs = [r for r in Store.read(CPU, "sweep").records if (r.tags or {}).get("sweep") == "bandwidth"]
    assert sweep_plots.plot_bandwidth(recs, "cpu", tmp_path / "bw.png", "saxpy")
    assert (tmp_path / "bw.png").read_bytes().startswith(b"\x89PNG")
    assert not sweep_plots.plot_bandwidth(recs, "cuda", tmp_path / "none.png", "saxpy")
    assert not (tmp_path / "none.png").exists()


@pytest.mark.slow                       # three figures rendered: seconds
def test_write_plots_draws_what_the_records_allow_per_device(tmp_path):
    recs = list(Store.read(SITE, "sweep").records)
    written = sweep_plots.write_plots(recs, tmp_path)
    assert set(written) == {"time_vs_error-cuda", "scaling-cuda", "horizon-cuda"}
    for key, path in written.items():
        assert path == tmp_path / f"{key.replace('-', '_')}.png" and path.read_bytes().startswith(b"\x89PNG")
    assert sweep_plots.write_plots([], tmp_path / "empty") == {}
