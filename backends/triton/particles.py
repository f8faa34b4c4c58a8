"""Bouncing particles in Triton: one launch for the whole rollout.

Particles do not interact, so each program owns BLOCK particles and keeps their state in
registers through every step (one particle a thread: BLOCK = 32 * WARPS), as the CuPy and Numba
CUDA kernels do; the steps loop runs inside the kernel. The step is the scenario's, in its order,
with the contact branches as ``tl.where`` selects (the same values as the branches). Trajectory
frames (frames, n) are written only when ``record_every`` asks (RECORD is a compile-time switch,
so the plain rollout has no frame logic). The constants come from a tensor of the cell's dtype;
gdt = gravity*dt, lo = -1 + radius and hi = 1 - radius are formed once per program, as in the other
ports. n, steps and record_every are not specialised on: one compiled kernel for every size.
"""
from __future__ import annotations

from typing import Any

import numpy as np
import triton
import triton.language as tl

from scenarios.particles import CONSTANTS, INITIAL, STATE, n_frames

from . import download, empty, kernel_info, launch_options, put
from ..base import ScenarioKernel
from scenarios.particles import ParticlesParams
from ..base import Device
from scenarios.base import Precision
# One particle a thread, 128 threads a program (a serial rollout per thread; smaller programs
# spread a modest n over more SMs).
WARPS = 4
BLOCK = 32 * WARPS


@triton.jit(do_not_specialize=["n", "steps", "record_every"])
def particles_kernel(consts_ptr, x0_ptr, y0_ptr, vx0_ptr, vy0_ptr,
                     x_ptr, y_ptr, vx_ptr, vy_ptr, traj_x_ptr, traj_y_ptr,
                     n, steps, record_every, RECORD: tl.constexpr, BLOCK: tl.constexpr):
    p = tl.program_id(0).to(tl.int64) * BLOCK + tl.arange(0, BLOCK)
    m = p < n
    dt = tl.load(consts_ptr)
    gravity = tl.load(consts_ptr + 1)
    damping = tl.load(consts_ptr + 2)
    bounce = tl.load(consts_ptr + 3)
    radius = tl.load(consts_ptr + 4)
    x = tl.load(x0_ptr + p, mask=m, other=0.0)
    y = tl.load(y0_ptr + p, mask=m, other=0.0)
    u = tl.load(vx0_ptr + p, mask=m, other=0.0)
    v = tl.load(vy0_ptr + p, mask=m, other=0.0)
    gdt = gravity * dt
    lo = -1.0 + radius
    hi = 1.0 - radius
    if RECORD:
        tl.store(traj_x_ptr + p, x, mask=m)
        tl.store(traj_y_ptr + p, y, mask=m)
    for s in range(steps):
        v = v + gdt
        x = x + u * dt
        y = y + v * dt
        floor = y < radius
        y = tl.where(floor, radius, y)
        v = tl.where(floor, -bounce * v, v)
        u = tl.where(floor, damping * u, u)
        left = x < lo
        x = tl.where(left, lo, x)
        u = tl.where(left, -bounce * u, u)
        right = x > hi
        x = tl.where(right, hi, x)
        u = tl.where(right, -bounce * u, u)
        if RECORD:
            if (s + 1) % record_every == 0:
                f = ((s + 1) // record_every).to(tl.int64) * n
                tl.store(traj_x_ptr + f + p, x, mask=m)
                tl.store(traj_y_ptr + f + p, y, mask=m)
    tl.store(x_ptr + p, x, mask=m)
    tl.store(y_ptr + p, y, mask=m)
    tl.store(vx_ptr + p, u, mask=m)
    tl.store(vy_ptr + p, v, mask=m)


class Kernel(ScenarioKernel):
    def __init__(self, params: ParticlesParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        self.params = params
        n = params.n
        frames = n_frames(params)
        self.consts = put([inputs[k] for k in CONSTANTS], precision, device)
        self.state0 = [put(inputs[k], precision, device) for k in INITIAL]
        self.state = [empty((n,), precision, device) for _ in STATE]
        # without frames the kernel never touches these: one element each keeps real pointers
        self.traj = [empty((frames, n) if frames else (1,), precision, device) for _ in range(2)]
        self.grid = (triton.cdiv(n, BLOCK),)
        self.args = (self.consts, *self.state0, *self.state, *self.traj, n, params.steps,
                     params.record_every)
        self.meta = {"RECORD": bool(frames), "BLOCK": BLOCK, "num_warps": WARPS, **launch_options()}

    def run(self) -> Any:
        particles_kernel[self.grid](*self.args, **self.meta)
        return self.state[0]

    def outputs(self) -> dict[str, np.ndarray]:
        out = {k: download(a) for k, a in zip(STATE, self.state)}
        if self.params.record_every:
            out["traj_x"], out["traj_y"] = (download(a) for a in self.traj)
        return out

    def info(self) -> dict[str, Any]:
        return kernel_info(block=BLOCK, num_warps=WARPS, programs=self.grid[0], launches_per_run=1)
