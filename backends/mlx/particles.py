"""Bouncing particles in MLX: one compiled step over all particles, called once per time step.

The step (the scenario's order: velocity, positions, then the floor and the two walls, each a
``mx.where``) is one ``mx.compile``d function over all particles; ``run()`` calls it ``steps``
times, adding the step's kernels to the lazy graph each time. MLX fuses per output chain: a value
that several outputs need (a contact mask, a position after a clamp) is computed by a kernel of
its own, so a step is about ten small elementwise kernels rather than one. Compiling the function
that runs many times (MLX's compile guide: compile what you call more than once) and looping in
Python is the MLX way; variant ``rollout`` traces the whole rollout into one compiled function
instead (below), so the two are timed side by side. Every ``CHUNK`` steps the graph built so far is handed to
``mx.async_eval``, so the stream computes while Python builds the next steps. With
``record_every`` > 0 every k-th position is kept (frame 0 the initial state) and the frames
stacked at the end.

Variant ``rollout``: ``mx.compile`` of the whole rollout (the steps loop, frames and stack inside
one traced function), one compiled call a run: no Python per step after the first trace, at the
price of a first call that traces and compiles every step's kernels.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from scenarios.base import dtype_of
from scenarios.particles import INITIAL, STATE, step_constants

from . import Program, download, kernel_info, launch, put
from ..base import ScenarioKernel
from scenarios.particles import ParticlesParams
from ..base import Device
from scenarios.base import Precision

CHUNK = 32          # steps per async_eval: overlaps graph building with computing


def _step(x: Any, y: Any, u: Any, v: Any, c: dict[str, Any]) -> tuple[Any, Any, Any, Any]:
    import mlx.core as mx
    v = v + c["gdt"]
    x = x + u * c["dt"]
    y = y + v * c["dt"]
    hit = y < c["radius"]                                     # floor
    y = mx.where(hit, c["radius"], y)
    v = mx.where(hit, c["nbounce"] * v, v)
    u = mx.where(hit, c["damping"] * u, u)
    hit = x < c["lo"]                                         # left wall
    x = mx.where(hit, c["lo"], x)
    u = mx.where(hit, c["nbounce"] * u, u)
    hit = x > c["hi"]                                         # right wall
    x = mx.where(hit, c["hi"], x)
    u = mx.where(hit, c["nbounce"] * u, u)
    return x, y, u, v


class Kernel(ScenarioKernel):
    def __init__(self, params: ParticlesParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        self.params, self.device, self.precision = params, device, precision
        # derived once per run (gdt, lo, hi), rounded in the cell's dtype as the oracle's are
        self.c = {k: put(v, precision) for k, v in step_constants(inputs, dtype_of(precision)).items()}
        self.state0 = tuple(put(inputs[k], precision) for k in INITIAL)
        self.variant = variant
        self.step = Program(_step)
        self.rollout = Program(self._rollout) if variant == "rollout" else None
        self.out: tuple[Any, ...] = ()

    def _rollout(self, x: Any, y: Any, u: Any, v: Any, c: dict[str, Any]) -> tuple[Any, ...]:
        """The whole rollout, traced once by ``mx.compile`` (variant ``rollout``)."""
        import mlx.core as mx
        p = self.params
        frames_x, frames_y = [x], [y]
        for s in range(1, p.steps + 1):
            x, y, u, v = _step(x, y, u, v, c)
            if p.record_every and s % p.record_every == 0:
                frames_x.append(x)
                frames_y.append(y)
        out = (x, y, u, v)
        return out + (mx.stack(frames_x), mx.stack(frames_y)) if p.record_every else out

    def run(self) -> Any:
        import mlx.core as mx
        if self.rollout is not None:
            self.out = launch(tuple(self.rollout(*self.state0, self.c)))
            return self.out
        p = self.params
        x, y, u, v = self.state0
        frames_x, frames_y = [x], [y]
        for s in range(1, p.steps + 1):
            x, y, u, v = self.step(x, y, u, v, self.c)
            if p.record_every and s % p.record_every == 0:
                frames_x.append(x)
                frames_y.append(y)
            if s % CHUNK == 0:
                mx.async_eval(x, y, u, v)
        out = (x, y, u, v)
        if p.record_every:
            out += (mx.stack(frames_x), mx.stack(frames_y))
        self.out = launch(out)
        return self.out

    def outputs(self) -> dict[str, np.ndarray]:
        return {k: download(a, self.precision) for k, a in zip((*STATE, "traj_x", "traj_y"), self.out)}

    def info(self) -> dict[str, Any]:
        if self.rollout is not None:
            return kernel_info(self.device, self.precision, self.rollout,
                               loop="the whole rollout in one mx.compile'd function, vectorised over particles")
        return kernel_info(self.device, self.precision, self.step,
                           loop="Python loop over steps of one compiled step, vectorised over particles",
                           async_eval_every=CHUNK)
