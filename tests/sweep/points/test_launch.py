"""compare/sweep/points/launch.py: the trivial-launch yardstick, one element (fast tier)."""
from __future__ import annotations

from compare.sweep.points import Point, sweeps
from compare.sweep.points.launch import SWEEPS


def test_one_point_of_one_element_in_the_bandwidth_sweep_only():
    assert sweeps("launch") is SWEEPS and SWEEPS.measures == "launch"
    for device in ("cpu", "cuda"):
        for quick in (False, True):
            assert SWEEPS.points("bandwidth", device, quick) == [Point({"n": 1})]
            assert all(SWEEPS.points(k, device, quick) == [] for k in ("error", "scaling", "horizon"))
