"""Device copy in CuPy: a ``cupy.ElementwiseKernel`` ``out = x``, one thread per element.

A kernel rather than ``cupy.copyto`` (a cudaMemcpy) so the copy is the same kind of code as the
scenarios' kernels: the bandwidth a bandwidth-bound CuPy kernel reaches.
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
    return cupy.ElementwiseKernel(f"{precision} x", f"{precision} out", "out = x",
                                  name=f"copy_{precision}")


class Kernel(ScenarioKernel):
    """One elementwise kernel from x into a preallocated out (launch.py reuses it with its own)."""
    make = staticmethod(elementwise)

    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        import cupy
        S = scalar_type(precision)
        self.fn = self.make(precision)
        self.x = upload(inputs["x"], S)
        self.out = cupy.empty(params.n, dtype=S)

    def run(self) -> None:
        self.fn(self.x, self.out)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.get()}

    def info(self) -> dict[str, Any]:
        return kernel_info(kernel="cupy.ElementwiseKernel", copy="kernel out[i] = x[i]")
