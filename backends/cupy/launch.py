"""Trivial launch in CuPy: a ``cupy.ElementwiseKernel`` ``out = x + 1`` over n (default 1) elements.

What one CuPy kernel call costs: the ElementwiseKernel's per-call argument handling plus the
launch (the graph regime shows the launch alone).
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np

from . import ctype, kernel_info, scalar_type, upload
from ..base import ScenarioKernel


@functools.cache
def elementwise(precision: str) -> Any:
    import cupy
    return cupy.ElementwiseKernel(f"{precision} x", f"{precision} out",
                                  f"out = x + ({ctype(precision)})1.0", name=f"plus_one_{precision}")


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        import cupy
        S = scalar_type(precision)
        self.fn = elementwise(precision)
        self.x = upload(inputs["x"], S)
        self.out = cupy.empty(params.n, dtype=S)

    def run(self) -> None:
        self.fn(self.x, self.out)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.get()}

    def info(self) -> dict[str, Any]:
        return kernel_info(kernel="cupy.ElementwiseKernel")
