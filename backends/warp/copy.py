"""Device copy in Warp: one thread per element, out[i] = x[i] (the bandwidth roofline)."""
# (no "from __future__ import annotations": Warp evaluates kernel annotations from the closure)

import functools

import numpy as np
import warp as wp

from . import launcher, wp_device, wp_scalar
from ..base import ScenarioKernel


@functools.cache
def _copy(scalar):
    @wp.kernel(module="unique")
    def copy(x: wp.array(dtype=scalar), out: wp.array(dtype=scalar)):
        i = wp.tid()
        out[i] = x[i]
    return copy


class Kernel(ScenarioKernel):
    """One thread per element from x into a preallocated out (launch.py reuses it with its own)."""
    make = staticmethod(_copy)

    def __init__(self, params, inputs, device, precision, variant):
        self.dev = wp_device(device)
        scalar = wp_scalar(precision)
        self.kernel = self.make(scalar)
        self.x = wp.array(inputs["x"], dtype=scalar, device=self.dev)
        self.out = wp.empty(params.n, dtype=scalar, device=self.dev)
        self.launch = launcher(variant, self.kernel, params.n, [self.x], [self.out], self.dev)

    def run(self):
        self.launch()

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.numpy()}

    def info(self) -> dict:
        return {"copy": "kernel out[i] = x[i]"}
