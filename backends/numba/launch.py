"""Trivial launch in Numba: out[i] = x[i] + 1 over n (default 1) elements.

CPU: ``@njit(parallel=True)`` like every other CPU kernel here, so the figure includes what a
parallel region costs to start; CUDA: one block.
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
    def plus_one(x, one, out):
        for i in prange(out.shape[0]):
            out[i] = x[i] + one
    return plus_one


@functools.cache
def cuda_kernel(fastmath: bool):
    @cuda.jit(fastmath=fastmath)
    def plus_one(x, one, out):
        i = cuda.grid(1)
        if i < out.shape[0]:
            out[i] = x[i] + one
    return plus_one


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.device, self.fastmath = device, use_fastmath(variant)
        self.one = S(1)                      # typed: a Python 1.0 would promote float32 to float64
        if device == "cuda":
            self.x = cuda.to_device(inputs["x"])
            self.out = cuda.device_array(params.n, dtype=S)
            self.fn = cuda_kernel(self.fastmath)[blocks(params.n), THREADS_PER_BLOCK, launch_stream()]
        else:
            self.x = np.ascontiguousarray(inputs["x"])
            self.out = np.empty(params.n, dtype=S)
            self.fn = cpu_kernel(self.fastmath)

    def run(self) -> None:
        self.fn(self.x, self.one, self.out)

    def outputs(self) -> dict[str, np.ndarray]:
        out = self.out.copy_to_host() if self.device == "cuda" else self.out.copy()
        return {"out": out}

    def info(self) -> dict[str, Any]:
        return kernel_info(self.device, self.fastmath)
