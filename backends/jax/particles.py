"""Bouncing particles in JAX: the state is four vectors, stepped by one jitted loop.

Particles are independent, so each step is a handful of fused elementwise ops over all particles;
the step loop is a lax.fori_loop (static trip count, ``unroll`` steps per trip) inside the one
jitted program. With
``record_every`` > 0 an outer loop runs ``record_every`` steps at a time and writes each frame into
the trajectory buffers in place (dynamic_update_slice on the loop carry), frame 0 being the
initial state; without it no trajectory is kept at all.
The previous call's outputs are donated, so a steady-state call allocates no new output buffers.
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np

from scenarios.particles import CONSTANTS, INITIAL, STATE, n_frames

from . import UNROLL, Program, jax_device, jax_dtype, put
from ..base import ScenarioKernel
from scenarios.particles import ParticlesParams
from ..base import Device
from scenarios.base import Precision


def _rollout(steps: int, record_every: int, unroll: int, state0, consts, out):
    import jax.numpy as jnp
    from jax import lax
    dt, gravity, damping, bounce, radius = consts
    one = jnp.ones((), dtype=dt.dtype)
    gdt = gravity * dt
    lo = -one + radius
    hi = one - radius

    def step(_, s):
        # The scenario's exact order: velocity, positions, then the three clamps in sequence.
        x, y, u, v = s
        v = v + gdt
        x = x + u * dt
        y = y + v * dt
        hit = y < radius
        y = jnp.where(hit, radius, y)
        v = jnp.where(hit, -bounce * v, v)
        u = jnp.where(hit, damping * u, u)
        hit = x < lo
        x = jnp.where(hit, lo, x)
        u = jnp.where(hit, -bounce * u, u)
        hit = x > hi
        x = jnp.where(hit, hi, x)
        u = jnp.where(hit, -bounce * u, u)
        return x, y, u, v

    if not record_every:
        return lax.fori_loop(0, steps, step, tuple(state0), unroll=max(1, min(unroll, steps)))

    traj_x, traj_y = out[4], out[5]          # donated: written in place, frame by frame
    traj_x = traj_x.at[0].set(state0[0])
    traj_y = traj_y.at[0].set(state0[1])

    def frame(f, carry):
        s, tx, ty = carry
        s = lax.fori_loop(0, record_every, step, s, unroll=max(1, min(unroll, record_every)))
        return s, tx.at[f].set(s[0]), ty.at[f].set(s[1])

    frames = steps // record_every
    s, traj_x, traj_y = lax.fori_loop(1, frames + 1, frame, (tuple(state0), traj_x, traj_y))
    rest = steps - frames * record_every                    # steps after the last frame
    s = lax.fori_loop(0, rest, step, s, unroll=max(1, min(unroll, rest)))
    return (*s, traj_x, traj_y)


class Kernel(ScenarioKernel):
    def __init__(self, params: ParticlesParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str, unroll: int | None = None) -> None:
        import jax.numpy as jnp
        dev = jax_device(device)
        self.params = params
        self.state0 = tuple(put(inputs[k], precision, dev) for k in INITIAL)
        self.consts = tuple(put(inputs[k], precision, dev) for k in CONSTANTS)
        dt = jax_dtype(precision)
        out = [jnp.empty(params.n, dtype=dt, device=dev) for _ in range(4)]
        if params.record_every:
            out += [jnp.empty((n_frames(params), params.n), dtype=dt, device=dev) for _ in range(2)]
        self.out = tuple(out)
        self.unroll = unroll = UNROLL[device] if unroll is None else unroll
        fn = functools.partial(_rollout, params.steps, params.record_every, unroll)
        self.program = Program(fn, donate=(2,))

    def run(self) -> Any:
        self.out = self.program(self.state0, self.consts, self.out)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {k: np.asarray(a) for k, a in zip((*STATE, "traj_x", "traj_y"), self.out)}

    def info(self) -> dict[str, Any]:
        return {**self.program.info(), "loop": "lax.fori_loop over steps, vectorised over particles",
                "unroll": self.unroll}
