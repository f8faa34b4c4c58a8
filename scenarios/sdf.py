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

from .base import UNIT_ROUNDOFF, Check, Scenario, pick_runs, require, run_label

TOLERANCE_ULPS = 300.0
# Time-against-error sweep: resolutions r x r per (device, quick), and the evaluation grid (per
# axis) of the reconstruction error against the analytic field.
SWEEP_RES = {("cpu", False): (64, 128, 256, 512, 1024, 2048), ("cpu", True): (32, 64, 128),
             ("cuda", False): (64, 128, 256, 512, 1024, 2048, 4096), ("cuda", True): (32, 64, 128)}
SWEEP_EVAL = 2001


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
    error_metric = (f"max |bilinear(image) - f| over a {SWEEP_EVAL}x{SWEEP_EVAL} grid, "
                    "f the analytic field in float64")
    sweep_labels = {"error_axis": "max |bilinear(image) - field| (log)"}

    def sweep_points(self, kind, device, quick):
        if kind != "error":
            return []
        return [{"params": {"width": r, "height": r}, "knob": {"name": "resolution", "value": r}}
                for r in SWEEP_RES.get((device, quick), ())]

    def reconstruction_error(self, image: np.ndarray, cache: dict | None = None) -> dict[str, float]:
        """Bilinear reconstruction of the image against the analytic field on a fixed fine grid
        (SWEEP_EVAL points per axis over [-1, 1]^2): max and RMS of the difference."""
        img = np.asarray(image, np.float64)
        h, w = img.shape
        t = np.linspace(-1.0, 1.0, SWEEP_EVAL)
        cache = {} if cache is None else cache
        if ("sdf-field", SWEEP_EVAL) not in cache:
            cache["sdf-field", SWEEP_EVAL] = sdf_field(t[None, :], t[:, None])
        exact = cache["sdf-field", SWEEP_EVAL]

        def axis(n):
            pos = (t + 1.0) * 0.5 * (n - 1)
            i0 = np.clip(np.floor(pos).astype(np.int64), 0, n - 2)
            return i0, pos - i0
        i0, fx = axis(w)
        j0, fy = axis(h)
        rows0, rows1 = img[j0], img[j0 + 1]
        top = rows0[:, i0] * (1 - fx) + rows0[:, i0 + 1] * fx
        bot = rows1[:, i0] * (1 - fx) + rows1[:, i0 + 1] * fx
        d = np.abs(top * (1 - fy)[:, None] + bot * fy[:, None] - exact)
        return {"error": float(d.max()), "rms": float(np.sqrt(np.mean(d * d)))}

    def converged_error(self, params, outputs, record, cache, reference=None):
        if outputs is None:
            return None
        return {**self.reconstruction_error(outputs["image"], cache), "metric": self.error_metric,
                "reference": {"eval_grid": SWEEP_EVAL, "note": "analytic field, float64"}}

    def ulp_cases(self, quick):
        return [({"width": 512, "height": 512}, "image", "sdf")]

    def inputs(self, params: SdfParams, precision: str) -> dict[str, np.ndarray]:
        return {}  # the image is a pure function of the pixel index

    def output_shapes(self, params: SdfParams) -> dict[str, tuple[int, ...]]:
        return {"image": (params.height, params.width)}

    def oracle(self, params: SdfParams, inputs) -> dict[str, np.ndarray]:
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
        tol = TOLERANCE_ULPS * (u + UNIT_ROUNDOFF["float64"])
        return Check(err, tol, err <= tol, {"metric": "max |v - v_ref|", "ulps": err / u})

    def distance(self, params, inputs, outputs, other) -> float:
        return self._max_abs(outputs["image"], other["image"])

    def figure(self, runs):
        """The float64 oracle image, then |image - oracle| per backend (log colour, one scale for
        all panels, the maximum also as a fraction of the derived tolerance)."""
        import matplotlib.pyplot as plt
        from matplotlib.colors import LogNorm
        runs = [(r, o) for r, o in pick_runs(runs, 8) if np.ndim(o.get("image")) == 2]
        if not runs:
            return None
        p = self.params(runs[0][0]["params"])
        ref = self.oracle(p, {})["image"]
        diffs = []
        for r, o in runs:
            img = np.asarray(o["image"], np.float64)
            diffs.append(np.abs(img - ref) if img.shape == ref.shape else None)
        tiny = 1e-12
        top = max([float(d.max()) for d in diffs if d is not None] + [tiny * 10])
        cols = min(3, len(runs) + 1)
        rows = -(-(len(runs) + 1) // cols)
        fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 3.3 * rows), squeeze=False)
        ax = axes.flat[0]
        im = ax.imshow(ref, origin="lower", cmap="magma")
        fig.colorbar(im, ax=ax, label="exp(-18|d|)", shrink=0.85)
        ax.set_title(f"float64 oracle, {p.width}x{p.height}", fontsize=8)
        norm = LogNorm(vmin=max(tiny, top * 1e-6), vmax=top)
        for ax, (r, _), d in zip(axes.flat[1:], runs, diffs):
            if d is None:
                ax.set_title(f"{run_label(r)}: shape differs", fontsize=8); continue
            im = ax.imshow(np.maximum(d, norm.vmin), origin="lower", cmap="viridis", norm=norm)
            fig.colorbar(im, ax=ax, label="|image - oracle|", shrink=0.85)
            tol = TOLERANCE_ULPS * (UNIT_ROUNDOFF[r["precision"]] + UNIT_ROUNDOFF["float64"])
            ax.set_title(f"{run_label(r)}\nmax {d.max():.2g} = {d.max() / tol:.2g} x derived tolerance",
                         fontsize=8)
        for ax in axes.flat:
            ax.set_xlabel("pixel column i", fontsize=7); ax.set_ylabel("pixel row j", fontsize=7)
            ax.tick_params(labelsize=6)
        for ax in axes.flat[len(runs) + 1:]:
            ax.set_visible(False)
        fig.suptitle("sdf: oracle image and each backend's difference to it", fontsize=10)
        fig.tight_layout()
        return fig

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
