"""Device copy: out = x, element by element, for a large n (the bandwidth roofline).

A measurement-only scenario (not in ``all``). Each framework copies with the simplest kernel it
can express (one element per thread or loop iteration), so the result is the memory bandwidth a
bandwidth-bound kernel can reach in that framework on that device: bytes moved = n * itemsize read
+ n * itemsize written. The largest figure over the backends is the run's roofline for SAXPY
and the other bandwidth-bound kernels (docs/measurement.md). A copy is exact: tolerance 0.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .base import Check, Precision, Scenario, dtype_of, require

@dataclasses.dataclass(frozen=True)
class CopyParams:
    n: int = 1 << 25           # 128 MiB per float32 array: far larger than any CPU's last-level cache

    def validate(self) -> None:
        require(1 <= self.n <= 2**31 - 1, f"n must be in [1, 2^31-1], got {self.n}")


class Copy(Scenario):
    name = "copy"
    title = "Device copy out = x (bandwidth roofline)"
    Params = CopyParams
    quick = {"n": (1 << 22) + 3}   # 16 MiB per float32 array; not a multiple of any block size
    outputs = ("out",)
    in_all = False

    def inputs(self, params: CopyParams, precision: str) -> dict[str, np.ndarray]:
        dt = dtype_of(precision)
        # distinct, non-trivial values (not zeros, which a wrong copy could still match)
        return {"x": np.linspace(-1.0, 1.0, params.n, dtype=np.float64).astype(dt)}

    def output_shapes(self, params: CopyParams) -> dict[str, tuple[int, ...]]:
        return {"out": (params.n,)}

    def oracle(self, params: CopyParams, inputs: dict[str, np.ndarray], precision: Precision) -> dict[str, np.ndarray]:
        return {"out": inputs["x"]}

    @staticmethod
    def _max_abs(out: np.ndarray, ref: np.ndarray) -> float:
        out = np.asarray(out)
        if out.shape != np.shape(ref) or not np.all(np.isfinite(out)):
            return float("inf")
        d = np.abs(out.astype(np.float64) - np.asarray(ref, np.float64))
        return float(d.max()) if d.size else 0.0

    def check(self, params, inputs, outputs, reference, precision) -> Check:
        err = self._max_abs(outputs["out"], reference["out"])
        dtype_ok = np.asarray(outputs["out"]).dtype == np.asarray(reference["out"]).dtype
        return Check(err, 0.0, err == 0.0 and dtype_ok,
                     {"metric": "max |out - x| (exact copy)", "dtype_ok": bool(dtype_ok)})

    def distance(self, params, inputs, outputs, other) -> float:
        return self._max_abs(outputs["out"], other["out"])

    def footprint(self, params: CopyParams, precision: str, device: str = "cpu") -> float:
        # x, the framework's copies, out, float64 temporaries of the check; measured on CPU at
        # n = 2^24: at most 32 B/element in float32, 48 in float64; bound 1.5x that
        itemsize = 4 if precision == "float32" else 8
        return params.n * (24.0 + 6.0 * itemsize)

    def work(self, params: CopyParams, precision: str) -> dict[str, float]:
        itemsize = 4 if precision == "float32" else 8
        return {"items": float(params.n), "bytes": 2.0 * params.n * itemsize}
