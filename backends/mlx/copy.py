"""Device copy in MLX: ``mx.array(x)``, MLX's copy of an array (a lazy Copy into a new buffer).

Most MLX ops that leave values unchanged (``mx.contiguous`` of a contiguous array, ``astype`` to
the same dtype, reshape, a full slice) share the input's buffer and move no bytes; ``mx.array``
of an array allocates and fills a new one (tests/backends/test_mlx.py checks that the output is new
memory). It is not compiled: there is nothing to fuse.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import download, kernel_info, launch, put
from ..base import ScenarioKernel
from scenarios.copy import CopyParams
from ..base import Device
from scenarios.base import Precision


class Kernel(ScenarioKernel):
    def __init__(self, params: CopyParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        self.device, self.precision = device, precision
        self.x = put(inputs["x"], precision)
        self.out: Any = None

    def run(self) -> Any:
        import mlx.core as mx
        self.out = launch(mx.array(self.x))
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out, self.precision)}

    def info(self) -> dict[str, Any]:
        return kernel_info(self.device, self.precision, compiled="no (a copy has nothing to fuse)",
                           copy="mx.array(x)")
