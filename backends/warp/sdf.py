"""Procedural SDF image in Warp: a 2-D launch, one thread per pixel."""
# (no "from __future__ import annotations": Warp evaluates kernel annotations from the closure)

import functools

import numpy as np
import warp as wp

from . import launcher, wp_device, wp_scalar
from ..base import ScenarioKernel


@functools.cache
def _sdf(scalar):
    @wp.kernel(module="unique")
    def sdf(width: int, height: int, image: wp.array2d(dtype=scalar)):
        j, i = wp.tid()
        one = scalar(1.0)
        two = scalar(2.0)
        fx = two * (scalar(i) / scalar(width - 1)) - one
        fy = two * (scalar(j) / scalar(height - 1)) - one
        ax = fx + scalar(0.35)
        r1 = wp.sqrt(ax * ax + fy * fy) - scalar(0.28)
        bx = fx - scalar(0.25)
        by = fy - scalar(0.15)
        r2 = wp.sqrt(bx * bx + by * by) - scalar(0.18)
        wave = fy + scalar(0.25) * wp.sin(scalar(8.0) * fx)
        d = wp.max(wp.min(r1, r2), -wave)
        image[j, i] = wp.exp(scalar(-18.0) * wp.abs(d))
    return sdf


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs, device, precision, variant):
        self.dev = wp_device(device)
        self.kernel = _sdf(wp_scalar(precision))
        self.w, self.h = params.width, params.height
        self.image = wp.empty((self.h, self.w), dtype=wp_scalar(precision), device=self.dev)
        self.launch = launcher(variant, self.kernel, (self.h, self.w), [self.w, self.h],
                               [self.image], self.dev)

    def run(self):
        self.launch()

    def outputs(self) -> dict[str, np.ndarray]:
        return {"image": self.image.numpy()}
