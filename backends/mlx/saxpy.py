"""SAXPY in MLX: one compiled expression a*x + y, fused by mx.compile into one elementwise kernel.

``a`` is a 0-d array of the cell's dtype, an input of the compiled function (not a traced
constant, which would compile one kernel per value). The product and the sum round separately
(g++ contracts nothing into an FMA on x86-64 without -mfma); each call's output buffer comes from
MLX's buffer cache, so a steady-state call allocates nothing new from the system.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import Program, download, kernel_info, launch, put
from ..base import ScenarioKernel
from scenarios.saxpy import SaxpyParams
from ..base import Device
from scenarios.base import Precision


def _saxpy(a: Any, x: Any, y: Any) -> Any:
    return a * x + y


class Kernel(ScenarioKernel):
    def __init__(self, params: SaxpyParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        self.device, self.precision = device, precision
        self.a, self.x, self.y = (put(inputs[k], precision) for k in ("a", "x", "y"))
        self.program = Program(_saxpy)
        self.out: Any = None

    def run(self) -> Any:
        self.out = launch(self.program(self.a, self.x, self.y))
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out, self.precision)}

    def info(self) -> dict[str, Any]:
        return kernel_info(self.device, self.precision, self.program, expression="a * x + y")
