"""The kernels' division, square root and transcendental functions, chosen once per process.

Compiled (CUDA): libdevice's correctly rounded division and square root (``div.rn``,
``sqrt.rn``) and its ``exp``/``log``/``sin`` (``__nv_expf`` ... in float32, ``__nv_exp`` ... in
float64): what CUDA C's ``/``, ``sqrtf``, ``expf`` are under NVRTC's defaults, so the work is the
CuPy port's (linked without flush-to-zero: ``launch_options``). Triton's own float32 ``/``,
``tl.sqrt`` and ``tl.exp`` are approximate instructions (``div.full.f32``,
``sqrt.approx.ftz.f32``, ``ex2.approx`` after a multiply by log2 e).
Interpreted (TRITON_INTERPRET=1): the interpreter has no libdevice (extern calls raise there), so
the same names are Triton's ``/`` and ``tl.*`` functions, which it evaluates with NumPy's IEEE
division and square root and its exp/log/sin.
Every helper dispatches on its operands' dtype; pass tensors (not Python floats, which Triton
would type fp32 before libdevice sees them).
"""
from __future__ import annotations

import triton
import triton.language as tl

from . import interpreting

if interpreting():
    @triton.jit
    def div(a, b):
        return a / b

    @triton.jit
    def sqrt(a):
        return tl.sqrt(a)

    @triton.jit
    def exp(a):
        return tl.exp(a)

    @triton.jit
    def log(a):
        return tl.log(a)

    @triton.jit
    def sin(a):
        return tl.sin(a)
else:
    from triton.language.extra import libdevice

    @triton.jit
    def div(a, b):
        return libdevice.div_rn(a, b)

    @triton.jit
    def sqrt(a):
        return libdevice.sqrt_rn(a)

    @triton.jit
    def exp(a):
        return libdevice.exp(a)

    @triton.jit
    def log(a):
        return libdevice.log(a)

    @triton.jit
    def sin(a):
        return libdevice.sin(a)
