"""Device copy in NumPy: ``np.copyto(out, x)`` into a preallocated output (the bandwidth roofline).

``np.copyto`` is the simplest copy NumPy expresses; it runs on one thread (a memcpy for
contiguous arrays of one dtype), so this is the single-core copy bandwidth NumPy reaches.
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
        self.x = np.ascontiguousarray(inputs["x"], S)
        self.out = np.empty(params.n, dtype=S)

    def run(self) -> None:
        np.copyto(self.out, self.x)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.copy()}

    def info(self) -> dict[str, Any]:
        return kernel_info(copy="np.copyto(out, x)")
