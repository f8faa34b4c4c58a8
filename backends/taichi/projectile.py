"""Differentiable projectile in Taichi, gradients by Taichi's reverse-mode autodiff (kernel.grad).

Batched: B trajectories (B = 1 for the seed case), each with its own v0, target, loss and
gradient descent. One code path for every B, so batch row 0 is the B = 1 result bit for bit.

Taichi's global data access rule (a global value is never overwritten once read; gradients
accumulate) shapes the storage, as in the Warp port: the state lives in fields indexed by time
step and trajectory (xs[s, b] -> xs[s+1, b]) and every .grad is zeroed before each backward pass.
Layout (steps + 1, B), row-major: for one step, consecutive trajectories are adjacent, so the
threads of a CUDA warp (consecutive b, all at the same step s of the serial loop) read and write
one contiguous segment: coalesced. The (B, steps + 1) layout would put them steps + 1 elements
apart. (On the CPU a thread walks one trajectory with stride B; the CPU is not the target.)

Fused rollout: one primal and one backward launch per evaluation. The parallel loop runs over the
trajectories and the step loop is a serial range-for nested in it, because Taichi's AD reverses
only nested loops (a top-level loop, even under ti.loop_config(serialize=True), is differentiated
in forward order: silently wrong gradients) and rejects statements beside a loop in a
differentiated kernel. The B losses are independent: loss is a field of B, loss.grad seeded to 1
everywhere. Taichi 1.7's AD of such a loop has traps, all found by checking against the oracle,
and the guards hold per thread (adstacks are per-thread locals, es/ws per trajectory):
  * its backward kernel keeps per-step intermediates on autodiff stacks (adstacks) of depth
    steps + 1, which Taichi cannot size for a runtime trip count: it falls back to 32 entries and
    overflows without an error (zero gradients at 33 steps, then segfaults or hangs). The backend
    sets ``ad_stack_size`` at ti.init and the fused path is taken only when the rollout fits;
  * every reassignment of a local pushes again, so the contact is written with ti.select rather
    than a mutating if (whose depth would grow with the number of bounces);
  * the adjoint of exp (and tanh) reuses the op's own result, which Taichi keeps in a plain
    backup rather than on an adstack, so the reversed loop sees the *last* step's exp(w)
    (softplus gradients 16% off). The backward kernel therefore reads exp(w) stored per step and
    trajectory by the primal launch and writes it as es[s, b] + (w - ws[s, b]) * es[s, b]:
    exactly es[s, b] in value (w - ws[s, b] == 0), d/dw = es[s, b] = exp(w) through an ordinary
    product, i.e. the same adjoint arithmetic; loss and states come from the unmodified primal.
Rollouts longer than the adstacks fall back to one launch per step over the B trajectories
(Warp's scheme), where none of this arises. Both paths give the same outputs: bitwise on the CPU,
to a few roundings on CUDA, whose compiler contracts FMAs kernel by kernel (tests/test_taichi.py).

Per gradient-descent iteration the host makes 3 launches (fused) or 2*steps + 5 (per step),
whatever B; the update kernel also zeroes the gradients and re-seeds loss.grad for the next
evaluation. Measured per run() (B = 1, 180 steps, 21 evaluations), fused vs per step: 2-core CPU
VM 3-12 ms vs 235-270 ms; H200 4-14 ms vs 350-540 ms.
Storage: fields (Taichi 1.7's autodiff is built around fields), allocated once in the
constructor: 4 state fields of (steps + 1) x B with gradients, plus es/ws of steps x B for soft
contact only: about 64 (steps + 1) B bytes in float64 (12 GiB at 180 steps, B = 2^20), +16 steps B
for soft.
"""
# (no "from __future__ import annotations": Taichi reads kernel annotations as objects)

from typing import Any

import numpy as np
import taichi as ti
from taichi.lang import impl

from . import config_info
from ..base import ScenarioKernel

NONE, HARD, SOFT = 0, 1, 2
CONTACT = {"none": NONE, "hard": HARD, "soft": SOFT}
ADSTACK_MARGIN = 2     # the deepest adstack holds steps + 1 entries (measured); one spare


