"""Bouncing particles in Warp.
# (no "from __future__ import annotations": Warp evaluates kernel annotations from the closure)

Particles do not interact, so one thread owns one particle and loops over all steps in registers:
one launch per run, no global-memory traffic per step, and no cross-step race (the seed's single
launch over step x particle reads states that other threads have not written yet). Trajectory
frames are written only when ``record_every`` asks for them.

Variant "racy-one-launch" (never listed in the backend's ``variants``; only the stress suite asks
for it, as a control that its race detector must catch) is the seed's bug kept on purpose: state
arrays of (steps+1)*n, one launch over steps*n threads, thread (s, p) reading step s that another
thread of the same launch writes. Warp's CPU runs the threads of a launch in index order, so there
the result happens to be right; on a GPU the blocks of different steps run concurrently.
"""

import functools
from typing import Any

import numpy as np
import warp as wp

from scenarios.particles import CONSTANTS, INITIAL, STATE, n_frames

from . import launcher, wp_device, wp_scalar
from ..base import ScenarioKernel


@wp.func
def step(x: Any, y: Any, u: Any, v: Any, gdt: Any, dt: Any, damping: Any, bounce: Any, radius: Any,
         lo: Any, hi: Any):
    """One step of one particle in the scenario's order (both kernels below take it)."""
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
    return x, y, u, v


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
    return rollout


class Kernel(ScenarioKernel):
    def __new__(cls, params, inputs, device, precision, variant):
        if variant == RACY:         # the deliberately wrong control; the default path is below
            return RacyOneLaunch(params, inputs, device, precision, variant)
        return super().__new__(cls)

    def __init__(self, params, inputs, device, precision, variant):
        self.dev = wp_device(device)
        scalar = wp_scalar(precision)
        self.kernel = _rollout(scalar)
        self.params = params
        arr = lambda a: wp.array(a, dtype=scalar, device=self.dev)  # noqa: E731
        self.state0 = [arr(inputs[k]) for k in INITIAL]
        self.state = [wp.empty(params.n, dtype=scalar, device=self.dev) for _ in range(4)]
        frames = n_frames(params)
        shape = (frames, params.n) if frames else (0, 0)
        self.traj = [wp.empty(shape, dtype=scalar, device=self.dev) for _ in range(2)]
        self.consts = [scalar(float(inputs[k])) for k in CONSTANTS]
        self.launch = launcher(variant, self.kernel, params.n,
                               [params.steps, params.record_every, *self.consts, *self.state0],
                               [*self.state, *self.traj], self.dev)

    def run(self):
        self.launch()

    def outputs(self) -> dict[str, np.ndarray]:
        out = dict(zip(STATE, (a.numpy() for a in self.state)))
        if self.params.record_every:
            out["traj_x"], out["traj_y"] = (a.numpy() for a in self.traj)
        return out


RACY = "racy-one-launch"


@functools.cache
def _racy_kernels(scalar):
    @wp.kernel(module="unique")
    def init(x0: wp.array(dtype=scalar), y0: wp.array(dtype=scalar), vx0: wp.array(dtype=scalar),
             vy0: wp.array(dtype=scalar), px: wp.array(dtype=scalar), py: wp.array(dtype=scalar),
             vx: wp.array(dtype=scalar), vy: wp.array(dtype=scalar)):
        p = wp.tid()
        px[p] = x0[p]
        py[p] = y0[p]
        vx[p] = vx0[p]
        vy[p] = vy0[p]

    @wp.kernel(module="unique")
    def all_steps(n: int, dt: scalar, gravity: scalar, damping: scalar, bounce: scalar,
                  radius: scalar, px: wp.array(dtype=scalar), py: wp.array(dtype=scalar),
                  vx: wp.array(dtype=scalar), vy: wp.array(dtype=scalar)):
        tid = wp.tid()
        s = tid // n                 # which time step
        p = tid - s * n              # which particle
        i0 = s * n + p
        i1 = (s + 1) * n + p
        lo = scalar(-1.0) + radius
        hi = scalar(1.0) - radius
        # RACE: step s was written by thread (s-1, p) of this same launch
        x, y, u, v = step(px[i0], py[i0], vx[i0], vy[i0], gravity * dt, dt, damping, bounce, radius,
                          lo, hi)
        px[i1] = x
        py[i1] = y
        vx[i1] = u
        vy[i1] = v
    return init, all_steps


class RacyOneLaunch(ScenarioKernel):
    """The seed's single launch over (step, particle): a known-wrong control for the stress suite.

    The history arrays are zeroed at the start of every run (as a fresh allocation often is), so
    a thread that reads its step before the writer has stored it sees zeros: the race shows in
    the result instead of hiding behind the previous run's values.
    """

    def __init__(self, params, inputs, device, precision, variant):
        if (params.steps + 1) * params.n > 2**31 - 1:
            raise ValueError(f"{RACY}: (steps+1)*n must fit in int32, got {(params.steps + 1) * params.n}")
        self.dev = wp_device(device)
        scalar = wp_scalar(precision)
        self.k_init, self.k_steps = _racy_kernels(scalar)
        self.params = params
        arr = lambda a: wp.array(a, dtype=scalar, device=self.dev)  # noqa: E731
        self.state0 = [arr(inputs[k]) for k in INITIAL]
        size = (params.steps + 1) * params.n
        self.hist = [wp.zeros(size, dtype=scalar, device=self.dev) for _ in range(4)]
        self.consts = [scalar(float(inputs[k])) for k in CONSTANTS]

    def run(self):
        p = self.params
        for h in self.hist:
            h.zero_()
        wp.launch(self.k_init, dim=p.n, inputs=self.state0, outputs=self.hist, device=self.dev)
        if p.steps:
            wp.launch(self.k_steps, dim=p.steps * p.n, inputs=[p.n, *self.consts],
                      outputs=self.hist, device=self.dev)

    def outputs(self) -> dict[str, np.ndarray]:
        p = self.params
        hist = [h.numpy().reshape(p.steps + 1, p.n) for h in self.hist]
        out = dict(zip(STATE, (h[-1].copy() for h in hist)))
        if p.record_every:
            out["traj_x"], out["traj_y"] = (h[::p.record_every].copy() for h in hist[:2])
        return out

    def info(self) -> dict:
        return {"variant": RACY, "launch_dim": self.params.steps * self.params.n}
