"""Procedural signed-distance image (the seed's two circles, sine wave and exp(-18|d|)).

Pixel (i, j), i the column in [0, width), j the row in [0, height), stored row-major as
image[j, i]:
    fx = 2 i/(width-1) - 1,  fy = 2 j/(height-1) - 1
    r1 = sqrt((fx+0.35)^2 + fy^2) - 0.28,  r2 = sqrt((fx-0.25)^2 + (fy-0.15)^2) - 0.18
    wave = fy + 0.25 sin(8 fx),  d = max(min(r1, r2), -wave),  v = exp(-18 |d|)

Error metric: max |v - v_ref| over pixels, in units of u (v is in (0, 1]).
Derived bound (first order, per operation |d| <= u, libm sin/exp within 2 ulp):
    |dfx|, |dfy| <= 3u                      (one division, one subtraction; x2 is exact)
    |dr1|, |dr2| <= sqrt(2)*4.7u + 2.5u*1.9 + 2u <= 13u   (shifted coordinate, hypot, sqrt, shift)
    |dwave| <= 3u + 0.25*(8*3u + 2u) + 1.25u <= 11u
    |dd| <= 16u                             (min, max and |.| are 1-Lipschitz; margin included)
    |dv| <= v*(18*16u + 18|d|u + 2u) <= 288u + u/e + 2u <= 291u   (18|d|e^{-18|d|} <= 1/e)
The float64 oracle obeys the same bound with u64, so the tolerance is 300(u + u64):
1.8e-5 in float32, 6.7e-14 in float64.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .base import UNIT_ROUNDOFF, Check, Precision, Scenario, require

TOLERANCE_ULPS = 300.0


@dataclasses.dataclass(frozen=True)
class SdfParams:
    width: int = 512
    height: int = 512

    def validate(self) -> None:
        require(2 <= self.width <= 65536, f"width must be in [2, 65536], got {self.width}")
        require(2 <= self.height <= 65536, f"height must be in [2, 65536], got {self.height}")


def sdf_field(fx: np.ndarray, fy: np.ndarray) -> np.ndarray:
    r1 = np.sqrt((fx + 0.35) ** 2 + fy * fy) - 0.28
    r2 = np.sqrt((fx - 0.25) ** 2 + (fy - 0.15) ** 2) - 0.18
    wave = fy + 0.25 * np.sin(8.0 * fx)
    d = np.maximum(np.minimum(r1, r2), -wave)
    return np.exp(-18.0 * np.abs(d))


class Sdf(Scenario):
    name = "sdf"
    title = "Procedural SDF image"
    Params = SdfParams
    quick = {"width": 203, "height": 97}   # non-square, not a multiple of any block size
    outputs = ("image",)
    # on a GPU no timed row reads its defaults (the per-call rows rank SAXPY's small kernel; its
    # accuracy and first result are ranked everywhere); the CPU-only and busy rows rank them
    timings_ranked_on = ("cpu",)

    def inputs(self, params: SdfParams, precision: str) -> dict[str, np.ndarray]:
        return {}  # the image is a pure function of the pixel index

    def output_shapes(self, params: SdfParams) -> dict[str, tuple[int, ...]]:
        return {"image": (params.height, params.width)}

    def oracle(self, params: SdfParams, inputs, precision: Precision) -> dict[str, np.ndarray]:
        i = np.arange(params.width, dtype=np.float64)
        j = np.arange(params.height, dtype=np.float64)
        fx = 2.0 * (i / (params.width - 1)) - 1.0
        fy = 2.0 * (j / (params.height - 1)) - 1.0
        return {"image": sdf_field(fx[None, :], fy[:, None])}

    def _max_abs(self, a: np.ndarray, b: np.ndarray) -> float:
        a = np.asarray(a, dtype=np.float64)
        b = np.asarray(b, dtype=np.float64)
        if a.shape != b.shape:
            return float("inf")
        d = np.abs(a - b)
        return float(d.max()) if np.all(np.isfinite(d)) else float("inf")

    def check(self, params, inputs, outputs, reference, precision) -> Check:
        u = UNIT_ROUNDOFF[precision]
        err = self._max_abs(outputs["image"], reference["image"])
        tol = TOLERANCE_ULPS * (u + UNIT_ROUNDOFF[Precision.FLOAT64])
        return Check(err, tol, err <= tol, {"metric": "max |v - v_ref|", "ulps": err / u})

    def distance(self, params, inputs, outputs, other) -> float:
        return self._max_abs(outputs["image"], other["image"])

    def footprint(self, params: SdfParams, precision: str, device: str = "cpu") -> float:
        # image + float64 oracle temporaries; measured on CPU at 2048^2 (all four backends): at
        # most 58 B/pixel in float32 and 65 in float64; bound ~1.4x that (docs/reliability.md)
        itemsize = 4 if precision == "float32" else 8
        return params.width * params.height * (64.0 + 4.0 * itemsize)

    def input_bytes(self, params: SdfParams, precision: str) -> float:
        return 0.0           # the image is a pure function of the pixel index: no inputs

    def work(self, params: SdfParams, precision: str) -> dict[str, float]:
        itemsize = 4 if precision == "float32" else 8
        n = params.width * params.height
        # 30 FLOP per pixel: pixel -> (fx, fy) 6, two circle distances 12 (sqrt as one), the wave 3
        # (sin as one), min/max/negate 3, exp(-18|d|) 3 (exp as one), rounded to 30 (a floor that
        # counts a transcendental as one operation is loose: the SFU path costs more)
        return {"items": n, "bytes": float(n * itemsize), "flops": 30.0 * n}
