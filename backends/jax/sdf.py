"""Procedural SDF image in JAX: one jitted elementwise program over the (height, width) grid."""
from __future__ import annotations

from typing import Any

import numpy as np

from . import Program, jax_device, jax_dtype, put
from ..base import ScenarioKernel
from scenarios.sdf import SdfParams
from ..base import Device
from scenarios.base import Precision


# The scenario's literals, rounded to the cell's dtype and passed in at run time: as compile-time
# constants XLA's simplifier would fold (2q - 1) + 0.35 into 2q - 0.65, which rounds differently.
LITERALS = (1.0, 2.0, 0.35, 0.28, 0.25, 0.15, 0.18, 8.0, -18.0)


def _sdf(wm1, hm1, lit, image):
    """image[j, i] for row j, column i.

    ``wm1``/``hm1`` are vectors filled with width-1 and height-1 (runtime data, not broadcast
    scalars): XLA rewrites a division by a broadcast scalar into a multiply by its reciprocal,
    which rounds differently from the scenario's i/(width-1). fx depends on the column only and fy
    on the row only, so both are computed once per column/row and broadcast (same values per pixel).
    """
    import jax.numpy as jnp
    from jax import lax
    one, two, c035, c028, c025, c015, c018, c8, cm18 = (lit[k] for k in range(len(LITERALS)))
    i = lax.iota(image.dtype, wm1.shape[0])      # exact: width, height <= 65536
    j = lax.iota(image.dtype, hm1.shape[0])
    fx = (two * (i / wm1) - one)[None, :]
    fy = (two * (j / hm1) - one)[:, None]
    ax = fx + c035
    r1 = jnp.sqrt(ax * ax + fy * fy) - c028
    bx = fx - c025
    by = fy - c015
    r2 = jnp.sqrt(bx * bx + by * by) - c018
    wave = fy + c025 * jnp.sin(c8 * fx)
    d = jnp.maximum(jnp.minimum(r1, r2), -wave)
    return jnp.exp(cm18 * jnp.abs(d))


class Kernel(ScenarioKernel):
    def __init__(self, params: SdfParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        import jax.numpy as jnp
        dev = jax_device(device)
        self.wm1 = put(np.full(params.width, params.width - 1), precision, dev)
        self.hm1 = put(np.full(params.height, params.height - 1), precision, dev)
        self.lit = put(LITERALS, precision, dev)
        # The previous image is donated, so each call writes into the same buffer.
        self.image = jnp.empty((params.height, params.width), dtype=jax_dtype(precision), device=dev)
        self.program = Program(_sdf, donate=(3,))

    def run(self) -> Any:
        self.image = self.program(self.wm1, self.hm1, self.lit, self.image)
        return self.image

    def outputs(self) -> dict[str, np.ndarray]:
        return {"image": np.asarray(self.image)}

    def info(self) -> dict[str, Any]:
        return self.program.info()
