"""Differentiable projectile in Quadrants, gradients by reverse-mode autodiff (kernel.grad).

Adapted from the Taichi port (backends/taichi/projectile.py), whose structure it keeps: batched,
B trajectories (B = 1 for the seed case), each with its own v0, target, loss and gradient descent;
one code path for every B, so batch row 0 is the B = 1 result bit for bit. The state lives in
fields indexed by time step and trajectory (xs[s, b] -> xs[s+1, b]; Quadrants keeps Taichi's
global data access rule: a global value is never overwritten once read, gradients accumulate),
layout (steps + 1, B) so the threads of a CUDA warp touch one contiguous segment per step, and
every .grad is zeroed before each backward pass.

Fused rollout: one primal and one backward launch per evaluation. The parallel loop runs over the
trajectories and the step loop is a serial range-for nested in it, which the reverse pass walks
backwards through Quadrants' *adstack* pipeline (``ad_stack_experimental_enabled=True``, set by
the backend). What differs from the Taichi port, and why (docs/findings.md has the reproducers):
  * Taichi 1.7 sizes its adstacks for a run-time trip count at 32 entries and overflows them
    silently (wrong gradients or a crash past 32 steps), so the Taichi port sets ``ad_stack_size``
    at ti.init and falls back to one launch per step beyond it. Quadrants sizes every adstack at
    launch from the loop bound, and reports an overflow instead of ignoring it: no stack size, no
    steps limit, the fused rollout always. The bound must be a shape the sizer can read: a kernel
    scalar argument is not (compile error "adstack bound ... is unresolved"), so the step count
    is read from a 0-d i32 field, ``nsteps[None]``, set once in the constructor.
  * Taichi 1.7 pushes every reassignment of a local, so a mutating if (the hard contact) made the
    stack depth grow with the number of bounces past what ad_stack_size allowed; the Taichi port
    writes the contact with ti.select. Quadrants' sizer counts those pushes, so this port writes
    the contact as Warp and the scenario do, a mutating if (same values bit for bit).
  * Taichi 1.7's adjoint of exp (and tanh) reads the op's result from a plain backup holding the
    last iteration's value (softplus gradients 16% off), so the Taichi port stores exp(w) per step
    in the primal launch and linearises around it in the backward one (two extra fields).
    Quadrants gets the adjoint of exp right through a loop: plain qd.exp, no extra fields.
One launch per step over the B trajectories (Warp's per-step scheme, where none of this arises)
is kept as ``Kernel.fused = False`` for the tests, which check both paths give the same outputs
(tests/test_quadrants.py); the driver always runs the fused one.

Per gradient-descent iteration the host makes 3 launches (fused) or 2*steps + 5 (per step),
whatever B; the update kernel also zeroes the gradients and re-seeds loss.grad for the next
evaluation. Storage: fields, allocated once in the constructor: 4 state fields of (steps + 1) x B
with gradients, about 64 (steps + 1) B bytes in float64. The adstacks come on top, on the device
for CUDA: per thread, (steps + 1) slots of 8 (f32) or 16 (f64) bytes per loop-carried value,
allocated by Quadrants at launch (not measured on a GPU here).
"""
# (no "from __future__ import annotations": Quadrants (like Taichi) reads kernel annotations as objects)

from typing import Any

import numpy as np
import quadrants as qd
from quadrants.lang import impl

from . import config_info
from ..base import ScenarioKernel

NONE, HARD, SOFT = 0, 1, 2
CONTACT = {"none": NONE, "hard": HARD, "soft": SOFT}


@qd.func
def _acc(y, contact: qd.template(), gravity, stiffness, softness):
    acc = gravity
    if qd.static(contact == SOFT):
        z = -y / softness
        sp = qd.max(z, 0.0) + qd.log(1.0 + qd.exp(-qd.abs(z)))
        acc = gravity + stiffness * (softness * sp)
    return acc


