"""Trivial launch in MLX: one compiled x + 1 over n (default 1) elements, started by async_eval.

The figure is what one call of a compiled MLX function costs: the call builds its graph node,
``mx.async_eval`` schedules it on the stream, ``synchronize`` waits for it.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import Program, download, kernel_info, launch, put
from ..base import ScenarioKernel
from scenarios.launch import LaunchParams
from ..base import Device
from scenarios.base import Precision


def _plus_one(x: Any) -> Any:
    return x + 1.0                   # a Python scalar takes the array's dtype


class Kernel(ScenarioKernel):
    def __init__(self, params: LaunchParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        self.device, self.precision = device, precision
        self.x = put(inputs["x"], precision)
        self.program = Program(_plus_one)
        self.out: Any = None

    def run(self) -> Any:
        self.out = launch(self.program(self.x))
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out, self.precision)}

    def info(self) -> dict[str, Any]:
        return kernel_info(self.device, self.precision, self.program)
