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

from .base import SWEEP_CHECK_SAMPLE, Check, Scenario, UNIT_ROUNDOFF, dtype_of, require, run_label

# Bandwidth-sweep sizes per (device, quick), exponents of 2: CPU sizes stop where a cell still
# takes seconds on a small machine, GPU sizes where the arrays are ~1 GiB.
SWEEP_EXP = {("cpu", False): range(10, 25, 2), ("cpu", True): range(10, 21, 2),
             ("cuda", False): range(10, 29, 2), ("cuda", True): range(10, 23, 2)}


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
    name = "saxpy"
    title = "SAXPY out = a*x + y"
    Params = SaxpyParams
    quick = {"n": 100_003}          # not a multiple of any block size
    outputs = ("out",)
    measures = "bandwidth"          # the sweeps' size sweep (achieved bandwidth against size)
    error_metric = "scenario metric against the float64 oracle: max |err|/(|a x|+|y|)"
    sweep_labels = {"name": "SAXPY", "bytes": "3·n·itemsize",
                    "error_axis": "max |err|/(|a x|+|y|) vs float64 oracle (0 drawn at {floor:g})"}

    def sweep_points(self, kind, device, quick):
        if kind == "bandwidth":
            return [{"params": {"n": 1 << e}, "knob": {"name": "n", "value": 1 << e},
                     "check_sample": SWEEP_CHECK_SAMPLE, "save_outputs": False}
                    for e in SWEEP_EXP.get((device, quick), ())]
        if kind == "error":        # knobs: precision and variant only
            return [{"params": {"n": self.params(quick=quick).n},
                     "knob": {"name": "precision", "value": None}}]
        return []

    def converged_error(self, params, outputs, record, cache, reference=None):
        """The oracle's error is already converged: float64 of the same rounded inputs."""
        return {"error": record["error"]["vs_oracle"], "metric": self.error_metric,
                "reference": {"note": "float64 oracle of the same rounded inputs"}}

    def ulp_cases(self, quick):
        """Both input kinds (cancellation in random ones), at the quick or the full size."""
        n = 100_003 if quick else 1_000_000
        return [({"n": n, "inputs": "linspace"}, "out", "saxpy (linspace)"),
                ({"n": n, "inputs": "random", "seed": 3}, "out", "saxpy (random)")]

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

    def oracle(self, params: SaxpyParams, inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
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
        u64 = UNIT_ROUNDOFF["float64"]
        tol = 2.0 * u * (1.0 + u) + 2.0 * u64 * (1.0 + u64)
        err = self.normalised_error(inputs, outputs["out"], reference["out"])
        return Check(err, tol, err <= tol, {"metric": "max |err|/(|a x|+|y|)", "ulps": err / u})

    def distance(self, params, inputs, outputs, other) -> float:
        return self.normalised_error(inputs, outputs["out"], other["out"])

    def figure(self, runs):
        """Distribution of each float32 run's error in ulps of the exact result (float64 a*x + y
        of the float32 inputs: the product is exact, the sum far below a float32 ulp): <= 0.5 is
        correctly rounded (an FMA), up to ~1 for the two roundings of a*x then + y."""
        import matplotlib.pyplot as plt
        fig, ax = plt.subplots(figsize=(6.5, 4.2))
        edges = np.linspace(0.0, 1.5, 31)
        p = self.params(runs[0][0]["params"])
        runs = [(r, o) for r, o in runs if r["precision"] == "float32"]
        if not runs:
            return None
        for r, o in runs:
            inputs = self.inputs(p, r["precision"])
            ref = self.oracle(p, inputs)["out"]
            out = np.asarray(o["out"], np.float64)
            if out.shape != ref.shape:
                continue
            ulp = np.spacing(np.abs(ref).astype(np.float32)).astype(np.float64)
            ulps = np.abs(out - ref) / np.maximum(ulp, np.finfo(np.float64).tiny)
            ax.hist(np.clip(ulps, 0, edges[-1]), bins=edges, histtype="step", lw=1.2,
                    weights=np.full(ulps.size, 100.0 / max(ulps.size, 1)),
                    label=f"{run_label(r)} (max {ulps.max():.2f})")
        ax.axvline(0.5, color="0.4", ls=":", lw=1)
        ax.set_xlabel("|out - exact| in float32 ulps of the exact result")
        ax.set_ylabel("% of elements"); ax.set_yscale("log")
        ax.set_title(f"saxpy float32 error distribution (n={p.n}, inputs={p.inputs}); "
                     "identical runs overlap", fontsize=8)
        ax.legend(fontsize=6)
        fig.tight_layout()
        return fig

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
