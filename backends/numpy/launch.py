"""Trivial launch in NumPy: out = x + 1, one ufunc call into a preallocated output.

The figure is what one NumPy ufunc call costs (argument checks, type resolution, dispatch), the
NumPy counterpart of a kernel launch.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import kernel_info, scalar_type
from ..base import ScenarioKernel


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.one = S(1)                      # typed: keeps the float32 cell in float32
        self.x = np.ascontiguousarray(inputs["x"], S)
        self.out = np.empty(params.n, dtype=S)

    def run(self) -> None:
        np.add(self.x, self.one, out=self.out)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.copy()}

    def info(self) -> dict[str, Any]:
        return kernel_info()
