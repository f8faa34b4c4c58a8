"""The sdf scenario's part in the measurement sweeps (``compare.sweep.points``)."""
from __future__ import annotations

from typing import Any

import numpy as np

from compare.sweep import converged
from compare.sweep.converged import SDF_EVAL
from compare.sweep.points import Point, Sweeps


# Time-against-error sweep: resolutions r x r per (device, quick).
SDF_RES = {("cpu", False): (64, 128, 256, 512, 1024, 2048), ("cpu", True): (32, 64, 128),
           ("cuda", False): (64, 128, 256, 512, 1024, 2048, 4096), ("cuda", True): (32, 64, 128)}


class SdfSweeps(Sweeps):
    error_metric = (f"max |bilinear(image) - f| over a {SDF_EVAL}x{SDF_EVAL} grid, "
                    "f the analytic field in float64")
    labels = {"error_axis": "max |bilinear(image) - field| (log)"}

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        if kind != "error":
            return []
        return [{"params": {"width": r, "height": r}, "knob": {"name": "resolution", "value": r}}
                for r in SDF_RES.get((device, quick), ())]

    def converged_error(self, params: dict[str, Any], outputs: dict[str, np.ndarray] | None,
                        record: dict[str, Any], cache: dict[Any, Any],
                        reference: dict[str, Any] | None = None) -> dict[str, Any] | None:
        if outputs is None:
            return None
        return {**converged.reconstruction_error(outputs["image"], cache), "metric": self.error_metric,
                "reference": {"eval_grid": SDF_EVAL, "note": "analytic field, float64"}}


SWEEPS = SdfSweeps()
