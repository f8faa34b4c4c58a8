"""Bouncing particles in Warp.
# (no "from __future__ import annotations": Warp evaluates kernel annotations from the closure)

Particles do not interact, so one thread owns one particle and loops over all steps in registers:
one launch per run, no global-memory traffic per step, and no cross-step race (the seed's single
launch over step x particle reads states that other threads have not written yet). Trajectory
frames are written only when ``record_every`` asks for them.
"""

import functools

import numpy as np
import warp as wp

from . import wp_device, wp_scalar
from ..base import ScenarioKernel


@functools.cache
def _rollout(scalar):
    @wp.kernel(module="unique")
    def rollout(steps: int, record_every: int, dt: scalar, gravity: scalar, damping: scalar,
                bounce: scalar, radius: scalar,
                x0: wp.array(dtype=scalar), y0: wp.array(dtype=scalar),
                vx0: wp.array(dtype=scalar), vy0: wp.array(dtype=scalar),
                x_out: wp.array(dtype=scalar), y_out: wp.array(dtype=scalar),
                vx_out: wp.array(dtype=scalar), vy_out: wp.array(dtype=scalar),
                traj_x: wp.array2d(dtype=scalar), traj_y: wp.array2d(dtype=scalar)):
        p = wp.tid()
        x = x0[p]
        y = y0[p]
        u = vx0[p]
        v = vy0[p]
        gdt = gravity * dt
        lo = scalar(-1.0) + radius
        hi = scalar(1.0) - radius
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


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs, device, precision, variant):
        self.dev = wp_device(device)
        scalar = wp_scalar(precision)
        self.kernel = _rollout(scalar)
        self.params = params
        arr = lambda a: wp.array(a, dtype=scalar, device=self.dev)  # noqa: E731
        self.state0 = [arr(inputs[k]) for k in ("x0", "y0", "vx0", "vy0")]
        self.state = [wp.empty(params.n, dtype=scalar, device=self.dev) for _ in range(4)]
        frames = params.steps // params.record_every + 1 if params.record_every else 0
        shape = (frames, params.n) if frames else (0, 0)
        self.traj = [wp.empty(shape, dtype=scalar, device=self.dev) for _ in range(2)]
        self.consts = [scalar(float(inputs[k])) for k in ("dt", "gravity", "damping", "bounce", "radius")]

    def run(self):
        p = self.params
        wp.launch(self.kernel, dim=p.n,
                  inputs=[p.steps, p.record_every, *self.consts, *self.state0],
                  outputs=[*self.state, *self.traj], device=self.dev)

    def outputs(self) -> dict[str, np.ndarray]:
        out = dict(zip(("x", "y", "vx", "vy"), (a.numpy() for a in self.state)))
        if self.params.record_every:
            out["traj_x"], out["traj_y"] = (a.numpy() for a in self.traj)
        return out
