"""Trivial launch in PyTorch: out = x + 1 over n (default 1) elements, one kernel into ``out``."""
from __future__ import annotations

from typing import Any

import numpy as np

from . import check_variant, compiled, download, empty, kernel_info, put
from ..base import ScenarioKernel


def _plus_one(x, one, out):
    out.copy_(x + one)


class Kernel(ScenarioKernel):
    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        check_variant(variant)
        self.variant = variant
        self.x = put(inputs["x"], precision, device)
        self.one = put(1.0, precision, device)
        self.out = empty((params.n,), precision, device)
        self.fn = compiled(_plus_one) if variant == "compile" else None

    def run(self) -> Any:
        import torch
        with torch.inference_mode():
            if self.fn is not None:
                self.fn(self.x, self.one, self.out)
            else:
                torch.add(self.x, self.one, out=self.out)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out)}

    def info(self) -> dict[str, Any]:
        return kernel_info(self.variant)
