"""SAXPY in CuPy, ``out = a * x + y``.

* ``default``: a ``cupy.ElementwiseKernel``, one thread per element (CuPy's one-line idiom).
  Typed in the cell's precision (``float32 a, float32 x, ...``), so the float32 kernel is all
  float32; ``a * x + y`` contracts to one FMA under NVRTC's default, as in Warp and Numba.
* ``vector``: a ``cupy.RawKernel`` that moves 16 bytes per load and store (``float4`` in float32,
  ``double2`` in float64), the CUDA C idiom for bandwidth-bound kernels: the ElementwiseKernel
  falls short of the 90 % target at large n (docs/results/h100/report/bandwidth.md), and wider
  accesses keep more bytes in flight per thread. Each vector is one thread; the ``n % W`` tail
  elements get one thread each, after the vectors. The same arithmetic: one FMA per element under
  NVRTC's default, as the ElementwiseKernel.
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np

from . import THREADS_PER_BLOCK, blocks, kernel_info, prelude, raw_kernel, scalar_type, upload
from ..base import Precision, ScenarioKernel

# 16-byte CUDA vector type and its lanes, per precision
VECTOR = {Precision.FLOAT32: ("float4", "xyzw"), Precision.FLOAT64: ("double2", "xy")}

VECTOR_BODY = r"""
extern "C" __global__ void saxpy_vector(const real a,
    const VEC* __restrict__ xv, const VEC* __restrict__ yv, VEC* __restrict__ outv,
    const real* __restrict__ x, const real* __restrict__ y, real* __restrict__ out,
    const long long n)
{
    const long long i = (long long)blockIdx.x * blockDim.x + threadIdx.x;
    const long long vectors = n / WIDTH;
    if (i < vectors) {
        const VEC xi = xv[i];
        const VEC yi = yv[i];
        VEC o;
LANES
        outv[i] = o;
    } else {
        const long long j = vectors * WIDTH + (i - vectors);   // the tail, one element a thread
        if (j < n) out[j] = a * x[j] + y[j];
    }
}
"""


@functools.cache
def elementwise(precision: str) -> Any:
    import cupy
    t = precision
    return cupy.ElementwiseKernel(f"{t} a, {t} x, {t} y", f"{t} out", "out = a * x + y",
                                  name=f"saxpy_{t}")


def vector_width(precision: str) -> int:
    return len(VECTOR[precision][1])


def vector_source(precision: str) -> str:
    vec, lanes = VECTOR[precision]
    body = "\n".join(f"        o.{c} = a * xi.{c} + yi.{c};" for c in lanes)
    return (prelude(precision) + f"typedef {vec} VEC;\n#define WIDTH {len(lanes)}\n"
            + VECTOR_BODY.replace("LANES", body))


@functools.cache
def compiled_vector(precision: str) -> Any:
    return raw_kernel(vector_source(precision), "saxpy_vector")


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        import cupy
        S = scalar_type(precision)
        self.a = S(inputs["a"])               # a typed scalar: a Python float is a double
        self.x, self.y = upload(inputs["x"], S), upload(inputs["y"], S)
        self.out = cupy.empty(params.n, dtype=S)
        self.vector = variant == "vector"
        if self.vector:
            # 16-byte accesses need 16-byte aligned arrays (CuPy's allocations are 256-byte aligned)
            if any(a.data.ptr % 16 for a in (self.x, self.y, self.out)):
                raise RuntimeError("vector variant: an array is not 16-byte aligned")
            self.fn = compiled_vector(precision)
            width = vector_width(precision)
            self.grid = (blocks(params.n // width + params.n % width),)
            self.call = (self.grid, (THREADS_PER_BLOCK,),        # RawKernel(grid, block, args)
                         (self.a, self.x, self.y, self.out, self.x, self.y, self.out, np.int64(params.n)))
        else:
            self.fn = elementwise(precision)
            self.call = (self.a, self.x, self.y, self.out)

    def run(self) -> None:
        self.fn(*self.call)

    def outputs(self) -> dict[str, np.ndarray]:
        return {"out": self.out.get()}

    def info(self) -> dict[str, Any]:
        if self.vector:
            return kernel_info(kernel="cupy.RawKernel", loads="16-byte vectors",
                               threads_per_block=THREADS_PER_BLOCK, blocks=self.grid[0])
        return kernel_info(kernel="cupy.ElementwiseKernel")
