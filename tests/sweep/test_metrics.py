"""compare/sweep/metrics.py: roofline and Pareto math on hand-made records (fast tier; moved here
from tests/suites/test_sweep.py)."""
from __future__ import annotations

import math

from compare.results.record import Record
from compare.sweep import metrics as sweep_metrics


def _rec(role, backend, n, median, nbytes, wall=None, timer="wall", device="cuda"):
    scenario = {"bandwidth": "saxpy"}.get(role, role)
    return Record(tags={"sweep": "bandwidth", "role": role, "knob": {"name": "n", "value": n}},
                  scenario=scenario, backend=backend,
                  device=device, precision="float32", status="ok", params={"n": n},
                  work={"bytes": nbytes},
                  time={"median_s": median, "timer": timer,
                        "wall": {"median_s": wall or median, "iqr_s": 0.0, "min_s": wall or median}})


def test_roofline_and_bandwidth_rows():
    recs = [_rec("copy", "a", 1 << 20, 1e-3, 2e9), _rec("copy", "b", 1 << 20, 2e-3, 2e9),
            _rec("launch", "a", 1, 1e-5, 8, wall=1e-5),
            _rec("bandwidth", "a", 1 << 10, 2e-6, 3e3, wall=1.2e-5, timer="events"),
            _rec("bandwidth", "a", 1 << 28, 2e-3, 3e9, wall=2.1e-3, timer="events")]
    roof = sweep_metrics.roofline(recs, "cuda")
    assert roof["backend"] == "a" and math.isclose(roof["gbps"], 2000.0)
    assert sweep_metrics.roofline(recs, "cpu") is None
    small = sweep_metrics.bandwidth_row(recs[3], recs)
    assert math.isclose(small["gbps"], 3e3 / 2e-6 / 1e9)              # primary clock (events)
    assert math.isclose(small["wall_gbps"], 3e3 / 1.2e-5 / 1e9)
    assert math.isclose(small["launch_share"], 1e-5 / 1.2e-5) and small["regime"] == "overhead-bound"
    big = sweep_metrics.bandwidth_row(recs[4], recs)
    assert math.isclose(big["roof_share"], 1500.0 / 2000.0) and big["regime"] == "bandwidth-bound"
    assert sweep_metrics.regime(0.1, 0.2) == "mixed" and sweep_metrics.regime(None, None) == "-"
    assert sweep_metrics.gbps(1e9, 0.5) == 2.0


def test_pareto_front():
    pts = [(1.0, 10.0), (2.0, 5.0), (3.0, 6.0), (4.0, 1.0), (2.0, 5.0), (0.5, 20.0), (5.0, 1.0)]
    assert sweep_metrics.pareto_front(pts) == [True, True, False, True, True, True, False]
    assert sweep_metrics.pareto_front([]) == []
    assert sweep_metrics.pareto_front([(1.0, 1.0)]) == [True]
