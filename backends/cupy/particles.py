"""Bouncing particles in CuPy: a ``cupy.RawKernel``, one thread per particle over all steps.

Particles do not interact, so a thread keeps its particle in registers through every step (one
launch per run, race-free), in the scenario's step order exactly as Warp's kernel; trajectory
frames (frames, n) are written only when ``record_every`` asks for them.
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np

from scenarios.particles import CONSTANTS, INITIAL, STATE, n_frames

from . import THREADS_PER_BLOCK, blocks, empty, kernel_info, prelude, raw_kernel, scalar_type, upload
from ..base import ScenarioKernel

BODY = r"""
extern "C" __global__ void particles(
    const int n, const int steps, const int record_every,
    const real dt, const real gravity, const real damping, const real bounce, const real radius,
    const real* __restrict__ x0, const real* __restrict__ y0,
    const real* __restrict__ vx0, const real* __restrict__ vy0,
    real* __restrict__ x_out, real* __restrict__ y_out,
    real* __restrict__ vx_out, real* __restrict__ vy_out,
    real* __restrict__ traj_x, real* __restrict__ traj_y)
{
    const long long p = (long long)blockIdx.x * blockDim.x + threadIdx.x;   // n may near 2^31
    if (p >= n) return;
    real x = x0[p];
    real y = y0[p];
    real u = vx0[p];
    real v = vy0[p];
    const real gdt = gravity * dt;
    const real lo = R(-1.0) + radius;
    const real hi = R(1.0) - radius;
    if (record_every > 0) {
        traj_x[p] = x;
        traj_y[p] = y;
    }
    for (int s = 0; s < steps; ++s) {
        v = v + gdt;
        x = x + u * dt;
        y = y + v * dt;
        if (y < radius) {
            y = radius;
            v = -bounce * v;
            u = damping * u;
        }
        if (x < lo) {
            x = lo;
            u = -bounce * u;
        }
        if (x > hi) {
            x = hi;
            u = -bounce * u;
        }
        if (record_every > 0 && (s + 1) % record_every == 0) {
            const long long f = (s + 1) / record_every;
            traj_x[f * n + p] = x;
            traj_y[f * n + p] = y;
        }
    }
    x_out[p] = x;
    y_out[p] = y;
    vx_out[p] = u;
    vy_out[p] = v;
}
"""


def source(precision: str) -> str:
    return prelude(precision) + BODY


@functools.cache
def compiled(precision: str) -> Any:
    return raw_kernel(source(precision), "particles")


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.params = params
        self.fn = compiled(precision)
        frames = n_frames(params)
        traj_shape = (frames, params.n) if frames else (0, 0)
        consts = [S(inputs[k]) for k in CONSTANTS]          # typed scalars, like Warp's
        self.state0 = [upload(inputs[k], S) for k in INITIAL]
        self.state = [empty(params.n, S) for _ in STATE]
        self.traj = [empty(traj_shape, S) for _ in range(2)]
        self.grid = (blocks(params.n),)
        self.args = (np.int32(params.n), np.int32(params.steps), np.int32(params.record_every),
                     *consts, *self.state0, *self.state, *self.traj)

    def run(self) -> None:
        self.fn(self.grid, (THREADS_PER_BLOCK,), self.args)

    def outputs(self) -> dict[str, np.ndarray]:
        out = {k: a.get() for k, a in zip(STATE, self.state)}
        if self.params.record_every:
            out["traj_x"], out["traj_y"] = (a.get() for a in self.traj)
        return out

    def info(self) -> dict[str, Any]:
        return kernel_info(kernel="cupy.RawKernel", threads_per_block=THREADS_PER_BLOCK,
                           blocks=self.grid[0])
