"""Procedural SDF image in Taichi: a struct-for over the (height, width) image, one pixel each.

Storage: a field. Measured on a 2-core CPU (median of 100 run()+sync, ndarray vs field, same
kernel body): 203x97 f32 330 vs 260 us, f64 483-496 vs 455-495 us; 512x512 f32 4.0-8.1 vs
3.1-4.7 ms, f64 6.1 vs 5.5 ms. Identical images.
Literals are Taichi default_fp, i.e. the cell's precision (set by ti.init).

``build(ti)`` defines the kernel and ``Kernel`` for ``ti``, the ``taichi`` module here and the
``quadrants`` one in backends/quadrants/sdf.py (Taichi's fork, the same API).
"""
# (no "from __future__ import annotations": Taichi reads kernel annotations as objects)

import functools
from types import ModuleType
from typing import Any

import numpy as np

from . import built_on_first_use, framework_config_info
from ..base import ScenarioKernel
from scenarios.sdf import SdfParams
from ..base import Device
from scenarios.base import Precision


@functools.cache
def build(ti: ModuleType) -> tuple[Any, type[ScenarioKernel]]:
    """(the kernel, ``Kernel``) in ``ti``: ``taichi`` or ``quadrants``."""

    @ti.kernel
    def _sdf(width: ti.i32, height: ti.i32, image: ti.template()):
        for j, i in image:
            # Same operation order as the Warp kernel: convert both, divide, then scale and shift.
            fx = 2.0 * (ti.cast(i, float) / ti.cast(width - 1, float)) - 1.0
            fy = 2.0 * (ti.cast(j, float) / ti.cast(height - 1, float)) - 1.0
            ax = fx + 0.35
            r1 = ti.sqrt(ax * ax + fy * fy) - 0.28
            bx = fx - 0.25
            by = fy - 0.15
            r2 = ti.sqrt(bx * bx + by * by) - 0.18
            wave = fy + 0.25 * ti.sin(8.0 * fx)
            d = ti.max(ti.min(r1, r2), -wave)
            image[j, i] = ti.exp(-18.0 * ti.abs(d))

    class Kernel(ScenarioKernel):
        def __init__(self, params: SdfParams, inputs: dict[str, np.ndarray], device: Device,
                     precision: Precision, variant: str) -> None:
            self.w, self.h = params.width, params.height
            self.image = ti.field(float, shape=(self.h, self.w))

        def run(self) -> None:
            _sdf(self.w, self.h, self.image)

        def outputs(self) -> dict[str, np.ndarray]:
            return {"image": self.image.to_numpy()}

        def info(self) -> dict[str, Any]:
            return {"storage": "field", **framework_config_info(ti.__name__)}

    return _sdf, Kernel


# _sdf, Kernel = build(taichi), on first use (see built_on_first_use)
__getattr__ = built_on_first_use(globals(), build, ("_sdf", "Kernel"))
