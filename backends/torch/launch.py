"""Trivial launch in PyTorch: out = x + 1 over n (default 1) elements, one kernel into ``out``.

The copy's ``Kernel`` (copy.py: the same tensors, variants, inference mode and download) with
this op, which takes a 0-d 1 of the cell's dtype: ``torch.add`` eager, ``_plus_one`` compiled.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import kernel_info, mark_static, put
from .copy import Kernel as CopyKernel
from scenarios.launch import LaunchParams
from ..base import Device
from scenarios.base import Precision


def _plus_one(x, one, out):
    out.copy_(x + one)


class Kernel(CopyKernel):
    body = staticmethod(_plus_one)

    def __init__(self, params: LaunchParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        super().__init__(params, inputs, device, precision, variant)
        self.one = put(1.0, precision, device)
        mark_static(variant, self.one)      # read before the first (compiling) call
        self.args = (self.x, self.one, self.out)

    def eager(self, torch: Any) -> None:
        torch.add(self.x, self.one, out=self.out)

    def info(self) -> dict[str, Any]:
        return kernel_info(self.variant)
