"""The launch scenario's part in the measurement sweeps (``compare.sweep.points``)."""
from __future__ import annotations

from compare.sweep.points import Point, Sweeps


class LaunchSweeps(Sweeps):
    measures = "launch"          # the trivial-launch overhead yardstick

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        return [Point({"n": 1})] if kind == "bandwidth" else []


SWEEPS = LaunchSweeps()
