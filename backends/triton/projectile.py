"""Differentiable projectile in Triton, with a hand-written discrete adjoint (Triton has no autodiff).

The CuPy port (backends/cupy/projectile.py, after Numba's) as a Triton kernel: a batch of B
independent trajectories (B = 1 for the seed case), each running its own gradient descent; each
program owns BLOCK trajectories (one a thread) and runs their whole descent, so a run is one
launch with no host transfers and no allocations.

Per iteration: the forward pass in the scenario's (Warp's) operation order with the state in
registers, writing the tape the reverse sweep reads, y_s before each step and whether the hard
contact fired, every step as the CuPy and Numba ports do; the tape is (steps, B), so step s of a
program's trajectories lies at consecutive addresses (coalesced). Then the loss; then the reverse
sweep, ``adjoint`` of scenarios/projectile_adjoint.py (same operations, same order) except the
soft-contact term, taken in reverse-mode order through the forward as written,
acc = g + k*(eps*sp(z)), with d sp/dz = sigmoid(z) from the forward's own exp(-|z|) (Warp's
tape's order; see backends/numba/projectile.py for why it matters). Then history[k, b] =
loss_b(v_b,k), grad = gradient at v0, and v_b <- v_b - lr*grad_b except after the last evaluation.
Branches are ``tl.where`` selects; the contact model is a compile-time switch (CONTACT). A CTA
barrier separates each forward pass from its reverse sweep, so the sweep reads the tape whatever
thread of the program wrote it. B, steps and iters are not specialised on: every B runs the same
compiled kernel, so batch row 0 is the single trajectory's arithmetic.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import triton
import triton.language as tl

from . import download, empty, kernel_info, launch_options, put
from ..base import ScenarioKernel
from .fmath import div, exp, log
from scenarios.projectile import ProjectileParams
from ..base import Device
from scenarios.base import Precision

CONTACT = {"none": 0, "hard": 1, "soft": 2}
CONSTANTS = ("dt", "gravity", "bounce", "damping", "stiffness", "softness", "lr")
# One serial trajectory per thread, 128 a program (as CuPy's 128 threads a block).
WARPS = 4
BLOCK = 32 * WARPS


@triton.jit(do_not_specialize=["batch", "steps", "iters"])
def projectile_kernel(consts_ptr, v0_ptr, target_ptr, v_ptr, ys_ptr, hit_ptr, history_ptr, grad_ptr,
                      batch, steps, iters, CONTACT: tl.constexpr, BLOCK: tl.constexpr):
    # v0, target, v, grad: (B, 2); ys, hit: (steps, B); history: (iters + 1, B)
    T = v0_ptr.dtype.element_ty
    b = tl.program_id(0).to(tl.int64) * BLOCK + tl.arange(0, BLOCK)
    m = b < batch
    B = batch.to(tl.int64)
    dt = tl.load(consts_ptr)
    gravity = tl.load(consts_ptr + 1)
    bounce = tl.load(consts_ptr + 2)
    damping = tl.load(consts_ptr + 3)
    stiffness = tl.load(consts_ptr + 4)
    softness = tl.load(consts_ptr + 5)
    lr = tl.load(consts_ptr + 6)
    zero = tl.zeros((BLOCK,), T)
    one = zero + 1.0
    eps = zero + softness                      # tensors for fmath's libdevice calls
    tx = tl.load(target_ptr + 2 * b, mask=m, other=0.0)
    ty = tl.load(target_ptr + 2 * b + 1, mask=m, other=0.0)
    vxk = tl.load(v0_ptr + 2 * b, mask=m, other=0.0)     # v_k, the point of evaluation k
    vyk = tl.load(v0_ptr + 2 * b + 1, mask=m, other=0.0)
    gx0 = zero
    gy0 = zero
    for k in range(iters + 1):
        # forward: state in registers, the tape keeps y_s and the contact flag per step
        x = zero
        y = zero
        vx = vxk
        vy = vyk
        for s in range(steps):
            row = s * B + b
            tl.store(ys_ptr + row, y, mask=m)
            acc = zero + gravity
            if CONTACT == 2:
                z = div(-y, eps)
                sp = tl.maximum(z, 0.0) + log(1.0 + exp(-tl.abs(z)))
                acc = gravity + stiffness * (softness * sp)
            vy = vy + acc * dt
            x = x + vx * dt
            y = y + vy * dt
            if CONTACT == 1:
                fired = y < 0.0
                y = tl.where(fired, 0.0, y)
                vy = tl.where(fired, -bounce * vy, vy)
                vx = tl.where(fired, damping * vx, vx)
                tl.store(hit_ptr + row, fired.to(tl.uint8), mask=m)
            else:
                tl.store(hit_ptr + row, tl.zeros((BLOCK,), tl.uint8), mask=m)
        tl.debug_barrier()
        dx = x - tx
        dy = y - ty
        loss = dx * dx + dy * dy
        # reverse sweep: adjoints of (x, y, vx, vy) after step s -> before step s
        ax = 2.0 * dx
        ay = 2.0 * dy
        avx = zero
        avy = zero
        for r in range(steps):
            row = (steps - 1 - r) * B + b
            hit = tl.load(hit_ptr + row, mask=m, other=0) != 0
            ay = tl.where(hit, 0.0, ay)
            avy = tl.where(hit, -bounce * avy, avy)
            avx = tl.where(hit, damping * avx, avx)
            avy = avy + ay * dt                  # y1 = y + vy1*dt
            avx = avx + ax * dt                  # x1 = x + vx*dt
            if CONTACT == 2:
                # vy1 = vy + acc(y)*dt with acc = g + k*(eps*sp(z)), z = -y/eps: reverse mode
                # through the forward as written; d sp/dz = sigmoid(z), e/(1+e) for z <= 0 and
                # 1 - e/(1+e) for z > 0, with the forward's own e = exp(-|z|)
                a_sp = softness * (stiffness * (dt * avy))
                z = div(-tl.load(ys_ptr + row, mask=m, other=0.0), eps)
                e = exp(-tl.abs(z))
                a_z = e * (div(one, one + e) * a_sp)
                a_z = tl.where(z > 0.0, a_sp - a_z, a_z)
                ay = ay - div(a_z, eps)
        # the next forward pass overwrites the tape this sweep read
        tl.debug_barrier()
        tl.store(history_ptr + k * B + b, loss, mask=m)
        if k == 0:
            gx0 = avx
            gy0 = avy
        if k < iters:
            vxk = vxk - lr * avx
            vyk = vyk - lr * avy
    tl.store(grad_ptr + 2 * b, gx0, mask=m)
    tl.store(grad_ptr + 2 * b + 1, gy0, mask=m)
    tl.store(v_ptr + 2 * b, vxk, mask=m)
    tl.store(v_ptr + 2 * b + 1, vyk, mask=m)


class Kernel(ScenarioKernel):
    def __init__(self, params: ProjectileParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        self.single = params.batch == 1          # outputs without the batch axis
        self.precision = precision
        B, steps = params.batch, params.steps
        self.arrays = {"consts": put([inputs[k] for k in CONSTANTS], precision, device),
                       "v0": put(np.reshape(inputs["v0"], (B, 2)), precision, device),
                       "target": put(np.reshape(inputs["target"], (B, 2)), precision, device),
                       "v": empty((B, 2), precision, device), "ys": empty((steps, B), precision, device),
                       "hit": empty((steps, B), np.uint8, device),
                       "history": empty((params.iters + 1, B), precision, device),
                       "grad0": empty((B, 2), precision, device)}
        self.grid = (triton.cdiv(B, BLOCK),)
        self.args = (*self.arrays.values(), B, steps, params.iters)
        self.meta = {"CONTACT": CONTACT[params.contact], "BLOCK": BLOCK, "num_warps": WARPS,
                     **launch_options()}

    def run(self) -> Any:
        projectile_kernel[self.grid](*self.args, **self.meta)
        return self.arrays["history"]

    def set_input(self, name: str, value: np.ndarray) -> None:
        """Overwrite ``v0`` or ``target`` in the same device tensor (the launch arguments and any
        captured graph read it there)."""
        if name not in ("v0", "target"):
            super().set_input(name, value)
        import torch
        a = self.arrays[name]
        a.copy_(torch.from_numpy(np.array(np.reshape(value, tuple(a.shape)), dtype=self.precision)))

    def outputs(self) -> dict[str, np.ndarray]:
        hist, grad, v = (download(self.arrays[k]) for k in ("history", "grad0", "v"))
        if self.single:
            hist, grad, v = hist[:, 0], grad[0], v[0]
        return {"loss": hist[0].copy(), "grad": grad, "loss_history": hist, "v_final": v}

    def info(self) -> dict[str, Any]:
        return kernel_info(block=BLOCK, num_warps=WARPS, programs=self.grid[0], launches_per_run=1,
                           trajectories_per_thread=1, tape_layout="(steps, batch)")
