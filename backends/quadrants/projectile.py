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
Variant 'per_step': one launch per step over the B trajectories (Warp's per-step scheme), forward
and reversed: no adstack at all, the state read once per step from global memory (coalesced on
CUDA), 2 steps + 5 launches per iteration against the fused path's 3. It exists because the
fused path's reverse launch walks adstacks that Quadrants lays out thread after thread, so a
warp's accesses do not coalesce; the two paths give the same outputs (bitwise on the CPU,
tests/backends/test_taichi_family.py), the driver times them side by side. A 'static' variant
(qd.static(range(steps)): the loop unrolled, which Quadrants' autodiff guide says never needs the
adstack) also gives the same outputs but is not offered: its compile time grows faster than
linearly with steps, minutes at the default 180 steps, and with the hard contact
the unrolled code still keeps small compile-time-sized adstacks for the branch flags.

The update kernel also zeroes the gradients and re-seeds loss.grad for the next evaluation.
Storage: fields, allocated once in the constructor; info()["design_bytes"] gives what the design
predicts, e = 4 or 8 bytes a float:
  state              4 fields x (steps + 1) x B x 2 (value + grad) x e
  adstack_per_stack  B x (8 + (steps + 1) x 2 x e)   (fused only: one buffer per adstack, one
                     adstack per loop-carried value or branch flag; Quadrants sizes it per launch
                     for the threads of the launch, on CUDA the full range of B; the slot count
                     steps + 1 is the design's, the sizer may add a few)
What does not differ from the Taichi port (init, loss, reset and update kernels, the Kernel's
bookkeeping) is one definition shared with it, backends/taichi/projectile_common.py, built here
with ``quadrants``; this file keeps the step, the fused rollout and the per-step kernel.
"""
# (no "from __future__ import annotations": Quadrants (like Taichi) reads kernel annotations as objects)

from typing import Any

import quadrants as qd
from quadrants.lang import impl

from ..taichi.projectile_common import HARD, SOFT, build
from scenarios.projectile import ProjectileParams

_init, _loss, _init_k, _loss_k, _reset, _update, FieldKernel = build(qd)


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
def _step_k(s: qd.i32, contact: qd.template(), dt: float, gravity: float, bounce: float,
            damping: float, stiffness: float, softness: float, xs: qd.template(),
            ys: qd.template(), vxs: qd.template(), vys: qd.template()):
    for b in range(xs.shape[1]):
        _step(s, b, contact, dt, gravity, bounce, damping, stiffness, softness, xs, ys, vxs, vys)


class Kernel(FieldKernel):
    fused: bool | None = None          # None: as the variant says (tests force either path)

    def _allocate(self, params: ProjectileParams, device: str, variant: str) -> list:
        n, nb = params.steps + 1, self.batch
        self.state = [qd.field(float, (n, nb), needs_grad=True) for _ in range(4)]  # xs ys vxs vys
        self.nsteps = qd.field(qd.i32, ())   # the step loop's bound, read by the adstack sizer
        self.nsteps[None] = params.steps
        fused = variant != "per_step" if self.fused is None else self.fused
        self.path = "fused" if fused else "per_step"
        return self.state

    def _evaluate(self) -> None:
        """Losses at the current v into loss, their gradients into v.grad (grads zeroed before)."""
        rest = (self.contact, *self.consts, self.target, self.v, *self.state, self.loss)
        if self.path == "fused":
            _rollout(self.nsteps, *rest)
            _rollout.grad(self.nsteps, *rest)
        else:
            self._evaluate_per_step(_step_k, *self.state)

    def design_bytes(self) -> dict[str, int]:
        """The bytes the design predicts (module doc): the state fields, and for the fused path
        one adstack's buffer over the B threads of the launch (a buffer per stack)."""
        nb, e, n = self.batch, self.elem, self.p.steps + 1
        out = {"state": 4 * n * nb * 2 * e}
        if self.path == "fused":
            out["adstack_per_stack"] = nb * (8 + 2 * e * n)
        return out

    def info(self) -> dict[str, Any]:
        cfg = impl.current_cfg()
        stack = "launch-time sized" if cfg.ad_stack_size == 0 else cfg.ad_stack_size
        return {**super().info(), "state_layout": "(steps+1, batch)",
                "ad_stack": stack if self.path == "fused" else None,
                "ad_stack_experimental_enabled": bool(cfg.ad_stack_experimental_enabled),
                "design_bytes": self.design_bytes()}
