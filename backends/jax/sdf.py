"""Procedural SDF image in JAX: one jitted elementwise program over the (height, width) grid."""
from __future__ import annotations

from typing import Any

import numpy as np

from . import Program, jax_device, jax_dtype, put
from ..base import ScenarioKernel


def _sdf(wm1, hm1, image):
    """image[j, i] for row j, column i.

    ``wm1``/``hm1`` are vectors filled with width-1 and height-1 (runtime data, not broadcast
    scalars): XLA rewrites a division by a broadcast scalar into a multiply by its reciprocal,
    which rounds differently from the scenario's i/(width-1). fx depends on the column only and fy
    on the row only, so both are computed once per column/row and broadcast (same values per pixel).
    """
    import jax.numpy as jnp
    from jax import lax
    dt = image.dtype
    c = lambda v: jnp.asarray(v, dtype=dt)  # noqa: E731  constants rounded to the cell's dtype
    one, two = c(1.0), c(2.0)
    i = lax.iota(dt, wm1.shape[0])      # exact: width, height <= 65536
    j = lax.iota(dt, hm1.shape[0])
    fx = (two * (i / wm1) - one)[None, :]
    fy = (two * (j / hm1) - one)[:, None]
    ax = fx + c(0.35)
    r1 = jnp.sqrt(ax * ax + fy * fy) - c(0.28)
    bx = fx - c(0.25)
    by = fy - c(0.15)
    r2 = jnp.sqrt(bx * bx + by * by) - c(0.18)
    wave = fy + c(0.25) * jnp.sin(c(8.0) * fx)
    d = jnp.maximum(jnp.minimum(r1, r2), -wave)
    return jnp.exp(c(-18.0) * jnp.abs(d))


class Kernel(ScenarioKernel):
    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        import jax.numpy as jnp
        dev = jax_device(device)
        self.wm1 = put(np.full(params.width, params.width - 1), precision, dev)
        self.hm1 = put(np.full(params.height, params.height - 1), precision, dev)
        # The previous image is donated, so each call writes into the same buffer.
        self.image = jnp.empty((params.height, params.width), dtype=jax_dtype(precision), device=dev)
        self.program = Program(_sdf, donate=(2,))

    def run(self) -> Any:
        self.image = self.program(self.wm1, self.hm1, self.image)
        return self.image

    def outputs(self) -> dict[str, np.ndarray]:
        return {"image": np.asarray(self.image)}

    def info(self) -> dict[str, Any]:
        return self.program.info()
