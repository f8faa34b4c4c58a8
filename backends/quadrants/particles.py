"""Bouncing particles in Quadrants: one parallel-for iteration per particle, all steps in registers.

Particles are independent, so the outer (parallel) loop is over particles and the inner loop over
steps is serial within one thread: one launch per run, race-free, state kept in registers.
Trajectory frames are written only when ``record_every`` asks for them.

The Taichi port's kernel with ``ti`` renamed ``qd``; nothing else differs. Storage: fields, as
there (the kernel is compute-bound; on Taichi 1.7 fields had the lower launch overhead).
"""
# (no "from __future__ import annotations": Quadrants (like Taichi) reads kernel annotations as objects)

from typing import Any

import numpy as np
import quadrants as qd

from . import config_info
from ..base import ScenarioKernel

STATE = ("x", "y", "vx", "vy")


@qd.kernel
def _rollout(steps: qd.i32, record_every: qd.i32, dt: float, gravity: float, damping: float,
             bounce: float, radius: float,
             x0: qd.template(), y0: qd.template(), vx0: qd.template(), vy0: qd.template(),
             x_out: qd.template(), y_out: qd.template(), vx_out: qd.template(),
             vy_out: qd.template(), traj_x: qd.template(), traj_y: qd.template()):
    for p in x0:                       # parallel over particles; the step loop below is serial
        x = x0[p]
        y = y0[p]
        u = vx0[p]
        v = vy0[p]
        gdt = gravity * dt
        lo = -1.0 + radius             # literals are default_fp: the cell's precision
        hi = 1.0 - radius
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


class Kernel(ScenarioKernel):
    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        self.params = params
        n = params.n
        self.state0 = [qd.field(float, shape=n) for _ in STATE]
        for f, k in zip(self.state0, ("x0", "y0", "vx0", "vy0")):
            f.from_numpy(inputs[k])
        self.state = [qd.field(float, shape=n) for _ in STATE]
        frames = params.steps // params.record_every + 1 if params.record_every else 0
        # A 1x1 placeholder when no trajectory is kept (fields cannot be empty); never written.
        self.traj = [qd.field(float, shape=(frames, n) if frames else (1, 1)) for _ in range(2)]
        self.consts = [float(inputs[k]) for k in ("dt", "gravity", "damping", "bounce", "radius")]

    def run(self) -> None:
        p = self.params
        _rollout(p.steps, p.record_every, *self.consts, *self.state0, *self.state, *self.traj)

    def outputs(self) -> dict[str, np.ndarray]:
        out = {k: f.to_numpy() for k, f in zip(STATE, self.state)}
        if self.params.record_every:
            out["traj_x"], out["traj_y"] = (f.to_numpy() for f in self.traj)
        return out

    def info(self) -> dict[str, Any]:
        return {"storage": "field", **config_info()}
