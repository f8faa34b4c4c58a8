"""Differentiable projectile in PyTorch: gradients by autograd, vectorised over trajectories.

The state (x, y, vx, vy) is four tensors of the batch shape (() for one trajectory, (B,) for a
batch), stepped out of place, because reverse mode keeps every step's operands (a few tensors of
B elements per step, from the caching allocator). Each gradient-descent iteration is: the losses
of all trajectories (the scenario's step order, the soft contact's softplus written as in
backends/warp/projectile.py), ``torch.autograd.grad`` of their sum with respect to v (trajectories
are independent, so d(sum)/d v_b = d loss_b / d v_b), then, without autograd, history[k] = loss,
grad0 = g at k = 0, and v <- v - lr*g while k < iters. All of it stays on the device: no host
reads, so a whole run can be captured as one CUDA graph (the ``capture`` hook).

"compile": the rollout runs as calls of a compiled function of SEGMENT steps (unrolled by Dynamo;
AOTAutograd compiles its backward too), so an iteration is a few fused kernels per segment forward
and backward instead of ~10 per step each way. "compile_graphs" (CUDA only): the same segments
under reduce-overhead, each segment's forward and backward replayed as CUDA graphs. CUDAGraph
Trees record the segments' forwards as one path while a backward is pending and the backwards
after them (the training-loop pattern they are built for), and ``torch.autograd.grad`` runs the
compiled backward like ``backward()`` does. Each iteration's loss and gradient are copied out of
the graphs' pool (into ``history``, ``grad0`` and ``v``) before the next iteration replays them.
The constants are marked static; the first segment's inputs (fresh each iteration) are copied
into the graph's input buffers by one batched copy per replay.

Memory at large batches: reverse mode keeps what each step's backward needs (eager: every step's
operands; compiled: what the partitioner saves per segment), O(steps x B) either way; the rest
(v, history, grad0) is O(iters x B).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import MODES, check_variant, compiled, download, empty, kernel_info, put, torch_device, torch_dtype
from ..base import ScenarioKernel
from scenarios.projectile import ProjectileParams
from ..base import Device
from scenarios.base import Precision

CONSTANTS = ("dt", "gravity", "bounce", "damping", "stiffness", "softness", "lr")
# "compile": steps per compiled call. The whole unrolled rollout (180 steps) is one kernel of
# thousands of statements that took minutes to build and crashed g++ (internal compiler error) in
# Inductor's CPU backend here; 16 steps (the JAX port's CUDA unroll) compile in seconds.
SEGMENT = 16


def advance(x, y, vx, vy, c, n: int, contact: str):
    """``n`` steps of the scenario (its order; the soft contact's softplus as in Warp's port)."""
    import torch
    zero, one, dt = c["zero"], c["one"], c["dt"]
    for _ in range(n):
        if contact == "soft":
            z = -y / c["softness"]
            sp = torch.maximum(z, zero) + torch.log(one + torch.exp(-torch.abs(z)))
            acc = c["gravity"] + c["stiffness"] * (c["softness"] * sp)
            vy = vy + acc * dt
        else:
            vy = vy + c["gdt"]                      # acc * dt with acc = gravity: the same value
        x = x + vx * dt
        y = y + vy * dt
        if contact == "hard":
            hit = y < zero
            y = torch.where(hit, zero, y)
            vy = torch.where(hit, c["neg_bounce"] * vy, vy)
            vx = torch.where(hit, c["damping"] * vx, vx)
    return x, y, vx, vy


def make_losses(contact: str, steps: int, segment: int = 0, variant: str = "default",
                static: tuple[Any, ...] = ()):
    """Loss per trajectory, v and target of shape (2,) -> () or (B, 2) -> (B,). ``segment`` > 0:
    the rollout as calls of ``advance`` of ``segment`` steps (and one of the rest), compiled by
    the compiled ``variant``, ``static`` its preallocated inputs."""
    import torch
    run = compiled(advance, variant, static) if segment else advance
    chunks = [steps]
    if segment:
        chunks = [segment] * (steps // segment) + ([steps % segment] if steps % segment else [])

    def losses(v, target, c):
        vx = v[..., 0]
        vy = v[..., 1]
        x = torch.zeros_like(vx)
        y = torch.zeros_like(vx)
        for n in chunks:
            x, y, vx, vy = run(x, y, vx, vy, c, n, contact)
        dx = x - target[..., 0]
        dy = y - target[..., 1]
        return dx * dx + dy * dy

    return losses


class Kernel(ScenarioKernel):
    def __init__(self, params: ProjectileParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        check_variant(variant)
        self.variant, self.params = variant, params
        self.dtype, self.device = torch_dtype(precision), torch_device(device)
        self.v0 = put(inputs["v0"], precision, device)
        self.target = put(inputs["target"], precision, device)
        c = {k: put(inputs[k], precision, device) for k in CONSTANTS}
        c.update(zero=put(0.0, precision, device), one=put(1.0, precision, device),
                 gdt=c["gravity"] * c["dt"], neg_bounce=-c["bounce"])
        self.c = c
        b = tuple(self.v0.shape[:-1])
        self.v = empty(tuple(self.v0.shape), precision, device).requires_grad_(True)
        self.step = empty(tuple(self.v0.shape), precision, device)
        self.history = empty((params.iters + 1,) + b, precision, device)
        self.grad0 = empty(tuple(self.v0.shape), precision, device)
        self.segment = SEGMENT if variant in MODES else 0
        self.losses = make_losses(params.contact, params.steps, self.segment, variant, tuple(c.values()))

    def run(self) -> Any:
        import torch
        v, iters = self.v, self.params.iters
        with torch.no_grad():
            v.copy_(self.v0)
        for k in range(iters + 1):
            with torch.enable_grad():
                loss = self.losses(v, self.target, self.c)
                (g,) = torch.autograd.grad(loss.sum(), v)
            with torch.no_grad():
                self.history[k].copy_(loss)
                if k == 0:
                    self.grad0.copy_(g)
                if k < iters:
                    v.sub_(torch.mul(g, self.c["lr"], out=self.step))     # v - lr*g
        return self.history

    def set_input(self, name: str, value: np.ndarray) -> None:
        """``v0`` or ``target``, same shape, copied into the existing tensor (a captured CUDA graph
        reads the new values)."""
        import torch
        if name not in ("v0", "target"):
            super().set_input(name, value)
        old = getattr(self, name)
        if tuple(np.shape(value)) != tuple(old.shape):
            raise ValueError(f"{name} must keep its shape {tuple(old.shape)}, got {np.shape(value)}")
        with torch.no_grad():
            old.copy_(torch.as_tensor(np.asarray(value), dtype=self.dtype).to(self.device))

    def outputs(self) -> dict[str, np.ndarray]:
        hist = download(self.history)
        return {"loss": hist[0].copy(), "grad": download(self.grad0), "loss_history": hist,
                "v_final": download(self.v)}

    def info(self) -> dict[str, Any]:
        b = self.params.batch
        how = "torch.autograd.grad of the loss" if b == 1 else \
            "torch.autograd.grad of the summed per-trajectory losses (vectorised over the batch)"
        return kernel_info(self.variant, gradient=how, batch=b,
                           compiled_unit=f"{self.segment} steps (backward by AOTAutograd)"
                           if self.segment else None)
