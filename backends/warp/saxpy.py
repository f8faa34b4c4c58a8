"""SAXPY in Warp.

* ``default``: one thread per element (``wp.launch``).
* ``record_cmd``: the default kernel, its launch recorded once and replayed (``launcher``).
* ``tile``: Warp's tile programming model (``wp.launch_tiled``), the documented way to give a
  block of threads a cooperative load: each block of ``BLOCK_DIM`` threads loads ``TILE``
  consecutive elements of x and y into registers (``TILE / BLOCK_DIM`` independent, coalesced
  loads per thread, so more bytes in flight than one element a thread), computes ``a * x + y`` and
  stores the tile. The last tile's out-of-range elements read as zero and are not stored
  (``tile_load``/``tile_store`` bounds checks). The bandwidth-bound variant closest to the memcpy
  at large n; the same arithmetic, one FMA per element on CUDA.
"""
# (no "from __future__ import annotations": Warp evaluates kernel annotations from the closure)

import functools

import numpy as np
import warp as wp

from . import launcher, wp_device, wp_scalar
from ..base import ScenarioKernel

BLOCK_DIM = 256
TILE = 8 * BLOCK_DIM        # elements per block: 8 loads of each input in flight per thread


@functools.cache
def _saxpy(scalar):
    @wp.kernel(module="unique")
    def saxpy(a: scalar, x: wp.array(dtype=scalar), y: wp.array(dtype=scalar),
              out: wp.array(dtype=scalar)):
        i = wp.tid()
        out[i] = a * x[i] + y[i]
    return saxpy


@functools.cache
def _saxpy_tile(scalar):
    @wp.kernel(module="unique")
    def saxpy_tile(a: scalar, x: wp.array(dtype=scalar), y: wp.array(dtype=scalar),
                   out: wp.array(dtype=scalar)):
        i = wp.tid()
        tx = wp.tile_load(x, shape=TILE, offset=i * TILE)
        ty = wp.tile_load(y, shape=TILE, offset=i * TILE)
        wp.tile_store(out, a * tx + ty, offset=i * TILE)
    return saxpy_tile


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs, device, precision, variant):
        self.dev = wp_device(device)
        scalar = wp_scalar(precision)
        self.tiled = variant == "tile"
        self.kernel = _saxpy_tile(scalar) if self.tiled else _saxpy(scalar)
        self.a = scalar(float(inputs["a"]))
        self.x = wp.array(inputs["x"], dtype=scalar, device=self.dev)
        self.y = wp.array(inputs["y"], dtype=scalar, device=self.dev)
        self.out = wp.empty(params.n, dtype=scalar, device=self.dev)
        if self.tiled:
            self.launch = functools.partial(
                wp.launch_tiled, self.kernel, dim=[-(-params.n // TILE)],
                inputs=[self.a, self.x, self.y], outputs=[self.out], device=self.dev,
                block_dim=BLOCK_DIM)
        else:
            self.launch = launcher(variant, self.kernel, params.n, [self.a, self.x, self.y],
                                   [self.out], self.dev)

    def run(self):
        self.launch()

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.numpy()}

    def info(self) -> dict:
        if self.tiled:
            return {"kernel": "wp.launch_tiled", "block_dim": BLOCK_DIM, "tile": TILE}
        return {}
