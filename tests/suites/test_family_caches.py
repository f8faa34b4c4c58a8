"""compare/suites/family_caches.py: a sweep's points of one curve share their kernel caches (the
first cold, the later ones kept), never two at the same time, and never the bandwidth sweep's."""
from __future__ import annotations

import json
from collections import Counter
from pathlib import Path

import pytest

from compare.running import engine
from compare.spec import Cell
from compare.suites import family_caches, sweep
from conftest import require_device
from reliability_checks import run_main


def cell(backend: str = "numpy", n: int = 256, **kw: object) -> Cell:
    return Cell.make("particles", backend, "cpu", "float32", params={"n": n}, **kw)


def test_a_family_of_two_or_more_shares_one_directory(tmp_path: Path) -> None:
    cells = [cell(n=256), cell(n=4096), cell("numba", n=256), cell(n=65536, cache="warm"),
             cell(n=2**20, cache_dir=str(tmp_path / "own"))]
    got = family_caches.share(cells, tmp_path, lambda c: True)
    assert got[0].cache_dir and got[0].cache_dir == got[1].cache_dir        # one curve: one directory
    assert Path(got[0].cache_dir).parent == tmp_path
    assert not got[2].cache_dir                          # alone in its family: nothing to share
    assert not got[3].cache_dir                          # warm: the framework's own caches
    assert got[4].cache_dir == str(tmp_path / "own")     # a directory of its own stays
    assert family_caches.share(cells, tmp_path, lambda c: False) == cells
    assert family_caches.family(cells[0]) == family_caches.family(cells[1]) != family_caches.family(cells[2])


def test_cells_of_one_directory_never_overlap_on_the_cpu(tmp_path: Path) -> None:
    shared = family_caches.share([cell(n=256), cell(n=4096)], tmp_path, lambda c: True)
    assert engine.cell_lane(shared[0]) == engine.cell_lane(shared[1]) is not None
    assert engine.cell_lane(cell()) is None                       # a CPU cell of its own: no constraint
    gpu = Cell.make("particles", "numpy", "cuda", "float32")
    assert engine.cell_lane(gpu) == engine.gpu_lane(gpu) is not None


def test_the_sweeps_share_but_the_bandwidth_sweep(tmp_path: Path) -> None:
    suite = sweep.SweepSuite()
    assert not suite.shares_caches(cell(tags={"sweep": "bandwidth"}))
    assert all(suite.shares_caches(cell(tags={"sweep": k})) for k in ("scaling", "error", "horizon"))


@pytest.mark.cli
@pytest.mark.parametrize("kind", ["scaling", "bandwidth"])
def test_a_sweeps_later_points_start_from_the_first_ones_caches(kind: str, tmp_path: Path) -> None:
    """Each family's first point to run is cold, every later one kept; the bandwidth sweep's (its
    launch table shows the first call) all cold."""
    require_device("numpy", "cpu")
    rc, lines = run_main(["sweep", kind, "--quick", "--backends", "numpy", "--devices", "cpu", "--precision",
                          "float32", "--min-time", "0", "--out", str(tmp_path), "--no-plots"])
    assert rc == 0, lines
    recs = [r for r in json.loads((tmp_path / "sweep.json").read_text())["records"] if r["status"] == "ok"]
    states = Counter((r["scenario"], r["variant"], r["time"]["cache"].split(":")[0]) for r in recs)
    if kind == "bandwidth":
        assert {s for _, _, s in states} == {"cold"}
        return
    curves = {(s, v) for s, v, _ in states}
    assert curves and all(states[(s, v, "cold")] == 1 for s, v in curves), states
    assert all(states[(s, v, "kept")] >= 1 for s, v in curves), states