@qd.func
def _step(s, b, contact: qd.template(), dt, gravity, bounce, damping, stiffness, softness,
          xs: qd.template(), ys: qd.template(), vxs: qd.template(), vys: qd.template()):
    # Warp's step, operation for operation (its mutating if included: see the module doc).
    x = xs[s, b]
    y = ys[s, b]
    vx = vxs[s, b]
    vy = vys[s, b]
    acc = _acc(y, contact, gravity, stiffness, softness)
    vy = vy + acc * dt
    x = x + vx * dt
    y = y + vy * dt
    if qd.static(contact == HARD):
        if y < 0.0:
            y = 0.0
            vy = -bounce * vy
            vx = damping * vx
    xs[s + 1, b] = x
    ys[s + 1, b] = y
    vxs[s + 1, b] = vx
    vys[s + 1, b] = vy


@qd.func
def _init(b, v: qd.template(), xs: qd.template(), ys: qd.template(), vxs: qd.template(),
          vys: qd.template()):
    xs[0, b] = 0.0
    ys[0, b] = 0.0
    vxs[0, b] = v[b, 0]
    vys[0, b] = v[b, 1]


@qd.func
def _loss(b, steps, target: qd.template(), xs: qd.template(), ys: qd.template(),
          loss: qd.template()):
    dx = xs[steps, b] - target[b, 0]
    dy = ys[steps, b] - target[b, 1]
    loss[b] = dx * dx + dy * dy


@qd.kernel
def _rollout(nsteps: qd.template(), contact: qd.template(), dt: float, gravity: float,
             bounce: float, damping: float, stiffness: float, softness: float,
             target: qd.template(), v: qd.template(), xs: qd.template(), ys: qd.template(),
             vxs: qd.template(), vys: qd.template(), loss: qd.template()):
    for b in range(loss.shape[0]):     # parallel over trajectories; the step loop nested, serial,
        _init(b, v, xs, ys, vxs, vys)  # and reversed by AD (adstacks sized from nsteps[None])
        for s in range(nsteps[None]):
            _step(s, b, contact, dt, gravity, bounce, damping, stiffness, softness,
                  xs, ys, vxs, vys)
        _loss(b, nsteps[None], target, xs, ys, loss)


@qd.kernel
def _init_k(v: qd.template(), xs: qd.template(), ys: qd.template(), vxs: qd.template(),
            vys: qd.template()):
    for b in range(xs.shape[1]):
        _init(b, v, xs, ys, vxs, vys)


@qd.kernel
def _step_k(s: qd.i32, contact: qd.template(), dt: float, gravity: float, bounce: float,
            damping: float, stiffness: float, softness: float, xs: qd.template(),
            ys: qd.template(), vxs: qd.template(), vys: qd.template()):
    for b in range(xs.shape[1]):
        _step(s, b, contact, dt, gravity, bounce, damping, stiffness, softness, xs, ys, vxs, vys)


@qd.kernel
def _loss_k(steps: qd.i32, target: qd.template(), xs: qd.template(), ys: qd.template(),
            loss: qd.template()):
    for b in range(loss.shape[0]):
        _loss(b, steps, target, xs, ys, loss)


@qd.func
def _zero_grads(v: qd.template(), loss: qd.template(), xs: qd.template(), ys: qd.template(),
                vxs: qd.template(), vys: qd.template()):
    # Backward passes accumulate (+=) into every .grad: clear them and re-seed d loss_b/d loss_b = 1
    # (independent losses: no cross terms).
    for b in range(loss.shape[0]):
        v.grad[b, 0] = 0.0
        v.grad[b, 1] = 0.0
        loss.grad[b] = 1.0
    for s, b in xs:
        xs.grad[s, b] = 0.0
        ys.grad[s, b] = 0.0
        vxs.grad[s, b] = 0.0
        vys.grad[s, b] = 0.0


@qd.kernel
def _reset(v0: qd.template(), v: qd.template(), loss: qd.template(), xs: qd.template(),
           ys: qd.template(), vxs: qd.template(), vys: qd.template()):
    for b in range(loss.shape[0]):
        v[b, 0] = v0[b, 0]
        v[b, 1] = v0[b, 1]
    _zero_grads(v, loss, xs, ys, vxs, vys)


