"""Bouncing particles in NumPy: every particle at once, one Python iteration per time step.

The state is four arrays over the particles, updated in place; each step is the scenario's step
in its order as whole-array ufuncs, and a contact is a mask: the clamp writes through
``np.copyto(..., where=mask)`` and the velocity factors through ``np.multiply(..., where=mask)``,
so particles that do not touch a wall keep their values untouched, as in Warp's branch. Masks,
the state and the trajectory frames are allocated once; a step allocates nothing. The time loop
is the Python-side cost that a compiled kernel (one thread looping over steps) does not pay: about
a dozen ufunc calls per step whatever n.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from scenarios.particles import INITIAL, STATE, n_frames, step_constants

from . import kernel_info, scalar_type
from ..base import ScenarioKernel


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.params = params
        self.c = step_constants(inputs, S)      # gdt, lo, hi derived once per run, as Warp's kernel does
        self.state0 = [np.ascontiguousarray(inputs[k], S) for k in INITIAL]
        n = params.n
        self.state = [np.empty(n, S) for _ in STATE]
        self.tmp = np.empty(n, S)
        self.mask = np.empty(n, np.bool_)
        frames = n_frames(params)
        self.traj = [np.empty((frames, n) if frames else (0, 0), S) for _ in range(2)]

    def run(self) -> None:
        p, c = self.params, self.c
        x, y, u, v = self.state
        tmp, hit = self.tmp, self.mask
        for a, a0 in zip(self.state, self.state0):
            np.copyto(a, a0)
        tx, ty = self.traj
        if p.record_every:
            np.copyto(tx[0], x); np.copyto(ty[0], y)
        dt, gdt, radius, lo, hi = c["dt"], c["gdt"], c["radius"], c["lo"], c["hi"]
        nbounce, damping = c["nbounce"], c["damping"]
        for s in range(p.steps):
            np.add(v, gdt, out=v)                                  # v += g dt
            np.multiply(u, dt, out=tmp); np.add(x, tmp, out=x)     # x += u dt
            np.multiply(v, dt, out=tmp); np.add(y, tmp, out=y)     # y += v dt
            np.less(y, radius, out=hit)                            # floor
            np.copyto(y, radius, where=hit)
            np.multiply(v, nbounce, out=v, where=hit)
            np.multiply(u, damping, out=u, where=hit)
            np.less(x, lo, out=hit)                                # left wall
            np.copyto(x, lo, where=hit)
            np.multiply(u, nbounce, out=u, where=hit)
            np.greater(x, hi, out=hit)                             # right wall
            np.copyto(x, hi, where=hit)
            np.multiply(u, nbounce, out=u, where=hit)
            if p.record_every and (s + 1) % p.record_every == 0:
                f = (s + 1) // p.record_every
                np.copyto(tx[f], x); np.copyto(ty[f], y)

    def outputs(self) -> dict[str, np.ndarray]:
        out = {k: a.copy() for k, a in zip(STATE, self.state)}
        if self.params.record_every:
            out["traj_x"], out["traj_y"] = (a.copy() for a in self.traj)
        return out

    def info(self) -> dict[str, Any]:
        return kernel_info(ufuncs_per_step=15)
