"""The saxpy scenario's part in the measurement sweeps (``compare.sweep.points``)."""
from __future__ import annotations

from typing import Mapping

import scenarios
from compare.results.record import Record
from compare.sweep.converged import Cache, Converged, Param, Reference, ReferenceInfo
from compare.sweep.points import CHECK_SAMPLE, Knob, Outputs, Point, Sweeps


# Bandwidth-sweep sizes per (device, quick), exponents of 2: CPU sizes stop where a cell still
# takes seconds on a small machine, GPU sizes where the arrays are ~1 GiB. --quick on a CPU: the
# two ends (a curve of two points; the fast test tier runs it).
SAXPY_EXP = {("cpu", False): range(10, 25, 2), ("cpu", True): (10, 20),
             ("cuda", False): range(10, 29, 2), ("cuda", True): range(10, 23, 2)}


class SaxpySweeps(Sweeps):
    measures = "bandwidth"          # the size sweep (achieved bandwidth against size)
    large = {"cuda": (26, 28), "cpu": (24, 26)}
    large_quick = (16, 18)
    large_variants = ("default", "graph", "vector", "tile")
    error_metric = "scenario metric against the float64 oracle: max |err|/(|a x|+|y|)"
    labels = {"name": "SAXPY", "bytes": "3·n·itemsize",
              "error_axis": "max |err|/(|a x|+|y|) vs float64 oracle (0 drawn at {floor:g})"}

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        if kind == "bandwidth":
            return [Point({"n": 1 << e}, Knob("n", 1 << e), check_sample=CHECK_SAMPLE, save_outputs=False)
                    for e in SAXPY_EXP.get((device, quick), ())]
        if kind == "error":        # knobs: precision and variant only
            return [Point({"n": scenarios.get(self.scenario).params(quick=quick).n}, Knob("precision"))]
        return []

    def converged_error(self, params: Mapping[str, Param], outputs: Outputs | None, record: Record,
                        cache: Cache, reference: Reference | None = None) -> Converged | None:
        """The oracle's error is already converged: float64 of the same rounded inputs (None
        without the record's check)."""
        if record.error is None:
            return None
        return Converged(record.error.vs_oracle, self.error_metric,
                         ReferenceInfo("float64 oracle of the same rounded inputs"))


SWEEPS = SaxpySweeps()
