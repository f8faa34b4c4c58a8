"""Bouncing particles in Numba.

Particles do not interact, so one prange iteration (CPU) or one CUDA thread owns one particle and
loops over all steps in registers: race-free, one launch per run. The per-particle rollout is
written once, in the scenario's step order, and compiled for both targets. Trajectory frames are
written only when ``record_every`` asks for them (otherwise the traj arrays are empty).
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np
from numba import njit, prange
try:
    from numba import cuda   # numba-cuda; a module global, which the CUDA simulator swaps in kernels
except ImportError:          # CPU-only install
    cuda = None

from . import THREADS_PER_BLOCK, blocks, kernel_info, launch_stream, scalar_type, use_fastmath
from ..base import ScenarioKernel

CONSTANTS = ("dt", "gravity", "damping", "bounce", "radius")
STATE = ("x", "y", "vx", "vy")


@functools.cache
def rollout_function(S: type[np.floating]):
    def rollout(p, steps, record_every, dt, gravity, damping, bounce, radius, x0, y0, vx0, vy0,
                x_out, y_out, vx_out, vy_out, traj_x, traj_y):
        x = x0[p]
        y = y0[p]
        u = vx0[p]
        v = vy0[p]
        gdt = gravity * dt
        lo = S(-1.0) + radius
        hi = S(1.0) - radius
        if record_every > 0:
            traj_x[0, p] = x
            traj_y[0, p] = y
        for s in range(steps):
            v = v + gdt
            x = x + u * dt
            y = y + v * dt
            if y < radius:
                y = radius
                v = -bounce * v
                u = damping * u
            if x < lo:
                x = lo
                u = -bounce * u
            if x > hi:
                x = hi
                u = -bounce * u
            if record_every > 0:
                if (s + 1) % record_every == 0:
                    f = (s + 1) // record_every
                    traj_x[f, p] = x
                    traj_y[f, p] = y
        x_out[p] = x
        y_out[p] = y
        vx_out[p] = u
        vy_out[p] = v
    return rollout


@functools.cache
def cpu_kernel(S: type[np.floating], fastmath: bool):
    rollout = njit(fastmath=fastmath)(rollout_function(S))

    @njit(parallel=True, fastmath=fastmath)
    def particles(steps, record_every, dt, gravity, damping, bounce, radius, x0, y0, vx0, vy0,
                  x_out, y_out, vx_out, vy_out, traj_x, traj_y):
        for p in prange(x0.shape[0]):
            rollout(p, steps, record_every, dt, gravity, damping, bounce, radius, x0, y0, vx0, vy0,
                    x_out, y_out, vx_out, vy_out, traj_x, traj_y)
    return particles


@functools.cache
def cuda_kernel(S: type[np.floating], fastmath: bool):
    rollout = cuda.jit(device=True, fastmath=fastmath)(rollout_function(S))

    @cuda.jit(fastmath=fastmath)
    def particles(steps, record_every, dt, gravity, damping, bounce, radius, x0, y0, vx0, vy0,
                  x_out, y_out, vx_out, vy_out, traj_x, traj_y):
        p = cuda.grid(1)
        if p < x0.shape[0]:
            rollout(p, steps, record_every, dt, gravity, damping, bounce, radius, x0, y0, vx0, vy0,
                    x_out, y_out, vx_out, vy_out, traj_x, traj_y)
    return particles


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.device, self.fastmath, self.params = device, use_fastmath(variant), params
        frames = params.steps // params.record_every + 1 if params.record_every else 0
        traj_shape = (frames, params.n) if frames else (0, 0)
        consts = [S(inputs[k]) for k in CONSTANTS]          # typed scalars, like Warp's
        state0 = [np.ascontiguousarray(inputs[k]) for k in ("x0", "y0", "vx0", "vy0")]
        if device == "cuda":
            state0 = [cuda.to_device(a) for a in state0]
            self.state = [cuda.device_array(params.n, dtype=S) for _ in STATE]
            self.traj = [cuda.device_array(traj_shape, dtype=S) for _ in range(2)]
            fn = cuda_kernel(S, self.fastmath)[blocks(params.n), THREADS_PER_BLOCK, launch_stream()]
        else:
            self.state = [np.empty(params.n, dtype=S) for _ in STATE]
            self.traj = [np.empty(traj_shape, dtype=S) for _ in range(2)]
            fn = cpu_kernel(S, self.fastmath)
        self.fn = fn
        self.args = (params.steps, params.record_every, *consts, *state0, *self.state, *self.traj)

    def run(self) -> None:
        self.fn(*self.args)

    def outputs(self) -> dict[str, np.ndarray]:
        host = (lambda a: a.copy_to_host()) if self.device == "cuda" else np.copy
        out = {k: host(a) for k, a in zip(STATE, self.state)}
        if self.params.record_every:
            out["traj_x"], out["traj_y"] = (host(a) for a in self.traj)
        return out

    def info(self) -> dict[str, Any]:
        return kernel_info(self.device, self.fastmath)
