"""Trivial launch: out[i] = x[i] + 1 for n (default 1) elements.

A measurement-only scenario (not in ``all``): its steady-state time is what one launch of a kernel
costs in a framework (dispatch, argument marshalling, the launch itself and the synchronisation),
with next to no work. Reading a small-size result against it tells overhead-bound from
bandwidth-bound (see docs/measurement.md). The kernel reads and writes real memory so that no
compiler can drop it, and the result is checked exactly: x holds small integers, x + 1 is exact in
both precisions, so the tolerance is 0.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .base import Check, Precision, Scenario, dtype_of, require


@dataclasses.dataclass(frozen=True)
class LaunchParams:
    n: int = 1

    def validate(self) -> None:
        # small by design: a launch, not a bandwidth measurement (x + 1 stays exact below 2^24)
        require(1 <= self.n <= 1 << 20, f"n must be in [1, 2^20], got {self.n}")


class Launch(Scenario):
    name = "launch"
    title = "Trivial launch out = x + 1 (launch overhead)"
    Params = LaunchParams
    outputs = ("out",)
    in_all = False

    def inputs(self, params: LaunchParams, precision: str) -> dict[str, np.ndarray]:
        dt = dtype_of(precision)
        return {"x": np.arange(params.n, dtype=dt)}

    def output_shapes(self, params: LaunchParams) -> dict[str, tuple[int, ...]]:
        return {"out": (params.n,)}

    def oracle(self, params: LaunchParams, inputs: dict[str, np.ndarray],
               precision: Precision) -> dict[str, np.ndarray]:
        return {"out": inputs["x"].astype(np.float64) + 1.0}

    @staticmethod
    def _max_abs(out: np.ndarray, ref: np.ndarray) -> float:
        out = np.asarray(out, np.float64)
        if out.shape != np.shape(ref) or not np.all(np.isfinite(out)):
            return float("inf")
        return float(np.max(np.abs(out - ref))) if out.size else 0.0

    def check(self, params, inputs, outputs, reference, precision) -> Check:
        err = self._max_abs(outputs["out"], reference["out"])
        return Check(err, 0.0, err == 0.0, {"metric": "max |out - (x + 1)| (exact)"})

    def distance(self, params, inputs, outputs, other) -> float:
        return self._max_abs(outputs["out"], np.asarray(other["out"], np.float64))

    def footprint(self, params: LaunchParams, precision: str, device: str = "cpu") -> float:
        # measured on CPU at n = 2^20: at most 48 B/element in float32, 59 in float64 (taichi)
        itemsize = 4 if precision == "float32" else 8
        return params.n * (48.0 + 8.0 * itemsize)

    def floor(self, params: LaunchParams, precision: str, hardware: dict) -> dict | None:
        """An empty kernel launched through the CUDA driver, pipelined (the same-run yardstick):
        what a framework's call costs beyond the hardware's own launch path."""
        if not hardware.get("launch_pipelined_s"):
            return None
        return {"kind": "launch", "seconds": hardware["launch_pipelined_s"],
                "derivation": "empty PTX kernel via cuLaunchKernel, pipelined, same run"}

    def work(self, params: LaunchParams, precision: str) -> dict[str, float]:
        itemsize = 4 if precision == "float32" else 8
        return {"items": float(params.n), "bytes": 2.0 * params.n * itemsize}
