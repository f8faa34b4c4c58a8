"""SAXPY in Numba: a prange loop on the CPU, one thread per element on CUDA.

No constants, so one dispatcher per fastmath setting; Numba specialises it per dtype (``a`` is a
typed NumPy scalar, so the float32 specialisation is all float32).
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numba import njit, prange
try:
    from numba import cuda   # numba-cuda; a module global, which the CUDA simulator swaps in kernels
except ImportError:          # CPU-only install
    cuda = None

from . import THREADS_PER_BLOCK, blocks, kernel_info, launch_stream, scalar_type, use_fastmath
from ..base import ScenarioKernel


@functools.cache
def cpu_kernel(fastmath: bool):
    @njit(parallel=True, fastmath=fastmath)
    def saxpy(a, x, y, out):
        for i in prange(out.shape[0]):
            out[i] = a * x[i] + y[i]
    return saxpy


@functools.cache
def cuda_kernel(fastmath: bool):
    @cuda.jit(fastmath=fastmath)
    def saxpy(a, x, y, out):
        i = cuda.grid(1)
        if i < out.shape[0]:
            out[i] = a * x[i] + y[i]
    return saxpy


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.device, self.fastmath = device, use_fastmath(variant)
        self.a = S(inputs["a"])               # a typed scalar: a Python float would type as float64
        if device == "cuda":
            self.x, self.y = cuda.to_device(inputs["x"]), cuda.to_device(inputs["y"])
            self.out = cuda.device_array(params.n, dtype=S)
            self.fn = cuda_kernel(self.fastmath)[blocks(params.n), THREADS_PER_BLOCK, launch_stream()]
        else:
            self.x, self.y = np.ascontiguousarray(inputs["x"]), np.ascontiguousarray(inputs["y"])
            self.out = np.empty(params.n, dtype=S)
            self.fn = cpu_kernel(self.fastmath)

    def run(self) -> None:
        self.fn(self.a, self.x, self.y, self.out)

    def outputs(self) -> dict[str, np.ndarray]:
        out = self.out.copy_to_host() if self.device == "cuda" else self.out.copy()
        return {"out": out}

    def info(self) -> dict[str, Any]:
        return kernel_info(self.device, self.fastmath)

