"""The sdf scenario's part in the measurement sweeps (``compare.sweep.points``)."""
from __future__ import annotations

from typing import Mapping

from compare.results.record import Record
from compare.sweep import converged
from compare.sweep.converged import SDF_EVAL, Cache, Converged, Param, Reference, ReferenceInfo
from compare.sweep.points import Knob, Outputs, Point, Sweeps


# Time-against-error sweep: resolutions r x r per (device, quick).
SDF_RES = {("cpu", False): (64, 128, 256, 512, 1024, 2048), ("cpu", True): (32, 64),
           ("cuda", False): (64, 128, 256, 512, 1024, 2048, 4096), ("cuda", True): (32, 64, 128)}


class SdfSweeps(Sweeps):
    error_metric = (f"max |bilinear(image) - f| over a {SDF_EVAL}x{SDF_EVAL} grid, "
                    "f the analytic field in float64")
    labels = {"error_axis": "max |bilinear(image) - field| (log)"}

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        if kind != "error":
            return []
        return [Point({"width": r, "height": r}, Knob("resolution", r)) for r in SDF_RES.get((device, quick), ())]

    def converged_error(self, params: Mapping[str, Param], outputs: Outputs | None, record: Record,
                        cache: Cache, reference: Reference | None = None) -> Converged | None:
        if outputs is None:
            return None
        return Converged.measured(converged.reconstruction_error(outputs["image"], cache), self.error_metric,
                            ReferenceInfo("analytic field, float64", eval_grid=SDF_EVAL))


SWEEPS = SdfSweeps()
