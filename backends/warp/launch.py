"""Trivial launch in Warp: out[i] = x[i] + 1 over n (default 1) threads."""
# (no "from __future__ import annotations": Warp evaluates kernel annotations from the closure)

import functools

import numpy as np
import warp as wp

from . import launcher, wp_device, wp_scalar
from ..base import ScenarioKernel


@functools.cache
def _plus_one(scalar):
    @wp.kernel(module="unique")
    def plus_one(x: wp.array(dtype=scalar), out: wp.array(dtype=scalar)):
        i = wp.tid()
        out[i] = x[i] + scalar(1.0)
    return plus_one


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs, device, precision, variant):
        self.dev = wp_device(device)
        scalar = wp_scalar(precision)
        self.kernel = _plus_one(scalar)
        self.x = wp.array(inputs["x"], dtype=scalar, device=self.dev)
        self.out = wp.empty(params.n, dtype=scalar, device=self.dev)
        self.launch = launcher(variant, self.kernel, params.n, [self.x], [self.out], self.dev)

    def run(self):
        self.launch()

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.numpy()}
