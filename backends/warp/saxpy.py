"""SAXPY in Warp: one thread per element."""
# (no "from __future__ import annotations": Warp evaluates kernel annotations from the closure)

import functools

import numpy as np
import warp as wp

from . import wp_device, wp_scalar
from ..base import ScenarioKernel


@functools.cache
def _saxpy(scalar):
    @wp.kernel(module="unique")
    def saxpy(a: scalar, x: wp.array(dtype=scalar), y: wp.array(dtype=scalar),
              out: wp.array(dtype=scalar)):
        i = wp.tid()
        out[i] = a * x[i] + y[i]
    return saxpy


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs, device, precision, variant):
        self.dev = wp_device(device)
        scalar = wp_scalar(precision)
        self.kernel = _saxpy(scalar)
        self.a = scalar(float(inputs["a"]))
        self.x = wp.array(inputs["x"], dtype=scalar, device=self.dev)
        self.y = wp.array(inputs["y"], dtype=scalar, device=self.dev)
        self.out = wp.empty(params.n, dtype=scalar, device=self.dev)

    def run(self):
        wp.launch(self.kernel, dim=self.out.shape[0], inputs=[self.a, self.x, self.y],
                  outputs=[self.out], device=self.dev)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.numpy()}
