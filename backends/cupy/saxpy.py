"""SAXPY in CuPy: a ``cupy.ElementwiseKernel`` ``out = a * x + y``, one thread per element.

Typed in the cell's precision (``float32 a, float32 x, ...``), so the float32 kernel is all float32;
``a * x + y`` contracts to one FMA under NVRTC's default, as in Warp and Numba.
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np

from . import kernel_info, scalar_type, upload
from ..base import ScenarioKernel


@functools.cache
def elementwise(precision: str) -> Any:
    import cupy
    t = precision
    return cupy.ElementwiseKernel(f"{t} a, {t} x, {t} y", f"{t} out", "out = a * x + y",
                                  name=f"saxpy_{t}")


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        import cupy
        S = scalar_type(precision)
        self.fn = elementwise(precision)
        self.a = S(inputs["a"])               # a typed scalar: a Python float is a double
        self.x, self.y = upload(inputs["x"], S), upload(inputs["y"], S)
        self.out = cupy.empty(params.n, dtype=S)

    def run(self) -> None:
        self.fn(self.a, self.x, self.y, self.out)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.get()}

    def info(self) -> dict[str, Any]:
        return kernel_info(kernel="cupy.ElementwiseKernel")
