"""Device copy in PyTorch: ``out.copy_(x)`` into a preallocated tensor (the bandwidth roofline).

ATen's copy_ between two same-dtype contiguous tensors on one device is a device memcpy on CUDA
(cudaMemcpyAsync, device to device) and a parallel memcpy on the CPU: the framework's own fastest
copy. "compile" lets Inductor emit the copy as a generated kernel instead; "compile_graphs"
replays that kernel as a CUDA graph.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import check_variant, compiled, download, empty, kernel_info, put
from ..base import ScenarioKernel
from scenarios.copy import CopyParams
from ..base import Device
from scenarios.base import Precision


def _copy(x, out):
    out.copy_(x)


class Kernel(ScenarioKernel):
    """One op from x into a preallocated out, eager or compiled (launch.py reuses it with its own):
    ``body`` is the compile variant's function of ``args``, ``eager`` the default variant's call."""
    body = staticmethod(_copy)

    def __init__(self, params: CopyParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        check_variant(variant)
        self.variant = variant
        self.x = put(inputs["x"], precision, device)
        self.out = empty((params.n,), precision, device)
        self.args: tuple[Any, ...] = (self.x, self.out)
        self.fn = compiled(self.body, variant, static=self.args)

    def eager(self, torch: Any) -> None:
        self.out.copy_(self.x)

    def run(self) -> Any:
        import torch
        if self.fn is not None:
            self.fn(*self.args)
        else:
            self.eager(torch)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": download(self.out)}

    def info(self) -> dict[str, Any]:
        return kernel_info(self.variant, copy="Tensor.copy_" if self.fn is None else "compiled copy_",
                           distinct_output_buffer=self.out.data_ptr() != self.x.data_ptr())
