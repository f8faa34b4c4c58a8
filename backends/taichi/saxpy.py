"""SAXPY in Taichi: one parallel-for iteration per element.

Storage: fields. Measured on a 2-core CPU (median of 200 run()+sync, ndarray vs field):
n=100_003 f32 113-204 vs 89-164 us, f64 130-206 vs 102-187 us; n=1e6 f32 733-852 vs 575-639 us,
f64 894-1087 vs 593-1098 us. Fields avoid the per-launch ndarray argument marshalling and let
the compiler see the extent; both give bit-identical results.

``build(ti)`` defines the kernel and ``Kernel`` for ``ti``, the ``taichi`` module here and the
``quadrants`` one in backends/quadrants/saxpy.py (Taichi's fork, the same API).
"""
# (no "from __future__ import annotations": Taichi reads kernel annotations as objects)

import functools
from types import ModuleType
from typing import Any

import numpy as np

from . import built_on_first_use, framework_config_info
from ..base import ScenarioKernel
from scenarios.saxpy import SaxpyParams
from ..base import Device
from scenarios.base import Precision


@functools.cache
def build(ti: ModuleType) -> tuple[Any, type[ScenarioKernel]]:
    """(the kernel, ``Kernel``) in ``ti``: ``taichi`` or ``quadrants``."""

    @ti.kernel
    def _saxpy(a: float, x: ti.template(), y: ti.template(), out: ti.template()):
        # Fields are template arguments: one compilation per Kernel instance, none per run().
        for i in out:
            out[i] = a * x[i] + y[i]

    class Kernel(ScenarioKernel):
        def __init__(self, params: SaxpyParams, inputs: dict[str, np.ndarray], device: Device,
                     precision: Precision, variant: str) -> None:
            self.a = float(inputs["a"])   # already rounded; the kernel's default_fp argument
            self.x, self.y, self.out = (ti.field(float, shape=params.n) for _ in range(3))
            self.x.from_numpy(inputs["x"])
            self.y.from_numpy(inputs["y"])

        def run(self) -> None:
            _saxpy(self.a, self.x, self.y, self.out)

        def outputs(self) -> dict[str, np.ndarray]:
            return {"out": self.out.to_numpy()}

        def info(self) -> dict[str, Any]:
            return {"storage": "field", **framework_config_info(ti.__name__)}

    return _saxpy, Kernel


# _saxpy, Kernel = build(taichi), on first use (see built_on_first_use)
__getattr__ = built_on_first_use(globals(), build, ("_saxpy", "Kernel"))
