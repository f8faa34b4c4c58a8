"""Procedural SDF image in Quadrants: a struct-for over the (height, width) image, one pixel each.

The Taichi port's kernel with ``ti`` renamed ``qd``; nothing else differs. Storage: a field, as
there (measured on Taichi 1.7: a field no slower than an ndarray, identical images).
Literals are Quadrants default_fp, i.e. the cell's precision (set by qd.init).
"""
# (no "from __future__ import annotations": Quadrants (like Taichi) reads kernel annotations as objects)

from typing import Any

import numpy as np
import quadrants as qd

from . import config_info
from ..base import ScenarioKernel


@qd.kernel
def _sdf(width: qd.i32, height: qd.i32, image: qd.template()):
    for j, i in image:
        # Same operation order as the Warp kernel: convert both, divide, then scale and shift.
        fx = 2.0 * (qd.cast(i, float) / qd.cast(width - 1, float)) - 1.0
        fy = 2.0 * (qd.cast(j, float) / qd.cast(height - 1, float)) - 1.0
        ax = fx + 0.35
        r1 = qd.sqrt(ax * ax + fy * fy) - 0.28
        bx = fx - 0.25
        by = fy - 0.15
        r2 = qd.sqrt(bx * bx + by * by) - 0.18
        wave = fy + 0.25 * qd.sin(8.0 * fx)
        d = qd.max(qd.min(r1, r2), -wave)
        image[j, i] = qd.exp(-18.0 * qd.abs(d))


class Kernel(ScenarioKernel):
    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        self.w, self.h = params.width, params.height
        self.image = qd.field(float, shape=(self.h, self.w))

    def run(self) -> None:
        _sdf(self.w, self.h, self.image)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"image": self.image.to_numpy()}

    def info(self) -> dict[str, Any]:
        return {"storage": "field", **config_info()}
