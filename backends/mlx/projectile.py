"""Differentiable projectile in MLX: ``mx.value_and_grad`` through the unrolled rollout, ``mx.vmap``
over a batch of trajectories, one ``mx.compile``d gradient-descent iteration.

MLX has no loop primitive, so the trajectory is a Python loop over the steps that the trace
unrolls: the loss of one trajectory is a graph of ``steps`` scenario steps (its exact operation
order), ``mx.value_and_grad`` differentiates it in reverse mode, and one iteration (loss, gradient
and the update v - lr*grad) is compiled once per input signature: the fused kernels are replayed on
every call. ``run()`` calls it iters + 1 times (iteration k records loss(v_k), keeps the gradient
of iteration 0 and updates v only while k < iters, so v_final = v_iters), handing each
iteration to ``mx.async_eval`` so that the stream computes while Python issues the next.

Variant ``step``: ``mx.compile`` of one step instead of the whole iteration, the loop traced in
Python on every call (value_and_grad and vmap compose with the compiled step). Compiling the
unrolled loop makes the first call compile-bound (many fused kernels; NVRTC on CUDA), so this
variant trades per-call tracing for a first call that compiles one step's kernels.

Batch (B > 1 trajectories, each with its own v0 and target): ``mx.vmap`` of the one-trajectory
value_and_grad, so each trajectory runs the batch = 1 arithmetic unchanged (row 0 equals
batch = 1 bit for bit on the CPU) and descends on its own loss.

Memory: reverse mode keeps every step's intermediates until the backward pass has used them. The
soft contact's exp goes through ``backends.mlx.exp`` (float64-accurate for float64 cells).
"""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from . import Program, download, exp, kernel_info, launch, put
from ..base import ScenarioKernel
from scenarios.projectile import ProjectileParams
from ..base import Device
from scenarios.base import Precision

CONSTANTS = ("dt", "gravity", "bounce", "damping", "stiffness", "softness", "lr")


def make_step(contact: str) -> Callable[..., Any]:
    """One scenario step (its exact operation order): (x, y, vx, vy, c) -> (x, y, vx, vy)."""
    import mlx.core as mx

    def step(x: Any, y: Any, vx: Any, vy: Any, c: dict[str, Any]) -> tuple[Any, Any, Any, Any]:
        dt, g = c["dt"], c["gravity"]
        acc = g
        if contact == "soft":
            z = -y / c["softness"]
            sp = mx.maximum(z, 0.0) + mx.log(1.0 + exp(-mx.abs(z)))
            acc = g + c["stiffness"] * (c["softness"] * sp)
        vy = vy + acc * dt
        x = x + vx * dt
        y = y + vy * dt
        if contact == "hard":
            hit = y < 0.0
            y = mx.where(hit, 0.0, y)
            vy = mx.where(hit, -c["bounce"] * vy, vy)
            vx = mx.where(hit, c["damping"] * vx, vx)
        return x, y, vx, vy

    return step


def make_loss(steps: int, contact: str, step: Callable[..., Any] | None = None) -> Callable[..., Any]:
    """loss(v, target, c) of one trajectory, v and target of shape (2,), c the 0-d constants;
    ``step``: the step function the loop calls (default: ``make_step(contact)``, traced inline)."""
    import mlx.core as mx
    step = step or make_step(contact)

    def loss(v: Any, target: Any, c: dict[str, Any]) -> Any:
        x = y = mx.zeros((), dtype=v.dtype)
        vx, vy = v[0], v[1]
        for _ in range(steps):
            x, y, vx, vy = step(x, y, vx, vy, c)
        dx = x - target[0]
        dy = y - target[1]
        return dx * dx + dy * dy

    return loss


def make_iteration(steps: int, contact: str, batched: bool,
                   step: Callable[..., Any] | None = None) -> Callable[..., Any]:
    """(v, target, c) -> (loss, grad, v - lr*grad); vmapped over the leading axis when batched."""
    import mlx.core as mx
    value_and_grad = mx.value_and_grad(make_loss(steps, contact, step))
    if batched:
        value_and_grad = mx.vmap(value_and_grad, in_axes=(0, 0, None))

    def iteration(v: Any, target: Any, c: dict[str, Any]) -> tuple[Any, Any, Any]:
        loss, grad = value_and_grad(v, target, c)
        return loss, grad, v - c["lr"] * grad

    return iteration


class Kernel(ScenarioKernel):
    def __init__(self, params: ProjectileParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        self.params, self.device, self.precision = params, device, precision
        self.c = {k: put(inputs[k], precision) for k in CONSTANTS}
        self.v0 = put(inputs["v0"], precision)
        self.target = put(inputs["target"], precision)
        batched = params.batch > 1
        if variant == "step":               # compile one step; the iteration traces its loop per call
            self.step = Program(make_step(params.contact))
            self.program: Any = make_iteration(params.steps, params.contact, batched, self.step)
        else:                               # compile the whole iteration: the loop unrolled in one trace
            self.step = None
            self.program = Program(make_iteration(params.steps, params.contact, batched))
        self.variant = variant
        self.out: tuple[Any, ...] = ()

    def run(self) -> Any:
        import mlx.core as mx
        iters = self.params.iters
        v, history, grad0 = self.v0, [], None
        for k in range(iters + 1):
            loss, grad, updated = self.program(v, self.target, self.c)
            history.append(loss)
            if k == 0:
                grad0 = grad
            if k < iters:                    # no update after the last evaluation
                v = updated
            mx.async_eval(loss, grad, v)
        self.out = launch((history[0], grad0, mx.stack(history), v))
        return self.out

    def set_input(self, name: str, value: np.ndarray) -> None:
        """``v0`` or ``target``, same shape: the compiled iteration is reused as is."""
        if name not in ("v0", "target"):
            super().set_input(name, value)
        old = getattr(self, name)
        if tuple(np.shape(value)) != tuple(old.shape):
            raise ValueError(f"{name} must keep its shape {tuple(old.shape)}, got {np.shape(value)}")
        setattr(self, name, put(value, self.precision))

    def outputs(self) -> dict[str, np.ndarray]:
        loss, grad, history, v = (download(a, self.precision) for a in self.out)
        return {"loss": loss, "grad": grad, "loss_history": history, "v_final": v}

    def info(self) -> dict[str, Any]:
        b = self.params.batch
        how = "mx.value_and_grad through the unrolled steps"
        how += "" if b == 1 else ", mx.vmap over trajectories"
        if self.step is not None:
            return kernel_info(self.device, self.precision, self.step, gradient=how, batch=b,
                               compiled_unit="one step (the iteration's loop is traced in Python per call)")
        return kernel_info(self.device, self.precision, self.program, gradient=how, batch=b,
                           compiled_unit="one gradient-descent iteration")
