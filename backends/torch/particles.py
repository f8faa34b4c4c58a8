"""Bouncing particles in PyTorch: the state is four vectors over particles, stepped in place.

Particles are independent, so one step is a handful of elementwise ops over all particles; the
step loop runs on the host (PyTorch has no device-side loop), so a run is 19 kernels per step in
eager mode. Each contact rule is a mask (``torch.lt(..., out=)``) and in-place masked updates:
``where(hit, bound, x, out=x)`` for the clamped position (not ``masked_fill_``, whose CUDA
kernel reads a tensor fill value back to the host) and a multiply by ``where(hit, factor, 1)``
for the velocity, which equals ``where(hit, factor*v, v)`` exactly (v*1 = v), all in
preallocated buffers, so a run allocates nothing. "compile" compiles one step (functional, ending in copy_
into the state) into one fused Inductor kernel and calls it ``steps`` times. With
``record_every`` > 0 every k-th state is copied into the trajectory tensors, frame 0 the initial
state; without it no trajectory is kept.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from scenarios.particles import CONSTANTS, INITIAL, STATE, n_frames

from . import check_variant, compiled, download, empty, kernel_info, put
from ..base import ScenarioKernel
from scenarios.particles import ParticlesParams
from ..base import Device
from scenarios.base import Precision


def _step(x, y, u, v, dt, gdt, radius, lo, hi, neg_bounce, damping):
    """One step in the scenario's order, functional, written back into the state (compile)."""
    import torch
    v1 = v + gdt
    x1 = x + u * dt
    y1 = y + v1 * dt
    hit = y1 < radius
    y1 = torch.where(hit, radius, y1)
    v1 = torch.where(hit, neg_bounce * v1, v1)
    u1 = torch.where(hit, damping * u, u)
    hit = x1 < lo
    x1 = torch.where(hit, lo, x1)
    u1 = torch.where(hit, neg_bounce * u1, u1)
    hit = x1 > hi
    x1 = torch.where(hit, hi, x1)
    u1 = torch.where(hit, neg_bounce * u1, u1)
    x.copy_(x1)
    y.copy_(y1)
    u.copy_(u1)
    v.copy_(v1)


class Kernel(ScenarioKernel):
    def __init__(self, params: ParticlesParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        import torch
        check_variant(variant)
        self.variant, self.params = variant, params
        n = params.n
        self.state0 = [put(inputs[k], precision, device) for k in INITIAL]
        self.state = [empty((n,), precision, device) for _ in range(4)]
        dt, gravity, damping, bounce, radius = (put(inputs[k], precision, device) for k in CONSTANTS)
        one = put(1.0, precision, device)
        # derived once, rounded in the cell's dtype, as the reference does per launch
        self.c = {"dt": dt, "gdt": gravity * dt, "radius": radius, "lo": -one + radius,
                  "hi": one - radius, "neg_bounce": -bounce, "damping": damping, "one": one}
        self.traj = [empty((n_frames(params), n), precision, device) for _ in range(2)]
        self.tmp = empty((n,), precision, device)
        self.factor = empty((n,), precision, device)
        self.hit = torch.empty((n,), dtype=torch.bool, device=self.tmp.device)
        self.fn = compiled(_step) if variant == "compile" else None

    def _eager_step(self) -> None:
        import torch
        x, y, u, v = self.state
        c, t, f, hit = self.c, self.tmp, self.factor, self.hit
        v.add_(c["gdt"])
        x.add_(torch.mul(u, c["dt"], out=t))
        y.add_(torch.mul(v, c["dt"], out=t))
        torch.lt(y, c["radius"], out=hit)
        torch.where(hit, c["radius"], y, out=y)
        v.mul_(torch.where(hit, c["neg_bounce"], c["one"], out=f))
        u.mul_(torch.where(hit, c["damping"], c["one"], out=f))
        torch.lt(x, c["lo"], out=hit)
        torch.where(hit, c["lo"], x, out=x)
        u.mul_(torch.where(hit, c["neg_bounce"], c["one"], out=f))
        torch.gt(x, c["hi"], out=hit)
        torch.where(hit, c["hi"], x, out=x)
        u.mul_(torch.where(hit, c["neg_bounce"], c["one"], out=f))

    def run(self) -> Any:
        p, c = self.params, self.c
        for s, s0 in zip(self.state, self.state0):
            s.copy_(s0)
        if p.record_every:
            self.traj[0][0].copy_(self.state[0])
            self.traj[1][0].copy_(self.state[1])
        for s in range(p.steps):
            if self.fn is not None:
                self.fn(*self.state, c["dt"], c["gdt"], c["radius"], c["lo"], c["hi"],
                        c["neg_bounce"], c["damping"])
            else:
                self._eager_step()
            if p.record_every and (s + 1) % p.record_every == 0:
                f = (s + 1) // p.record_every
                self.traj[0][f].copy_(self.state[0])
                self.traj[1][f].copy_(self.state[1])
        return self.state

    def outputs(self) -> dict[str, np.ndarray]:
        out = dict(zip(STATE, (download(a) for a in self.state)))
        if self.params.record_every:
            out["traj_x"], out["traj_y"] = (download(a) for a in self.traj)
        return out

    def info(self) -> dict[str, Any]:
        return kernel_info(self.variant, loop="host loop over steps, vectorised over particles",
                           kernels_per_step=1 if self.fn is not None else 19)
