"""Bouncing particles in Numba.

Particles do not interact. One step of one particle is written once (``step_function``, in the
scenario's step order, each contact a select) and compiled for both targets:

* CUDA: one thread owns one particle and loops over all steps in registers (one launch per run).
* CPU: each ``prange`` iteration owns a chunk of particles and runs the steps outside, the
  particles of its chunk inside, so LLVM vectorises the inner loop across particles (SIMD). The
  one-particle-per-iteration form runs every step as one serial chain of dependent operations,
  many times slower (docs/results/cpu/report/particles.md), with bit-identical results
  (tests/backends/test_numba.py).

Trajectory frames are written only when ``record_every`` asks for them (otherwise the traj arrays
are empty).
"""
from __future__ import annotations

import functools
from typing import Any

import numba
import numpy as np
from numba import njit, prange
try:
    from numba import cuda   # numba-cuda; a module global, which the CUDA simulator swaps in kernels
except ImportError:          # CPU-only install
    cuda = None

from scenarios.particles import CONSTANTS, INITIAL, STATE, n_frames

from . import THREADS_PER_BLOCK, blocks, kernel_info, launch_stream, scalar_type, use_fastmath
from ..base import ScenarioKernel

# CPU particles per prange iteration: a few SIMD registers' worth and L1-resident (4 arrays x
# 256 x 8 bytes), fewer when n is small, so that every thread gets a chunk.
CHUNK = 256


def cpu_chunk(n: int) -> int:
    return max(1, min(CHUNK, -(-n // numba.get_num_threads())))


@functools.cache
def step_function(S: type[np.floating]):
    def step(x, y, u, v, gdt, dt, damping, bounce, radius, lo, hi):
        v = v + gdt
        x = x + u * dt
        y = y + v * dt
        floor = y < radius
        y = radius if floor else y
        v = -bounce * v if floor else v
        u = damping * u if floor else u
        left = x < lo
        x = lo if left else x
        u = -bounce * u if left else u
        right = x > hi
        x = hi if right else x
        u = -bounce * u if right else u
        return x, y, u, v
    return step


@functools.cache
def cpu_kernel(S: type[np.floating], fastmath: bool):
    step = njit(inline="always", fastmath=fastmath)(step_function(S))

    @njit(parallel=True, fastmath=fastmath)
    def particles(steps, record_every, chunk, dt, gravity, damping, bounce, radius, x0, y0, vx0, vy0,
                  x_out, y_out, vx_out, vy_out, traj_x, traj_y):
        n = x0.shape[0]
        gdt = gravity * dt
        lo = S(-1.0) + radius
        hi = S(1.0) - radius
        for c in prange((n + chunk - 1) // chunk):
            a = c * chunk
            b = min(n, a + chunk)
            x = x0[a:b].copy()
            y = y0[a:b].copy()
            u = vx0[a:b].copy()
            v = vy0[a:b].copy()
            if record_every > 0:
                traj_x[0, a:b] = x
                traj_y[0, a:b] = y
            for s in range(steps):
                for j in range(b - a):
                    x[j], y[j], u[j], v[j] = step(x[j], y[j], u[j], v[j], gdt, dt, damping, bounce,
                                                  radius, lo, hi)
                if record_every > 0 and (s + 1) % record_every == 0:
                    f = (s + 1) // record_every
                    traj_x[f, a:b] = x
                    traj_y[f, a:b] = y
            x_out[a:b] = x
            y_out[a:b] = y
            vx_out[a:b] = u
            vy_out[a:b] = v
    return particles


@functools.cache
def cuda_kernel(S: type[np.floating], fastmath: bool):
    step = cuda.jit(device=True, fastmath=fastmath)(step_function(S))

    @cuda.jit(fastmath=fastmath)
    def particles(steps, record_every, dt, gravity, damping, bounce, radius, x0, y0, vx0, vy0,
                  x_out, y_out, vx_out, vy_out, traj_x, traj_y):
        p = cuda.grid(1)
        if p < x0.shape[0]:
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
                x, y, u, v = step(x, y, u, v, gdt, dt, damping, bounce, radius, lo, hi)
                if record_every > 0:
                    if (s + 1) % record_every == 0:
                        f = (s + 1) // record_every
                        traj_x[f, p] = x
                        traj_y[f, p] = y
            x_out[p] = x
            y_out[p] = y
            vx_out[p] = u
            vy_out[p] = v
    return particles


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.device, self.fastmath, self.params = device, use_fastmath(variant), params
        frames = n_frames(params)
        traj_shape = (frames, params.n) if frames else (0, 0)
        consts = [S(inputs[k]) for k in CONSTANTS]          # typed scalars, like Warp's
        state0 = [np.ascontiguousarray(inputs[k]) for k in INITIAL]
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
        chunk = () if device == "cuda" else (cpu_chunk(params.n),)    # the CPU kernel's only extra
        self.args = (params.steps, params.record_every, *chunk, *consts, *state0, *self.state, *self.traj)

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
