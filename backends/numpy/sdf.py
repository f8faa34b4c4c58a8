"""Procedural SDF image in NumPy: whole-image ufuncs, broadcasting a row of x terms against a
column of y terms.

Every pixel gets Warp's operations in Warp's order, but a term that depends on the column alone
(fx, (fx+0.35)^2, sin(8 fx), ...) is computed once per column and one that depends on the row
alone once per row, then broadcast: the same values a per-pixel kernel computes, without W*H
copies of them. -wave is formed as (-fy) - 0.25 sin(8 fx), which equals -(fy + 0.25 sin(8 fx))
bit for bit (negation is exact and rounding is symmetric). Twelve passes over the image, in one
preallocated scratch image and the output.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import kernel_info, scalar_type
from ..base import ScenarioKernel


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = self.S = scalar_type(precision)
        w, h = params.width, params.height
        self.c = {k: S(v) for k, v in (("one", 1.0), ("two", 2.0), ("ax", 0.35), ("r1", 0.28),
                                       ("bx", 0.25), ("by", 0.15), ("r2", 0.18), ("wave", 0.25),
                                       ("freq", 8.0), ("decay", -18.0))}
        self.wm1, self.hm1 = S(w - 1), S(h - 1)
        self.i = np.arange(w, dtype=S)              # the pixel index, as Warp's scalar(i)
        self.j = np.arange(h, dtype=S)
        self.col = [np.empty(w, S) for _ in range(4)]     # per-column terms
        self.row = [np.empty(h, S) for _ in range(4)]     # per-row terms
        self.image = np.empty((h, w), S)
        self.scratch = np.empty((h, w), S)
        # (a ufunc over the broadcast row x column operands allocates only NumPy's fixed iterator
        # buffer, np.getbufsize() elements per operand, whatever the image size)

    def run(self) -> None:
        c = self.c
        fx, axx, bxx, sw = self.col
        fy, fyy, byy, nfy = self.row
        img, t = self.image, self.scratch
        # fx = 2*(i/(w-1)) - 1, fy likewise
        np.divide(self.i, self.wm1, out=fx); np.multiply(fx, c["two"], out=fx)
        np.subtract(fx, c["one"], out=fx)
        np.divide(self.j, self.hm1, out=fy); np.multiply(fy, c["two"], out=fy)
        np.subtract(fy, c["one"], out=fy)
        # per-column and per-row parts: (fx+0.35)^2, fy^2, (fx-0.25)^2, (fy-0.15)^2, -fy, 0.25 sin(8 fx)
        np.add(fx, c["ax"], out=axx); np.multiply(axx, axx, out=axx)
        np.multiply(fy, fy, out=fyy)
        np.subtract(fx, c["bx"], out=bxx); np.multiply(bxx, bxx, out=bxx)
        np.subtract(fy, c["by"], out=byy); np.multiply(byy, byy, out=byy)
        np.negative(fy, out=nfy)
        np.multiply(fx, c["freq"], out=sw); np.sin(sw, out=sw); np.multiply(sw, c["wave"], out=sw)
        # r1 = sqrt(ax^2 + fy^2) - 0.28 (in img), r2 = sqrt(bx^2 + by^2) - 0.18 (in t)
        np.add(axx[None, :], fyy[:, None], out=img); np.sqrt(img, out=img)
        np.subtract(img, c["r1"], out=img)
        np.add(bxx[None, :], byy[:, None], out=t); np.sqrt(t, out=t)
        np.subtract(t, c["r2"], out=t)
        np.minimum(img, t, out=img)
        np.subtract(nfy[:, None], sw[None, :], out=t)          # -wave
        np.maximum(img, t, out=img)                            # d
        # v = exp(-18 |d|)
        np.abs(img, out=img); np.multiply(img, c["decay"], out=img); np.exp(img, out=img)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"image": self.image.copy()}

    def info(self) -> dict[str, Any]:
        return kernel_info(image_passes=12)
