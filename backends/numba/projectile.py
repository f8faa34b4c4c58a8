"""Differentiable projectile in Numba, with a hand-written discrete adjoint (Numba has no autodiff).

A batch of B independent trajectories (B = 1 for the seed case), each running its own gradient
descent. One compiled function, ``descend``, runs one trajectory's whole descent and is compiled
for both targets: on the CPU an ``njit(parallel=True)`` kernel calls it in a ``prange`` over the
trajectories (Numba's thread pool, ``numba.get_num_threads()`` threads), on CUDA a kernel with one
thread per trajectory (1-D grid over B, up to THREADS_PER_BLOCK threads a block) calls it as a
device function. A run is one call / one launch, with no host transfers and no allocations.

Per iteration, ``descend`` runs the forward pass in Warp's operation order with the state in
registers, keeping on a preallocated tape what the reverse sweep reads: y_s before each step (for
the soft contact's d acc/d y) and whether the hard contact fired, 1 value + 1 flag per step and
trajectory, the least a reverse sweep needs without recomputing the forward. The tape is
(steps, B) on CUDA, so consecutive threads touch consecutive addresses (coalesced), and (B, steps)
on the CPU, so each thread's tape is contiguous and stays in its cache; ``descend`` sees one
trajectory's column or row. Then the loss; then the reverse sweep, which is ``adjoint`` of
scenarios/projectile_adjoint.py (same operations, same order) except the soft-contact term: that one is
taken in reverse-mode order through the forward as written, acc = g + k*(eps*sp(z)), with
d sp/dz = sigmoid(z) evaluated from the forward's own exp(-|z|). That is the order Warp's tape
uses, and the gradient-descent history of the soft contact amplifies one-ulp differences in the
gradient ~1e7-fold over 20 iterations, so any other order leaves float64 ~1e-8 away from Warp
(still well within the scenario's derived bound). Then history[k, b] = loss_b(v_b,k), grad =
gradient at v0, and v_b <- v_b - lr*grad_b except after the last evaluation. Every trajectory's
arithmetic is the same whatever B (one compiled specialisation for every B), so on the CPU batch
row 0 equals the batch = 1 run bit for bit.
"""
from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np
from numba import njit, prange
try:
    from numba import cuda   # numba-cuda; a module global, which the CUDA simulator swaps in kernels
except ImportError:          # CPU-only install
    cuda = None

from . import launch_stream, scalar_type, use_fastmath
from ..base import ScenarioKernel

CONTACT = {"none": 0, "hard": 1, "soft": 2}
CONSTANTS = ("dt", "gravity", "bounce", "damping", "stiffness", "softness", "lr")
# One serial trajectory per thread: smaller blocks spread a modest batch over more SMs.
THREADS_PER_BLOCK = 128


@functools.cache
def descend_function(S: type[np.floating]):
    def descend(steps, iters, contact, dt, gravity, bounce, damping, stiffness, softness, lr,
                vx0, vy0, tx, ty, ys, hit, history):
        """One trajectory's descent from (vx0, vy0) to target (tx, ty); ys, hit: its tape (steps,),
        history: its losses (iters + 1,). Returns (gradient at v0, final v)."""
        zero = S(0.0)
        one = S(1.0)
        two = S(2.0)
        vx0k = vx0                       # v_k, the point of evaluation k
        vy0k = vy0
        gx0 = zero
        gy0 = zero
        for k in range(iters + 1):
            # forward: state in registers, the tape keeps y_s and the contact flag per step
            x = zero
            y = zero
            vx = vx0k
            vy = vy0k
            for s in range(steps):
                ys[s] = y
                acc = gravity
                if contact == 2:
                    z = -y / softness
                    sp = max(z, zero) + math.log(one + math.exp(-abs(z)))
                    acc = gravity + stiffness * (softness * sp)
                vy = vy + acc * dt
                x = x + vx * dt
                y = y + vy * dt
                fired = contact == 1 and y < zero
                if fired:
                    y = zero
                    vy = -bounce * vy
                    vx = damping * vx
                hit[s] = fired
            dx = x - tx
            dy = y - ty
            loss = dx * dx + dy * dy
            # reverse sweep: adjoints of (x, y, vx, vy) after step s -> before step s
            ax = two * dx
            ay = two * dy
            avx = zero
            avy = zero
            for s in range(steps - 1, -1, -1):
                if hit[s]:
                    ay = zero
                    avy = -bounce * avy
                    avx = damping * avx
                avy = avy + ay * dt              # y1 = y + vy1*dt
                avx = avx + ax * dt              # x1 = x + vx*dt
                if contact == 2:
                    # vy1 = vy + acc(y)*dt with acc = g + k*(eps*sp(z)), z = -y/eps: reverse mode
                    # through the forward as written; d sp/dz = sigmoid(z), which is e/(1+e) for
                    # z <= 0 and 1 - e/(1+e) for z > 0, with the forward's own e = exp(-|z|).
                    a_sp = softness * (stiffness * (dt * avy))
                    z = -ys[s] / softness
                    e = math.exp(-abs(z))
                    a_z = e * ((one / (one + e)) * a_sp)
                    if z > zero:
                        a_z = a_sp - a_z
                    ay = ay - a_z / softness
            history[k] = loss
            if k == 0:
                gx0 = avx
                gy0 = avy
            if k < iters:
                vx0k = vx0k - lr * avx
                vy0k = vy0k - lr * avy
        return gx0, gy0, vx0k, vy0k
    return descend


