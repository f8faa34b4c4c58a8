"""Procedural SDF image in Triton: one program per BLOCK_H x BLOCK_W tile of pixels.

Each program builds its tile's column coordinates fx (1, BLOCK_W) and row coordinates fy
(BLOCK_H, 1) and broadcasts the pixel function over the tile, in the scenario's (and Warp's)
operation order: libdevice's IEEE division, square root, sin and exp (fmath.py), min/max as
Warp's wp.min/wp.max. image[j, i] with i the column: the tile's rows are contiguous, so its stores
coalesce along BLOCK_W; the row offset is int64 (up to 65536^2 pixels).

Tile shape and warps: ``triton.autotune`` over CONFIGS keyed on (width, height); the first call
compiles and times each (first-call time), ``info()`` reports the choice. Under the interpreter
the first config runs.
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np
import triton
import triton.language as tl

from . import download, empty, interpreting, kernel_info, launch_options, tuned
from ..base import ScenarioKernel
from .fmath import div, exp, sin, sqrt
from scenarios.sdf import SdfParams
from ..base import Device
from scenarios.base import Precision

# (BLOCK_H, BLOCK_W, num_warps): 1024 or 2048 pixels a program, rows of 64 to 256 pixels
CONFIGS = ((8, 128, 4), (4, 256, 4), (16, 64, 4), (16, 128, 8))


@triton.jit
def sdf_kernel(image_ptr, width, height, BLOCK_H: tl.constexpr, BLOCK_W: tl.constexpr):
    T = image_ptr.dtype.element_ty
    i = tl.program_id(0) * BLOCK_W + tl.arange(0, BLOCK_W)[None, :]
    j = tl.program_id(1) * BLOCK_H + tl.arange(0, BLOCK_H)[:, None]
    fx = 2.0 * div(i.to(T), (width - 1).to(T)) - 1.0
    fy = 2.0 * div(j.to(T), (height - 1).to(T)) - 1.0
    ax = fx + 0.35
    r1 = sqrt(ax * ax + fy * fy) - 0.28
    bx = fx - 0.25
    by = fy - 0.15
    r2 = sqrt(bx * bx + by * by) - 0.18
    wave = fy + 0.25 * sin(8.0 * fx)
    d = tl.maximum(tl.minimum(r1, r2), -wave)
    v = exp(-18.0 * tl.abs(d))
    mask = (i < width) & (j < height)
    tl.store(image_ptr + j.to(tl.int64) * width + i, v, mask=mask)


@functools.cache
def autotuned() -> Any:
    if interpreting():
        return sdf_kernel
    configs = [triton.Config({"BLOCK_H": h, "BLOCK_W": w}, num_warps=nw) for h, w, nw in CONFIGS]
    return triton.autotune(configs=configs, key=["width", "height"])(sdf_kernel)


class Kernel(ScenarioKernel):
    def __init__(self, params: SdfParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        w, h = params.width, params.height
        self.image = empty((h, w), precision, device)
        self.fn = autotuned()
        if interpreting():
            bh, bw, _ = CONFIGS[0]
            grid: Any = (triton.cdiv(w, bw), triton.cdiv(h, bh))
            self.meta = {"BLOCK_H": bh, "BLOCK_W": bw}
        else:
            def grid(meta: dict) -> tuple[int, int]:
                return (triton.cdiv(w, meta["BLOCK_W"]), triton.cdiv(h, meta["BLOCK_H"]))
            self.meta = launch_options()
        self.grid, self.args = grid, (self.image, w, h)

    def run(self) -> Any:
        self.fn[self.grid](*self.args, **self.meta)
        return self.image

    def outputs(self) -> dict[str, np.ndarray]:
        return {"image": download(self.image)}

    def info(self) -> dict[str, Any]:
        return kernel_info(configs=[list(c) for c in CONFIGS], **tuned(self.fn))
