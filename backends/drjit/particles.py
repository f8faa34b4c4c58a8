"""Bouncing particles in Dr.Jit: one symbolic ``dr.while_loop`` over the steps, one kernel per run.

The state is four arrays over the particles; the loop over time steps is a symbolic
``dr.while_loop`` (a step counter in the loop state, the body traced once), so the whole rollout
compiles into one kernel in which each thread (SIMD lane on the CPU) keeps its particle in
registers for all steps. With ``record_every`` > 0 the body also scatters every
``record_every``-th state into the trajectory buffers (a masked ``dr.scatter``, a side effect of
the same kernel); frame 0 is the initial state, written by the same kernel.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from scenarios.particles import CONSTANTS, INITIAL, STATE, n_frames

from . import download, fast_math, jit_module, real_type, scalar, upload
from ..base import ScenarioKernel
from scenarios.particles import ParticlesParams
from ..base import Device
from scenarios.base import Precision


def rollout(steps: int, record_every: int, state: tuple, c: dict[str, Any], uint: Any,
            traj: tuple | None = None) -> tuple:
    """The scenario's steps from ``state`` (x, y, u, v); frames scattered into ``traj``."""
    import drjit as dr
    n = dr.width(state[0])
    gdt = c["gravity"] * c["dt"]
    lo = -1.0 + c["radius"]
    hi = 1.0 - c["radius"]
    p = dr.arange(uint, n)
    if traj is not None and steps == 0:
        dr.scatter(traj[0], state[0], p)
        dr.scatter(traj[1], state[1], p)

    def body(s, x, y, u, v):
        if traj is not None:
            # frame 0 from the first trip: a scatter pending before a symbolic loop would be
            # flushed as a kernel of its own, one after it would re-run the loop
            dr.scatter(traj[0], x, p, active=s == 0)
            dr.scatter(traj[1], y, p, active=s == 0)
        # the scenario's exact order: velocity, positions, then the three clamps in sequence
        v = v + gdt
        x = x + u * c["dt"]
        y = y + v * c["dt"]
        hit = y < c["radius"]
        y = dr.select(hit, c["radius"], y)
        v = dr.select(hit, -c["bounce"] * v, v)
        u = dr.select(hit, c["damping"] * u, u)
        hit = x < lo
        x = dr.select(hit, lo, x)
        u = dr.select(hit, -c["bounce"] * u, u)
        hit = x > hi
        x = dr.select(hit, hi, x)
        u = dr.select(hit, -c["bounce"] * u, u)
        s = s + 1
        if traj is not None:
            f = s // record_every
            frame = f * record_every == s
            dr.scatter(traj[0], x, f * n + p, active=frame)
            dr.scatter(traj[1], y, f * n + p, active=frame)
        return s, x, y, u, v

    out = dr.while_loop((dr.zeros(uint, n), *state), lambda s, *_: s < steps, body,
                        labels=("step", "x", "y", "vx", "vy"), label="particles", mode="symbolic")
    return out[1:]


class Kernel(ScenarioKernel):
    def __init__(self, params: ParticlesParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        import drjit as dr
        cls = real_type(device, precision)
        self.uint = jit_module(device).UInt32
        self.params, self.dtype = params, np.dtype(precision)
        self.state0 = tuple(upload(inputs[k], cls) for k in INITIAL)
        self.consts = {k: scalar(inputs[k], cls) for k in CONSTANTS}
        self.frames = n_frames(params)
        # frames * n <= 2^31 - 1 (the scenario's limit), so UInt32 indices cannot overflow
        self.traj = (tuple(dr.empty(cls, self.frames * params.n) for _ in range(2))
                     if self.frames else None)
        if self.traj:
            dr.eval(*self.traj)
        self.state: tuple = ()

    def run(self) -> Any:
        import drjit as dr
        p = self.params
        self.state = rollout(p.steps, p.record_every, self.state0, self.consts, self.uint, self.traj)
        dr.eval(*self.state, *(self.traj or ()))
        return self.state

    def outputs(self) -> dict[str, np.ndarray]:
        n = self.params.n
        out = {k: download(a, self.dtype, (n,)) for k, a in zip(STATE, self.state)}
        if self.traj:
            # a copy: the next run() scatters into the same buffers
            out["traj_x"], out["traj_y"] = (download(t, self.dtype, (self.frames, n)).copy()
                                            for t in self.traj)
        return out

    def info(self) -> dict[str, Any]:
        return {"loop": "symbolic dr.while_loop over steps (the rollout is one kernel)",
                "trajectory": "masked dr.scatter inside the loop" if self.traj else "none", **fast_math()}
