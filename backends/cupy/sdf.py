"""Procedural SDF image in CuPy: a ``cupy.RawKernel``, one thread per pixel on a 2-D grid.

The pixel function in Warp's operation order (fminf/fmaxf as Warp's wp.min/wp.max lower to), in
the cell's precision; image[j, i] with i the column, so adjacent threads of a block (x fastest)
write adjacent pixels.
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np

from . import empty, kernel_info, prelude, raw_kernel, scalar_type
from ..base import ScenarioKernel

BLOCK = (32, 8)          # 256 threads: a warp along a row, 8 rows

BODY = r"""
extern "C" __global__ void sdf(const int width, const int height, real* __restrict__ image)
{
    const int i = blockIdx.x * blockDim.x + threadIdx.x;
    const int j = blockIdx.y * blockDim.y + threadIdx.y;
    if (i >= width || j >= height) return;
    const real one = R(1.0);
    const real two = R(2.0);
    const real fx = two * ((real)i / (real)(width - 1)) - one;
    const real fy = two * ((real)j / (real)(height - 1)) - one;
    const real ax = fx + R(0.35);
    const real r1 = SQRT(ax * ax + fy * fy) - R(0.28);
    const real bx = fx - R(0.25);
    const real by = fy - R(0.15);
    const real r2 = SQRT(bx * bx + by * by) - R(0.18);
    const real wave = fy + R(0.25) * SIN(R(8.0) * fx);
    const real d = FMAX(FMIN(r1, r2), -wave);
    image[(long long)j * width + i] = EXP(R(-18.0) * FABS(d));
}
"""


def source(precision: str) -> str:
    return prelude(precision) + BODY


@functools.cache
def compiled(precision: str) -> Any:
    return raw_kernel(source(precision), "sdf")


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.fn = compiled(precision)
        self.image = empty((params.height, params.width), S)
        self.grid = (-(-params.width // BLOCK[0]), -(-params.height // BLOCK[1]))
        self.args = (np.int32(params.width), np.int32(params.height), self.image)

    def run(self) -> None:
        self.fn(self.grid, BLOCK, self.args)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"image": self.image.get()}

    def info(self) -> dict[str, Any]:
        return kernel_info(kernel="cupy.RawKernel", block=list(BLOCK), grid=list(self.grid))