@ti.func
def _exp(w, s, b, linearised: ti.template(), es: ti.template(), ws: ti.template()):
    if ti.static(linearised):          # backward kernel of the fused rollout (see module doc)
        return es[s, b] + (w - ws[s, b]) * es[s, b]
    e = ti.exp(w)
    es[s, b] = e
    ws[s, b] = w
    return e


@ti.func
def _acc(y, s, b, contact: ti.template(), linearised: ti.template(), gravity, stiffness, softness,
         es: ti.template(), ws: ti.template()):
    if ti.static(contact != SOFT):
        return gravity
    z = -y / softness
    sp = ti.max(z, 0.0) + ti.log(1.0 + _exp(-ti.abs(z), s, b, linearised, es, ws))
    return gravity + stiffness * (softness * sp)


@ti.func
def _step(s, b, contact: ti.template(), linearised: ti.template(), dt, gravity, bounce, damping,
          stiffness, softness, xs: ti.template(), ys: ti.template(), vxs: ti.template(),
          vys: ti.template(), es: ti.template(), ws: ti.template()):
    # Single-assignment locals, and ti.select for the contact rather than reassignments in an if:
    # the fused backward pass pushes every reassignment onto an adstack, so a mutating branch
    # would make the stack depth grow with the number of bounces. Same values, bit for bit.
    x = xs[s, b]
    y = ys[s, b]
    vx = vxs[s, b]
    vy = vys[s, b]
    acc = _acc(y, s, b, contact, linearised, gravity, stiffness, softness, es, ws)
    vy1 = vy + acc * dt
    x1 = x + vx * dt
    y1 = y + vy1 * dt
    xs[s + 1, b] = x1
    if ti.static(contact == HARD):
        hit = y1 < 0.0
        ys[s + 1, b] = ti.select(hit, 0.0, y1)
        vxs[s + 1, b] = ti.select(hit, damping * vx, vx)
        vys[s + 1, b] = ti.select(hit, -bounce * vy1, vy1)
    else:
        ys[s + 1, b] = y1
        vxs[s + 1, b] = vx
        vys[s + 1, b] = vy1


@ti.func
def _init(b, v: ti.template(), xs: ti.template(), ys: ti.template(), vxs: ti.template(),
          vys: ti.template()):
    xs[0, b] = 0.0
    ys[0, b] = 0.0
    vxs[0, b] = v[b, 0]
    vys[0, b] = v[b, 1]


@ti.func
def _loss(b, steps, target: ti.template(), xs: ti.template(), ys: ti.template(),
          loss: ti.template()):
    dx = xs[steps, b] - target[b, 0]
    dy = ys[steps, b] - target[b, 1]
    loss[b] = dx * dx + dy * dy


@ti.kernel
def _rollout(steps: ti.i32, contact: ti.template(), linearised: ti.template(), dt: float,
             gravity: float, bounce: float, damping: float, stiffness: float, softness: float,
             target: ti.template(), v: ti.template(), xs: ti.template(), ys: ti.template(),
             vxs: ti.template(), vys: ti.template(), es: ti.template(), ws: ti.template(),
             loss: ti.template()):
    for b in range(loss.shape[0]):     # parallel over trajectories; the step loop nested, serial,
        _init(b, v, xs, ys, vxs, vys)  # and reversed by AD
        for s in range(steps):
            _step(s, b, contact, linearised, dt, gravity, bounce, damping, stiffness, softness,
                  xs, ys, vxs, vys, es, ws)
        _loss(b, steps, target, xs, ys, loss)


@ti.kernel
def _init_k(v: ti.template(), xs: ti.template(), ys: ti.template(), vxs: ti.template(),
            vys: ti.template()):
    for b in range(xs.shape[1]):
        _init(b, v, xs, ys, vxs, vys)


@ti.kernel
def _step_k(s: ti.i32, contact: ti.template(), dt: float, gravity: float, bounce: float,
            damping: float, stiffness: float, softness: float, xs: ti.template(),
            ys: ti.template(), vxs: ti.template(), vys: ti.template(), es: ti.template(),
            ws: ti.template()):
    for b in range(xs.shape[1]):
        _step(s, b, contact, False, dt, gravity, bounce, damping, stiffness, softness,
              xs, ys, vxs, vys, es, ws)


