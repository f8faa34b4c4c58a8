"""Trivial launch in Numba: out[i] = x[i] + 1 over n (default 1) elements.

CPU: ``@njit(parallel=True)`` like every other CPU kernel here, so the figure includes what a
parallel region costs to start; CUDA: one block. The copy's ``Kernel`` (copy.py: the same arrays,
launch configuration and download) with these kernels, which take the typed 1 as an argument.
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

from . import kernel_info, scalar_type
from .copy import Kernel as CopyKernel


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


class Kernel(CopyKernel):
    cpu_make, cuda_make = staticmethod(cpu_kernel), staticmethod(cuda_kernel)

    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        super().__init__(params, inputs, device, precision, variant)
        self.one = scalar_type(precision)(1)   # typed: a Python 1.0 would promote float32 to float64

    def run(self) -> None:
        self.fn(self.x, self.one, self.out)

    def info(self) -> dict[str, Any]:
        return kernel_info(self.device, self.fastmath)
