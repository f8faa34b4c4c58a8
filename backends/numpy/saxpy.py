"""SAXPY in NumPy: out = a*x + y as two in-place ufuncs into one preallocated output.

``a`` is a scalar of the cell's dtype, so the float32 cell multiplies in float32 (with a float64
``a`` NumPy would compute in float64 and ``out=`` would round the result back, hiding it). Two
passes over memory (multiply, then add) where a fused kernel makes one: that is NumPy's cost.
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
        self.a = S(inputs["a"])
        self.x = np.ascontiguousarray(inputs["x"], S)
        self.y = np.ascontiguousarray(inputs["y"], S)
        self.out = np.empty(params.n, dtype=S)

    def run(self) -> None:
        np.multiply(self.x, self.a, out=self.out)      # a*x, rounded
        np.add(self.out, self.y, out=self.out)         # + y, rounded: Warp's order, no FMA

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.copy()}

    def info(self) -> dict[str, Any]:
        return kernel_info(passes=2)
