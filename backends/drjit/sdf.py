"""Procedural SDF image in Dr.Jit: one array expression over the h*w pixels, evaluated once.

Pixel p of the row-major image is (row j, column i) = divmod(p, width), computed from
``dr.arange`` in the kernel. The divisors width-1 and height-1 are opaque run-time values: Dr.Jit
would turn a division by a Python scalar into a multiplication by its reciprocal, which rounds
differently from the scenario's i/(width-1). The other literals are the scenario's, rounded to the
cell's precision; Dr.Jit folds literals only with literals, so (2q - 1) + 0.35 stays as written.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import download, fast_math, jit_module, real_type, scalar
from ..base import ScenarioKernel
from scenarios.sdf import SdfParams
from ..base import Device
from scenarios.base import Precision


def image(cls: Any, uint: Any, width: int, height: int, wm1: Any, hm1: Any) -> Any:
    """exp(-18 |d|) for every pixel, in the scenario's operation order."""
    import drjit as dr
    p = dr.arange(uint, width * height)
    j = p // width
    i = p - j * width
    fx = 2.0 * (cls(i) / wm1) - 1.0
    fy = 2.0 * (cls(j) / hm1) - 1.0
    ax = fx + 0.35
    r1 = dr.sqrt(ax * ax + fy * fy) - 0.28
    bx = fx - 0.25
    by = fy - 0.15
    r2 = dr.sqrt(bx * bx + by * by) - 0.18
    wave = fy + 0.25 * dr.sin(8.0 * fx)
    d = dr.maximum(dr.minimum(r1, r2), -wave)
    return dr.exp(-18.0 * dr.abs(d))


class Kernel(ScenarioKernel):
    def __init__(self, params: SdfParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        self.cls, self.uint = real_type(device, precision), jit_module(device).UInt32
        self.dtype, self.w, self.h = np.dtype(precision), params.width, params.height
        self.wm1, self.hm1 = scalar(self.w - 1, self.cls), scalar(self.h - 1, self.cls)
        self.image: Any = None

    def run(self) -> Any:
        import drjit as dr
        self.image = image(self.cls, self.uint, self.w, self.h, self.wm1, self.hm1)
        dr.eval(self.image)
        return self.image

    def outputs(self) -> dict[str, np.ndarray]:
        return {"image": download(self.image, self.dtype, (self.h, self.w))}

    def info(self) -> dict[str, Any]:
        return {"kernel": "one dr.eval over width*height pixels", **fast_math()}
