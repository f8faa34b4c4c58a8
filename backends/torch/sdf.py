"""Procedural SDF image in PyTorch: per-column and per-row terms, then (height, width) in place.

fx depends on the column only and fy on the row only, so fx, fy and the terms of one of them
((fx+0.35)^2, (fx-0.25)^2, 0.25 sin(8 fx), (fy-0.15)^2, fy^2) are vectors, broadcast into three
preallocated images (same values per pixel as the scenario's per-pixel formula, in its order).
The literals are 0-d tensors of the cell's dtype: a division by a Python float or a CPU scalar is
evaluated on CUDA as a multiply by its reciprocal (ATen's div_true_kernel), which rounds otherwise.
"compile" runs the same expression as one fused Inductor kernel writing into the image;
"compile_graphs" replays it as a CUDA graph (the two aranges stay eager, in every variant).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import check_variant, compiled, download, empty, kernel_info, put
from ..base import ScenarioKernel
from scenarios.sdf import SdfParams
from ..base import Device
from scenarios.base import Precision

LITERALS = ("one", "two", "c035", "c028", "c025", "c015", "c018", "c8", "cm18")
VALUES = (1.0, 2.0, 0.35, 0.28, 0.25, 0.15, 0.18, 8.0, -18.0)


def _sdf(i, j, wm1, hm1, lit, image):
    import torch
    one, two, c035, c028, c025, c015, c018, c8, cm18 = lit
    fx = (two * (i / wm1) - one)[None, :]
    fy = (two * (j / hm1) - one)[:, None]
    ax = fx + c035
    r1 = torch.sqrt(ax * ax + fy * fy) - c028
    bx = fx - c025
    by = fy - c015
    r2 = torch.sqrt(bx * bx + by * by) - c018
    wave = fy + c025 * torch.sin(c8 * fx)
    d = torch.maximum(torch.minimum(r1, r2), -wave)
    image.copy_(torch.exp(cm18 * torch.abs(d)))


class Kernel(ScenarioKernel):
    def __init__(self, params: SdfParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        check_variant(variant)
        self.variant = variant
        h, w = params.height, params.width
        self.wm1 = put(w - 1, precision, device)
        self.hm1 = put(h - 1, precision, device)
        self.lit = tuple(put(v, precision, device) for v in VALUES)
        vec = lambda n: empty((n,), precision, device)  # noqa: E731
        self.i, self.fx, self.ax, self.bx, self.sx = vec(w), vec(w), vec(w), vec(w), vec(w)
        self.j, self.fy, self.fy2, self.by = vec(h), vec(h), vec(h), vec(h)
        self.r1, self.r2 = empty((h, w), precision, device), empty((h, w), precision, device)
        self.image = empty((h, w), precision, device)
        self.fn = compiled(_sdf, variant, static=(self.i, self.j, self.wm1, self.hm1, *self.lit, self.image))

    def run(self) -> Any:
        import torch
        torch.arange(self.i.shape[0], out=self.i)       # exact: width, height <= 65536
        torch.arange(self.j.shape[0], out=self.j)
        if self.fn is not None:
            self.fn(self.i, self.j, self.wm1, self.hm1, self.lit, self.image)
        else:
            self._eager()
        return self.image

    def _eager(self) -> None:
        import torch
        one, two, c035, c028, c025, c015, c018, c8, cm18 = self.lit
        fx, fy, ax, bx, by, sx, fy2 = self.fx, self.fy, self.ax, self.bx, self.by, self.sx, self.fy2
        r1, r2, image = self.r1, self.r2, self.image
        torch.div(self.i, self.wm1, out=fx).mul_(two).sub_(one)      # fx = 2 (i/(w-1)) - 1
        torch.div(self.j, self.hm1, out=fy).mul_(two).sub_(one)
        torch.add(fx, c035, out=ax).mul_(ax)                          # (fx+0.35)^2
        torch.mul(fy, fy, out=fy2)
        torch.add(ax[None, :], fy2[:, None], out=r1).sqrt_().sub_(c028)
        torch.sub(fx, c025, out=bx).mul_(bx)                          # (fx-0.25)^2
        torch.sub(fy, c015, out=by).mul_(by)
        torch.add(bx[None, :], by[:, None], out=r2).sqrt_().sub_(c018)
        torch.minimum(r1, r2, out=r1)
        torch.mul(fx, c8, out=sx).sin_()                              # 0.25 sin(8 fx)
        torch.mul(sx, c025, out=sx)
        torch.add(fy[:, None], sx[None, :], out=r2).neg_()            # -wave
        torch.maximum(r1, r2, out=r1)
        torch.abs(r1, out=image).mul_(cm18).exp_()

    def outputs(self) -> dict[str, np.ndarray]:
        return {"image": download(self.image)}

    def info(self) -> dict[str, Any]:
        return kernel_info(self.variant)
