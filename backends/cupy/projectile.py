"""Differentiable projectile in CuPy: a ``cupy.RawKernel`` with a hand-written discrete adjoint.

CuPy has no autodiff, so this is Numba's port in CUDA C (backends/numba/projectile.py): a batch of
B independent trajectories (B = 1 for the seed case), one thread per trajectory running its whole
gradient descent, so a run is one launch with no host transfers and no allocations.

Per iteration: the forward pass in Warp's operation order with the state in registers, keeping on
a preallocated tape what the reverse sweep reads, y_s before each step (the soft contact's
d acc/d y) and whether the hard contact fired, written every step as Numba's port does; the tape
is (steps, B), so step s of consecutive threads lies at consecutive addresses (coalesced). Then the
loss; then the reverse sweep, ``adjoint`` of scenarios/projectile_adjoint.py (same operations, same order)
except the soft-contact term, which is taken in reverse-mode order through the forward as written,
acc = g + k*(eps*sp(z)), with d sp/dz = sigmoid(z) from the forward's own exp(-|z|): Warp's tape's
order, which Numba's docstring explains (the soft-contact descent amplifies one-ulp gradient
differences ~1e7-fold). Then history[k, b] = loss_b(v_b,k), grad = gradient at v0, and
v_b <- v_b - lr*grad_b except after the last evaluation. Targets come from ``target`` (B, 2).
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np

from . import empty, kernel_info, prelude, raw_kernel, scalar_type, upload
from ..base import ScenarioKernel

CONTACT = {"none": 0, "hard": 1, "soft": 2}
CONSTANTS = ("dt", "gravity", "bounce", "damping", "stiffness", "softness", "lr")
# One serial trajectory per thread: smaller blocks spread a modest batch over more SMs (as Numba).
THREADS_PER_BLOCK = 128

BODY = r"""
extern "C" __global__ void projectile(
    const int batch, const int steps, const int iters, const int contact,
    const real dt, const real gravity, const real bounce, const real damping,
    const real stiffness, const real softness, const real lr,
    const real* __restrict__ v0, const real* __restrict__ target,
    real* __restrict__ v, real* __restrict__ ys, unsigned char* __restrict__ hit,
    real* __restrict__ history, real* __restrict__ grad0)
{
    // v0, target, v, grad0: (B, 2); ys, hit: (steps, B); history: (iters + 1, B)
    const long long b = (long long)blockIdx.x * blockDim.x + threadIdx.x;
    if (b >= batch) return;
    const long long B = batch;
    const real zero = R(0.0);
    const real one = R(1.0);
    const real two = R(2.0);
    const real tx = target[2 * b];
    const real ty = target[2 * b + 1];
    real vxk = v0[2 * b];              // v_k, the point of evaluation k
    real vyk = v0[2 * b + 1];
    real gx0 = zero;
    real gy0 = zero;
    for (int k = 0; k <= iters; ++k) {
        // forward: state in registers, the tape keeps y_s and the contact flag per step
        real x = zero;
        real y = zero;
        real vx = vxk;
        real vy = vyk;
        for (int s = 0; s < steps; ++s) {
            ys[s * B + b] = y;
            real acc = gravity;
            if (contact == 2) {
                const real z = -y / softness;
                const real sp = FMAX(z, zero) + LOG(one + EXP(-FABS(z)));
                acc = gravity + stiffness * (softness * sp);
            }
            vy = vy + acc * dt;
            x = x + vx * dt;
            y = y + vy * dt;
            const bool fired = contact == 1 && y < zero;
            if (fired) {
                y = zero;
                vy = -bounce * vy;
                vx = damping * vx;
            }
            hit[s * B + b] = fired;
        }
        const real dx = x - tx;
        const real dy = y - ty;
        const real loss = dx * dx + dy * dy;
        // reverse sweep: adjoints of (x, y, vx, vy) after step s -> before step s
        const real ax = two * dx;
        real ay = two * dy;
        real avx = zero;
        real avy = zero;
        for (int s = steps - 1; s >= 0; --s) {
            if (hit[s * B + b]) {
                ay = zero;
                avy = -bounce * avy;
                avx = damping * avx;
            }
            avy = avy + ay * dt;             // y1 = y + vy1*dt
            avx = avx + ax * dt;             // x1 = x + vx*dt
            if (contact == 2) {
                // vy1 = vy + acc(y)*dt with acc = g + k*(eps*sp(z)), z = -y/eps: reverse mode
                // through the forward as written; d sp/dz = sigmoid(z), e/(1+e) for z <= 0 and
                // 1 - e/(1+e) for z > 0, with the forward's own e = exp(-|z|)
                const real a_sp = softness * (stiffness * (dt * avy));
                const real z = -ys[s * B + b] / softness;
                const real e = EXP(-FABS(z));
                real a_z = e * ((one / (one + e)) * a_sp);
                if (z > zero) a_z = a_sp - a_z;
                ay = ay - a_z / softness;
            }
        }
        history[k * B + b] = loss;
        if (k == 0) {
            gx0 = avx;
            gy0 = avy;
        }
        if (k < iters) {
            vxk = vxk - lr * avx;
            vyk = vyk - lr * avy;
        }
    }
    grad0[2 * b] = gx0;
    grad0[2 * b + 1] = gy0;
    v[2 * b] = vxk;
    v[2 * b + 1] = vyk;
}
"""


def source(precision: str) -> str:
    return prelude(precision) + BODY


@functools.cache
def compiled(precision: str) -> Any:
    return raw_kernel(source(precision), "projectile")


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.fn = compiled(precision)
        self.single = params.batch == 1          # outputs without the batch axis
        B, steps = params.batch, params.steps
        consts = [S(inputs[k]) for k in CONSTANTS]          # typed scalars, like Warp's
        self.arrays = {"v0": upload(np.reshape(inputs["v0"], (B, 2)), S),
                       "target": upload(np.reshape(inputs["target"], (B, 2)), S),
                       "v": empty((B, 2), S), "ys": empty((steps, B), S),
                       "hit": empty((steps, B), np.uint8),
                       "history": empty((params.iters + 1, B), S), "grad0": empty((B, 2), S)}
        tpb = min(B, THREADS_PER_BLOCK)
        self.launch = ((-(-B // tpb),), (tpb,))
        self.args = (np.int32(B), np.int32(steps), np.int32(params.iters),
                     np.int32(CONTACT[params.contact]), *consts, *self.arrays.values())

    def run(self) -> None:
        self.fn(*self.launch, self.args)

    def set_input(self, name: str, value: np.ndarray) -> None:
        """Overwrite ``v0`` or ``target`` in the same device buffer (the launch arguments and any
        captured graph read it there)."""
        if name not in ("v0", "target"):
            super().set_input(name, value)
        a = self.arrays[name]
        a.set(np.ascontiguousarray(value, a.dtype).reshape(a.shape))

    def outputs(self) -> dict[str, np.ndarray]:
        hist, grad, v = (self.arrays[k].get() for k in ("history", "grad0", "v"))
        if self.single:
            hist, grad, v = hist[:, 0], grad[0], v[0]
        return {"loss": hist[0].copy(), "grad": grad, "loss_history": hist, "v_final": v}

    def info(self) -> dict[str, Any]:
        (blocks,), (tpb,) = self.launch
        return kernel_info(kernel="cupy.RawKernel", threads_per_block=tpb, blocks=blocks,
                           launches_per_run=1, trajectories_per_thread=1,
                           tape_layout="(steps, batch)")
