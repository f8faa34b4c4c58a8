"""SAXPY: out = a*x + y.

Error metric (per element, normalised by the size of the terms, so it reads in units of u):
    e_i = |out_i - ref_i| / max(|a x_i| + |y_i|, tiny)
Derived bound: fl(fl(a*x) + y) = (a x (1+d1) + y)(1+d2), |d| <= u, so
    |err_i| <= u|a x_i| + u|a x_i + y_i| + u^2|a x_i| <= 2u(1+u)(|a x_i| + |y_i|);
with a fused multiply-add the bound is u|a x_i + y_i|, smaller. The reference is computed in
float64 from the same rounded a, x, y: exact for float32 inputs (a 24x24-bit product and the sum
fit in 53 bits), but itself rounded twice for float64 inputs, so it adds 2u64(1+u64).
Tolerance: 2u(1+u) + 2u64(1+u64), i.e. 2^-23 (+2^-52) in float32 and 2^-51 in float64.
"""
from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np

from .base import Check, Precision, Scenario, UNIT_ROUNDOFF, dtype_of, require

@dataclasses.dataclass(frozen=True)
class SaxpyParams:
    n: int = 1_000_000
    a: float = 2.5
    inputs: Literal["linspace", "random"] = "linspace"
    seed: int = 0

    def validate(self) -> None:
        require(1 <= self.n <= 2**31 - 1, f"n must be in [1, 2^31-1], got {self.n}")
        require(math.isfinite(self.a), f"a must be finite, got {self.a}")
        require(self.seed >= 0, f"seed must be >= 0, got {self.seed}")


class Saxpy(Scenario):
    ulps_count_roundings = True       # a*x + y: rounded once (an FMA) or twice (accuracy page)
    name = "saxpy"
    title = "SAXPY out = a*x + y"
    Params = SaxpyParams
    quick = {"n": 100_003}          # not a multiple of any block size
    outputs = ("out",)

    def inputs(self, params: SaxpyParams, precision: str) -> dict[str, np.ndarray]:
        dt = dtype_of(precision)
        if params.inputs == "linspace":
            x = np.linspace(0.0, 1.0, params.n)
            y = np.linspace(1.0, 2.0, params.n)
        else:  # signed values over several decades, so cancellation in a*x + y is exercised
            rng = np.random.default_rng(params.seed)
            x = rng.standard_normal(params.n) * 10.0 ** rng.uniform(-3, 3, params.n)
            y = rng.standard_normal(params.n) * 10.0 ** rng.uniform(-3, 3, params.n)
        return {"a": np.array(params.a, dtype=dt), "x": x.astype(dt), "y": y.astype(dt)}

    def output_shapes(self, params: SaxpyParams) -> dict[str, tuple[int, ...]]:
        return {"out": (params.n,)}

    def oracle(self, params: SaxpyParams, inputs: dict[str, np.ndarray], precision: Precision) -> dict[str, np.ndarray]:
        a = np.float64(inputs["a"])
        return {"out": a * inputs["x"].astype(np.float64) + inputs["y"].astype(np.float64)}

    def _scale(self, inputs: dict[str, np.ndarray]) -> np.ndarray:
        a = np.float64(inputs["a"])
        s = np.abs(a * inputs["x"].astype(np.float64)) + np.abs(inputs["y"].astype(np.float64))
        return np.maximum(s, np.finfo(np.float64).tiny)

    def normalised_error(self, inputs, out: np.ndarray, ref: np.ndarray) -> float:
        diff = np.abs(np.asarray(out, dtype=np.float64) - np.asarray(ref, dtype=np.float64))
        e = diff / self._scale(inputs)
        return float(np.max(e)) if e.size and np.all(np.isfinite(e)) else math.inf

    def check(self, params, inputs, outputs, reference, precision) -> Check:
        u = UNIT_ROUNDOFF[precision]
        u64 = UNIT_ROUNDOFF[Precision.FLOAT64]
        tol = 2.0 * u * (1.0 + u) + 2.0 * u64 * (1.0 + u64)
        err = self.normalised_error(inputs, outputs["out"], reference["out"])
        return Check(err, tol, err <= tol, {"metric": "max |err|/(|a x|+|y|)", "ulps": err / u})

    def distance(self, params, inputs, outputs, other) -> float:
        return self.normalised_error(inputs, outputs["out"], other["out"])

    def footprint(self, params: SaxpyParams, precision: str, device: str = "cpu") -> float:
        # inputs, the framework's copies, outputs, the float64 oracle and check temporaries.
        # Measured on CPU at n = 2^24 (all four backends): at most 64 B/element in float32 and
        # 88 in float64; bound ~1.36x that (docs/reliability.md)
        itemsize = 4 if precision == "float32" else 8
        return params.n * (56.0 + 8.0 * itemsize)

    def input_bytes(self, params: SaxpyParams, precision: str) -> float:
        return (2.0 * params.n + 1) * (4 if precision == "float32" else 8)     # a, x, y

    def work(self, params: SaxpyParams, precision: str) -> dict[str, float]:
        itemsize = 4 if precision == "float32" else 8
        return {"items": params.n, "bytes": 3.0 * params.n * itemsize}
