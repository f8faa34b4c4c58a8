"""Procedural SDF image in MLX: one compiled expression over the (height, width) grid.

fx depends on the column only and fy on the row only, so both are vectors broadcast against
each other (the same values a per-pixel kernel computes); mx.compile fuses the image expression
into elementwise kernels. The pixel indices and width-1, height-1 are inputs (arrays of the
cell's dtype), the scenario's literals Python scalars, which take the array's dtype. MLX does not
reassociate or fold them: the generated C++ keeps the scenario's operation order.
float64 cells evaluate exp and sin through ``backends.mlx.exp``/``sin`` (MLX's own round through
float32 on the CPU: docs/findings.md).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import Program, download, exp, kernel_info, launch, put, sin
from ..base import ScenarioKernel
from scenarios.sdf import SdfParams
from ..base import Device
from scenarios.base import Precision


def _sdf(i: Any, j: Any, wm1: Any, hm1: Any) -> Any:
    """image[j, i] for row j, column i, in the scenario's operation order."""
    import mlx.core as mx
    fx = (2.0 * (i / wm1) - 1.0)[None, :]
    fy = (2.0 * (j / hm1) - 1.0)[:, None]
    ax = fx + 0.35
    r1 = mx.sqrt(ax * ax + fy * fy) - 0.28
    bx = fx - 0.25
    by = fy - 0.15
    r2 = mx.sqrt(bx * bx + by * by) - 0.18
    wave = fy + 0.25 * sin(8.0 * fx)
    d = mx.maximum(mx.minimum(r1, r2), -wave)
    return exp(-18.0 * mx.abs(d))


class Kernel(ScenarioKernel):
    def __init__(self, params: SdfParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        self.device, self.precision = device, precision
        self.i = put(np.arange(params.width), precision)       # exact: width, height <= 65536
        self.j = put(np.arange(params.height), precision)
        self.wm1 = put(params.width - 1, precision)
        self.hm1 = put(params.height - 1, precision)
        self.program = Program(_sdf)
        self.image: Any = None

    def run(self) -> Any:
        self.image = launch(self.program(self.i, self.j, self.wm1, self.hm1))
        return self.image

    def outputs(self) -> dict[str, np.ndarray]:
        return {"image": download(self.image, self.precision)}

    def info(self) -> dict[str, Any]:
        return kernel_info(self.device, self.precision, self.program)
