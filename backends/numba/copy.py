"""Device copy in Numba: a prange loop on the CPU, one thread per element on CUDA, out[i] = x[i].

A kernel rather than ``np.copyto`` / ``copy_to_device`` so the copy is the same kind of code as
the scenarios' kernels (and parallel on the CPU, where np.copyto is one thread).
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
    def copy(x, out):
        for i in prange(out.shape[0]):
            out[i] = x[i]
    return copy


@functools.cache
def cuda_kernel(fastmath: bool):
    @cuda.jit(fastmath=fastmath)
    def copy(x, out):
        i = cuda.grid(1)
        if i < out.shape[0]:
            out[i] = x[i]
    return copy


class Kernel(ScenarioKernel):
    """One kernel from x into a preallocated out (launch.py reuses it with its own)."""
    cpu_make, cuda_make = staticmethod(cpu_kernel), staticmethod(cuda_kernel)

    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.device, self.fastmath = device, use_fastmath(variant)
        if device == "cuda":
            self.x = cuda.to_device(inputs["x"])
            self.out = cuda.device_array(params.n, dtype=S)
            self.fn = self.cuda_make(self.fastmath)[blocks(params.n), THREADS_PER_BLOCK, launch_stream()]
        else:
            self.x = np.ascontiguousarray(inputs["x"])
            self.out = np.empty(params.n, dtype=S)
            self.fn = self.cpu_make(self.fastmath)

    def run(self) -> None:
        self.fn(self.x, self.out)

    def outputs(self) -> dict[str, np.ndarray]:
        out = self.out.copy_to_host() if self.device == "cuda" else self.out.copy()
        return {"out": out}

    def info(self) -> dict[str, Any]:
        return kernel_info(self.device, self.fastmath, copy="kernel out[i] = x[i]")