@functools.cache
def cpu_kernel(S: type[np.floating], fastmath: bool):
    descend = njit(fastmath=fastmath)(descend_function(S))

    @njit(parallel=True, fastmath=fastmath)
    def projectile(steps, iters, contact, dt, gravity, bounce, damping, stiffness, softness, lr,
                   v0, target, v, ys, hit, history, grad0):
        # ys, hit: (B, steps), one contiguous row per trajectory; history: (iters + 1, B)
        for b in prange(v0.shape[0]):
            gx, gy, vx, vy = descend(steps, iters, contact, dt, gravity, bounce, damping,
                                     stiffness, softness, lr, v0[b, 0], v0[b, 1],
                                     target[b, 0], target[b, 1], ys[b], hit[b], history[:, b])
            grad0[b, 0] = gx
            grad0[b, 1] = gy
            v[b, 0] = vx
            v[b, 1] = vy
    return projectile


@functools.cache
def cuda_kernel(S: type[np.floating], fastmath: bool):
    descend = cuda.jit(device=True, fastmath=fastmath)(descend_function(S))

    @cuda.jit(fastmath=fastmath)
    def projectile(steps, iters, contact, dt, gravity, bounce, damping, stiffness, softness, lr,
                   v0, target, v, ys, hit, history, grad0):
        # one thread per trajectory; ys, hit: (steps, B) and history (iters + 1, B), so step s of
        # consecutive threads lies at consecutive addresses
        b = cuda.grid(1)
        if b < v0.shape[0]:
            gx, gy, vx, vy = descend(steps, iters, contact, dt, gravity, bounce, damping,
                                     stiffness, softness, lr, v0[b, 0], v0[b, 1],
                                     target[b, 0], target[b, 1], ys[:, b], hit[:, b], history[:, b])
            grad0[b, 0] = gx
            grad0[b, 1] = gy
            v[b, 0] = vx
            v[b, 1] = vy
    return projectile


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.device, self.fastmath = device, use_fastmath(variant)
        self.single = params.batch == 1          # outputs without the batch axis
        B, steps = params.batch, params.steps
        consts = [S(inputs[k]) for k in CONSTANTS]          # typed scalars, like Warp's
        tape = (steps, B) if device == "cuda" else (B, steps)
        arrays = {"v0": np.ascontiguousarray(inputs["v0"], S).reshape(B, 2),
                  "target": np.ascontiguousarray(inputs["target"], S).reshape(B, 2),
                  "v": np.empty((B, 2), S), "ys": np.empty(tape, S),
                  "hit": np.empty(tape, np.bool_), "history": np.empty((params.iters + 1, B), S),
                  "grad0": np.empty((B, 2), S)}
        if device == "cuda":
            arrays = {k: cuda.to_device(a) for k, a in arrays.items()}
            self.launch = (-(-B // min(B, THREADS_PER_BLOCK)), min(B, THREADS_PER_BLOCK))
            self.fn = cuda_kernel(S, self.fastmath)[(*self.launch, launch_stream())]
        else:
            self.fn = cpu_kernel(S, self.fastmath)
        self.arrays = arrays
        self.args = (steps, params.iters, CONTACT[params.contact], *consts, *arrays.values())

    def run(self) -> None:
        self.fn(*self.args)

    def set_input(self, name: str, value: np.ndarray) -> None:
        if name not in ("v0", "target"):
            super().set_input(name, value)
        a = self.arrays[name]              # the launch arguments hold this same array
        if self.device == "cuda":
            a.copy_to_device(np.ascontiguousarray(value, a.dtype).reshape(a.shape))
        else:
            a[...] = np.reshape(value, a.shape)

    def outputs(self) -> dict[str, np.ndarray]:
        host = {k: (a.copy_to_host() if self.device == "cuda" else a.copy())
                for k, a in self.arrays.items() if k in ("history", "grad0", "v")}
        hist, grad, v = host["history"], host["grad0"], host["v"]
        if self.single:
            hist, grad, v = hist[:, 0], grad[0], v[0]
        return {"loss": hist[0].copy(), "grad": grad, "loss_history": hist, "v_final": v}

    def info(self) -> dict[str, Any]:
        b = self.arrays["v0"].shape[0]
        if self.device == "cuda":
            return {"threads_per_block": self.launch[1], "blocks": self.launch[0],
                    "launches_per_run": 1, "trajectories_per_thread": 1,
                    "tape_layout": "(steps, batch)", "fastmath": self.fastmath}
        import numba
        threads = numba.get_num_threads()       # prange's pool; at most one per trajectory busy
        return {"parallel": True, "threads": threads, "busy_threads": min(threads, b),
                "tape_layout": "(batch, steps)", "fastmath": self.fastmath}