@ti.kernel
def _loss_k(steps: ti.i32, target: ti.template(), xs: ti.template(), ys: ti.template(),
            loss: ti.template()):
    for b in range(loss.shape[0]):
        _loss(b, steps, target, xs, ys, loss)


@ti.func
def _zero_grads(v: ti.template(), loss: ti.template(), xs: ti.template(), ys: ti.template(),
                vxs: ti.template(), vys: ti.template()):
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


@ti.kernel
def _reset(v0: ti.template(), v: ti.template(), loss: ti.template(), xs: ti.template(),
           ys: ti.template(), vxs: ti.template(), vys: ti.template()):
    for b in range(loss.shape[0]):
        v[b, 0] = v0[b, 0]
        v[b, 1] = v0[b, 1]
    _zero_grads(v, loss, xs, ys, vxs, vys)


@ti.kernel
def _update(k: ti.i32, iters: ti.i32, lr: float, loss: ti.template(), v: ti.template(),
            history: ti.template(), grad0: ti.template(), xs: ti.template(), ys: ti.template(),
            vxs: ti.template(), vys: ti.template()):
    for b in range(loss.shape[0]):     # each trajectory descends on its own loss
        history[k, b] = loss[b]
        if k == 0:
            grad0[b, 0] = v.grad[b, 0]
            grad0[b, 1] = v.grad[b, 1]
        if k < iters:                  # no update after the last evaluation
            v[b, 0] = v[b, 0] - lr * v.grad[b, 0]
            v[b, 1] = v[b, 1] - lr * v.grad[b, 1]
    _zero_grads(v, loss, xs, ys, vxs, vys)


def fused_steps_limit() -> int:
    """Longest rollout whose backward pass fits the adstacks configured at ti.init."""
    return impl.current_cfg().ad_stack_size - ADSTACK_MARGIN


class Kernel(ScenarioKernel):
    fused: bool | None = None          # None: fused when the rollout fits (tests force either)

    def __init__(self, params: Any, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        self.p = params
        self.batch = nb = int(params.batch)
        self.contact = CONTACT[params.contact]
        self.consts = [float(inputs[k]) for k in ("dt", "gravity", "bounce", "damping",
                                                  "stiffness", "softness")]
        self.lr = float(inputs["lr"])
        n = params.steps + 1
        self.state = [ti.field(float, (n, nb), needs_grad=True) for _ in range(4)]  # xs ys vxs vys
        # exp(w) and w per step and trajectory, read only with soft contact (a token field else)
        ew = (params.steps, nb) if self.contact == SOFT else (1, 1)
        self.exp_w = [ti.field(float, ew) for _ in range(2)]                        # es, ws
        self.v = ti.field(float, (nb, 2), needs_grad=True)
        self.loss = ti.field(float, nb, needs_grad=True)
        self.v0 = ti.field(float, (nb, 2))
        self.target = ti.field(float, (nb, 2))
        self.set_input("v0", inputs["v0"])
        self.target.from_numpy(np.ascontiguousarray(np.reshape(inputs["target"], (nb, 2))))
        self.history = ti.field(float, (params.iters + 1, nb))
        self.grad0 = ti.field(float, (nb, 2))
        if self.fused is None:
            self.fused = params.steps <= fused_steps_limit()

    def _evaluate(self) -> None:
        """Losses at the current v into loss, their gradients into v.grad (grads zeroed before)."""
        p, c, st = self.p, self.consts, self.state
        if self.fused:
            args = (*c, self.target, self.v, *st, *self.exp_w, self.loss)
            _rollout(p.steps, self.contact, False, *args)
            _rollout.grad(p.steps, self.contact, True, *args)
            return
        _init_k(self.v, *st)
        for s in range(p.steps):
            _step_k(s, self.contact, *c, *st, *self.exp_w)
        _loss_k(p.steps, self.target, st[0], st[1], self.loss)
        _loss_k.grad(p.steps, self.target, st[0], st[1], self.loss)
        for s in reversed(range(p.steps)):
            _step_k.grad(s, self.contact, *c, *st, *self.exp_w)
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
        return {"storage": "field", **config_info(), "fused_rollout": self.fused,
                "launches_per_iteration": 3 if self.fused else 2 * self.p.steps + 5,
                "batch": self.batch, "state_layout": "(steps+1, batch)",
                "ad_stack_size": impl.current_cfg().ad_stack_size}