@qd.kernel
def _update(k: qd.i32, iters: qd.i32, lr: float, loss: qd.template(), v: qd.template(),
            history: qd.template(), grad0: qd.template(), xs: qd.template(), ys: qd.template(),
            vxs: qd.template(), vys: qd.template()):
    for b in range(loss.shape[0]):     # each trajectory descends on its own loss
        history[k, b] = loss[b]
        if k == 0:
            grad0[b, 0] = v.grad[b, 0]
            grad0[b, 1] = v.grad[b, 1]
        if k < iters:                  # no update after the last evaluation
            v[b, 0] = v[b, 0] - lr * v.grad[b, 0]
            v[b, 1] = v[b, 1] - lr * v.grad[b, 1]
    _zero_grads(v, loss, xs, ys, vxs, vys)


class Kernel(ScenarioKernel):
    fused: bool = True                 # False: one launch per step (tests compare the two)

    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        self.p = params
        self.batch = nb = int(params.batch)
        self.contact = CONTACT[params.contact]
        self.consts = [float(inputs[k]) for k in ("dt", "gravity", "bounce", "damping",
                                                  "stiffness", "softness")]
        self.lr = float(inputs["lr"])
        n = params.steps + 1
        self.state = [qd.field(float, (n, nb), needs_grad=True) for _ in range(4)]  # xs ys vxs vys
        self.nsteps = qd.field(qd.i32, ())   # the step loop's bound, read by the adstack sizer
        self.nsteps[None] = params.steps
        self.v = qd.field(float, (nb, 2), needs_grad=True)
        self.loss = qd.field(float, nb, needs_grad=True)
        self.v0 = qd.field(float, (nb, 2))
        self.target = qd.field(float, (nb, 2))
        self.set_input("v0", inputs["v0"])
        self.target.from_numpy(np.ascontiguousarray(np.reshape(inputs["target"], (nb, 2))))
        self.history = qd.field(float, (params.iters + 1, nb))
        self.grad0 = qd.field(float, (nb, 2))

    def _evaluate(self) -> None:
        """Losses at the current v into loss, their gradients into v.grad (grads zeroed before)."""
        p, c, st = self.p, self.consts, self.state
        if self.fused:
            args = (self.nsteps, self.contact, *c, self.target, self.v, *st, self.loss)
            _rollout(*args)
            _rollout.grad(*args)
            return
        _init_k(self.v, *st)
        for s in range(p.steps):
            _step_k(s, self.contact, *c, *st)
        _loss_k(p.steps, self.target, st[0], st[1], self.loss)
        _loss_k.grad(p.steps, self.target, st[0], st[1], self.loss)
        for s in reversed(range(p.steps)):
            _step_k.grad(s, self.contact, *c, *st)
        _init_k.grad(self.v, *st)

    def run(self) -> None:
        _reset(self.v0, self.v, self.loss, *self.state)
        for k in range(self.p.iters + 1):
            self._evaluate()
            _update(k, self.p.iters, self.lr, self.loss, self.v, self.history, self.grad0,
                    *self.state)

    def set_input(self, name: str, value: np.ndarray) -> None:
        if name != "v0":
            super().set_input(name, value)
        value = np.asarray(value)
        if value.shape != ((2,) if self.batch == 1 else (self.batch, 2)):
            raise ValueError(f"v0 must keep its shape, got {value.shape}")
        self.v0.from_numpy(np.ascontiguousarray(value.reshape(self.batch, 2)))

    def outputs(self) -> dict[str, np.ndarray]:
        hist, grad, v = self.history.to_numpy(), self.grad0.to_numpy(), self.v.to_numpy()
        if self.batch == 1:            # the unbatched shapes: loss (), grad (2,), history (iters+1,)
            return {"loss": hist[0, 0], "grad": grad[0],
                    "loss_history": np.ascontiguousarray(hist[:, 0]), "v_final": v[0]}
        return {"loss": hist[0], "grad": grad, "loss_history": hist, "v_final": v}

    def info(self) -> dict[str, Any]:
        cfg = impl.current_cfg()
        return {"storage": "field", **config_info(), "fused_rollout": self.fused,
                "launches_per_iteration": 3 if self.fused else 2 * self.p.steps + 5,
                "batch": self.batch, "state_layout": "(steps+1, batch)",
                "ad_stack": "launch-time sized" if cfg.ad_stack_size == 0 else cfg.ad_stack_size,
                "ad_stack_experimental_enabled": bool(cfg.ad_stack_experimental_enabled)}
