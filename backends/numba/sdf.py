"""Procedural SDF image in Numba: one prange row per CPU task, one CUDA thread per pixel.

The per-pixel function is written once and compiled for both targets (``njit`` and a CUDA device
function), in Warp's operation order; image[j, i] with i the column, so adjacent threads of a
CUDA block (x fastest) write adjacent pixels.
"""
from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from numba import njit, prange
try:
    from numba import cuda   # numba-cuda; a module global, which the CUDA simulator swaps in kernels
except ImportError:          # CPU-only install
    cuda = None

from . import kernel_info, launch_stream, scalar_type, use_fastmath
from ..base import ScenarioKernel

BLOCK = (32, 8)          # 256 threads: a warp along a row, 8 rows


@functools.cache
def pixel_function(S: type[np.floating]):
    """v(i, j) in the scalar type S: every constant is S(...), so float32 stays float32."""
    def pixel(i, j, width, height):
        one = S(1.0)
        two = S(2.0)
        fx = two * (S(i) / S(width - 1)) - one
        fy = two * (S(j) / S(height - 1)) - one
        ax = fx + S(0.35)
        r1 = math.sqrt(ax * ax + fy * fy) - S(0.28)
        bx = fx - S(0.25)
        by = fy - S(0.15)
        r2 = math.sqrt(bx * bx + by * by) - S(0.18)
        wave = fy + S(0.25) * math.sin(S(8.0) * fx)
        d = max(min(r1, r2), -wave)
        return math.exp(S(-18.0) * abs(d))
    return pixel


@functools.cache
def cpu_kernel(S: type[np.floating], fastmath: bool):
    pixel = njit(fastmath=fastmath)(pixel_function(S))

    @njit(parallel=True, fastmath=fastmath)
    def sdf(image):
        height, width = image.shape
        for j in prange(height):
            for i in range(width):
                image[j, i] = pixel(i, j, width, height)
    return sdf


@functools.cache
def cuda_kernel(S: type[np.floating], fastmath: bool):
    pixel = cuda.jit(device=True, fastmath=fastmath)(pixel_function(S))

    @cuda.jit(fastmath=fastmath)
    def sdf(image):
        i, j = cuda.grid(2)
        height, width = image.shape
        if i < width and j < height:
            image[j, i] = pixel(i, j, width, height)
    return sdf


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.device, self.fastmath = device, use_fastmath(variant)
        shape = (params.height, params.width)
        if device == "cuda":
            self.image = cuda.device_array(shape, dtype=S)
            grid = (-(-params.width // BLOCK[0]), -(-params.height // BLOCK[1]))
            self.fn = cuda_kernel(S, self.fastmath)[grid, BLOCK, launch_stream()]
        else:
            self.image = np.empty(shape, dtype=S)
            self.fn = cpu_kernel(S, self.fastmath)

    def run(self) -> None:
        self.fn(self.image)

    def outputs(self) -> dict[str, np.ndarray]:
        image = self.image.copy_to_host() if self.device == "cuda" else self.image.copy()
        return {"image": image}

    def info(self) -> dict[str, Any]:
        extra = {"block": list(BLOCK)} if self.device == "cuda" else {}
        return kernel_info(self.device, self.fastmath, **extra)
