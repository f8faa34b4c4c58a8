"""Differentiable projectile in Taichi, gradients by Taichi's reverse-mode autodiff (kernel.grad).

Batched: B trajectories (B = 1 for the seed case), each with its own v0, target, loss and
gradient descent, one thread per trajectory. One code path for every B, so batch row 0 is the
B = 1 result bit for bit.

Taichi's global data access rule (a global value is never overwritten once read; gradients
accumulate) shapes the storage, as in the Warp port: the state lives in fields indexed by time
step and trajectory (xs[s, b] -> xs[s+1, b]) and every .grad is zeroed before each backward pass.
Memory order (same index [s, b], same values): on CUDA step-major, b fastest, so the threads of a
warp (consecutive b, all at the same step s of the serial loop) touch one contiguous segment:
coalesced; b-major order would put them steps + 1 elements apart. On the CPU, where one thread
walks whole trajectories, trajectory-major (s fastest).

Fused rollout: one primal and one backward launch per evaluation. The parallel loop runs over the
trajectories and the step loop is a serial range-for nested in it, because Taichi's AD reverses
only nested loops (a top-level loop, even under ti.loop_config(serialize=True), is differentiated
in forward order: silently wrong gradients) and rejects statements beside a loop in a
differentiated kernel. The B losses are independent: loss is a field of B, loss.grad seeded to 1
everywhere. Taichi 1.7's AD of such a loop has traps, all found by checking against the oracle;
the guards hold per thread (adstacks are the thread's locals, es/ws are per trajectory):
  * its backward kernel keeps per-step intermediates on autodiff stacks (adstacks) of depth
    steps + 1, which Taichi cannot size for a runtime trip count: it falls back to 32 entries and
    overflows without an error (zero gradients at 33 steps, then segfaults or hangs). The backend
    passes a ceiling to ti.init (AD_STACK_SIZE in __init__.py) and the fused path is taken only
    when the rollout fits under it;
  * every reassignment of a local pushes again, so the contact is written with ti.select rather
    than a mutating if (whose depth would grow with the number of bounces);
  * the adjoint of exp (and tanh) reuses the op's own result, which Taichi keeps in a plain
    backup rather than on an adstack, so the reversed loop sees the *last* step's exp(w)
    (softplus gradients 16% off). The backward kernel therefore reads exp(w) stored per step and
    trajectory by the primal launch and writes it as es[s, b] + (w - ws[s, b]) * es[s, b]:
    exactly es[s, b] in value, d/dw = es[s, b] = exp(w) through an ordinary product, i.e. the
    same adjoint arithmetic; loss and states come from the unmodified primal.
Adstack depth. ad_stack_size is read when a kernel is compiled, and an adstack is an alloca of
4 + 2 x depth x (4 or 8) bytes: on CUDA per-thread local memory, which the driver reserves for
every thread that can be resident (SMs x max threads per SM), whatever B, so a ceiling-deep stack
costs gigabytes even at B = 1. The kernel therefore compiles its backward kernel for steps +
ADSTACK_MARGIN entries: the config is set before each launch (compilation is lazy) and the depth
is a template argument, so a kernel of another depth in the same process gets its own
instantiation. Margin 3: with steps + 2 (the deepest stack's steps + 1 pushes and one spare),
some trajectories of a batch got gradients unlike the per-step path's, so exact sizing is not
trusted; the tests compare the sized fused path with the per-step one.

Variants (projectile only), all with the default's arithmetic and outputs:
  * 'per_step': one launch per step over the B trajectories (Warp's scheme), forward and
    reversed, for every steps: no adstack, no exp store needed in the backward kernel; the path
    the default also takes for rollouts longer than the ceiling allows. 2 steps + 5 launches per
    iteration against 3, for a state read once per step from global memory, coalesced on CUDA.
  * 'checkpoint': recomputation in segments of K = ceil(sqrt(steps)) steps (at most the
    adstack limit). The forward pass keeps only the states at segment starts; the backward pass,
    last segment first, recomputes a segment from its checkpoint into a scratch of K + 1 steps
    and runs that segment's fused backward pass (adstacks of K + margin). State memory
    (steps + 1) B -> about 2 sqrt(steps) B per field, at 4 ceil(steps/K) + 4 launches per
    iteration and one more forward pass. Taichi 1.7 has no built-in checkpointing:
    ti.ad.grad_replaced/grad_for only substitute a Python function's gradient under
    ti.ad.Tape, so the segments are driven from the host as the per-step path is.
A 'static' variant (the step loop unrolled with ti.static(range(steps)): straight-line code,
no adstack) gives the same outputs but is not offered: its compile time grows faster than
linearly with steps (Taichi warns past 32 unrolled iterations) and takes minutes at the
default 180 steps.
All paths give the same outputs: bitwise on the CPU, to a few roundings on CUDA, whose compiler
contracts FMAs kernel by kernel (tests/backends/test_taichi_family.py, tests/backends/test_taichi.py).
The update kernel also zeroes the gradients and re-seeds loss.grad. On the CPU the [s, b] fields
are trajectory-major (one thread walks whole trajectories: cache-friendly), on CUDA step-major.

Storage: fields (Taichi 1.7's autodiff is built around fields), allocated once in the
constructor; info()["design_bytes"] gives what the design predicts, e = 4 or 8 bytes a float:
  state        4 fields x (steps + 1) x B x 2 (value + grad) x e  ('checkpoint': segment + 1 rows)
  checkpoints  4 x (segments + 1) x B x 2 x e                     ('checkpoint' only)
  exp_store    2 x steps x B x e                                 (soft contact only; es, ws)
  adstack_per_stack_per_thread  4 + 2 x depth x e   (fused and checkpoint; times the backward
               kernel's adstacks, one per local of the step body, times the resident threads)
A field holds < 2^31 elements (Taichi's 32-bit index; refused).
What does not differ from the Quadrants port (init, loss, reset and update kernels, the Kernel's
bookkeeping) is one definition shared with it, projectile_common.py, built here with ``taichi``.
"""
# (no "from __future__ import annotations": Taichi reads kernel annotations as objects)

import math
from typing import Any

import taichi as ti
from taichi.lang import impl

from . import BACKEND
from .projectile_common import HARD, SOFT, build
from scenarios.projectile import ProjectileParams

ADSTACK_MARGIN = 3     # adstack entries beyond the steps (module doc: why 3)

_init, _loss, _init_k, _loss_k, _reset, _update, FieldKernel = build(ti)


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


@ti.kernel
def _rollout(stack: ti.template(), steps: ti.i32, contact: ti.template(),
             linearised: ti.template(), dt: float, gravity: float, bounce: float, damping: float,
             stiffness: float, softness: float, target: ti.template(), v: ti.template(), xs: ti.template(), ys: ti.template(),
             vxs: ti.template(), vys: ti.template(), es: ti.template(), ws: ti.template(),
             loss: ti.template()):
    # stack: the adstack depth it is compiled for (a template argument, so that each depth gets
    # its own instantiation; _use_stack sets the depth before the launch that may compile it)
    for b in range(loss.shape[0]):     # parallel over trajectories; the step loop nested, serial,
        _init(b, v, xs, ys, vxs, vys)  # and reversed by AD
        for s in range(steps):
            _step(s, b, contact, linearised, dt, gravity, bounce, damping, stiffness, softness,
                  xs, ys, vxs, vys, es, ws)
        _loss(b, steps, target, xs, ys, loss)


@ti.kernel
def _step_k(s: ti.i32, contact: ti.template(), dt: float, gravity: float, bounce: float,
            damping: float, stiffness: float, softness: float, xs: ti.template(),
            ys: ti.template(), vxs: ti.template(), vys: ti.template(), es: ti.template(),
            ws: ti.template()):
    for b in range(xs.shape[1]):
        _step(s, b, contact, False, dt, gravity, bounce, damping, stiffness, softness,
              xs, ys, vxs, vys, es, ws)


@ti.kernel
def _segment(stack: ti.template(), j: ti.i32, n: ti.i32, contact: ti.template(),
             linearised: ti.template(), dt: float, gravity: float, bounce: float, damping: float,
             stiffness: float, softness: float, cx: ti.template(), cy: ti.template(), cvx: ti.template(), cvy: ti.template(),
             xs: ti.template(), ys: ti.template(), vxs: ti.template(), vys: ti.template(),
             es: ti.template(), ws: ti.template()):
    # Checkpointed rollout: n steps from checkpoint j into checkpoint j + 1 through the scratch
    # fields (n + 1 entries used), the same per-step arithmetic as the fused rollout.
    for b in range(xs.shape[1]):
        xs[0, b] = cx[j, b]
        ys[0, b] = cy[j, b]
        vxs[0, b] = cvx[j, b]
        vys[0, b] = cvy[j, b]
        for s in range(n):
            _step(s, b, contact, linearised, dt, gravity, bounce, damping, stiffness, softness,
                  xs, ys, vxs, vys, es, ws)
        cx[j + 1, b] = xs[n, b]
        cy[j + 1, b] = ys[n, b]
        cvx[j + 1, b] = vxs[n, b]
        cvy[j + 1, b] = vys[n, b]


@ti.kernel
def _zero_scratch(xs: ti.template(), ys: ti.template(), vxs: ti.template(), vys: ti.template()):
    for s, b in xs:
        xs.grad[s, b] = 0.0
        ys.grad[s, b] = 0.0
        vxs.grad[s, b] = 0.0
        vys.grad[s, b] = 0.0


def _fields(count: int, n: int, nb: int, trajectory_major: bool, needs_grad: bool = True) -> list:
    """``count`` fields indexed [s, b] of shape (n, nb). Memory order: b fastest (step-major, the
    coalesced one on CUDA) or, with ``trajectory_major``, s fastest (one thread's trajectory
    contiguous, the cache-friendly one on the CPU). Same values either way."""
    if not trajectory_major:
        return [ti.field(float, (n, nb), needs_grad=needs_grad) for _ in range(count)]
    fs = [ti.field(float, needs_grad=needs_grad) for _ in range(count)]
    fb = ti.FieldsBuilder()
    for f in fs:
        fb.dense(ti.j, nb).dense(ti.i, n).place(*((f, f.grad) if needs_grad else (f,)))
    fb.finalize()
    return fs


def fused_steps_limit() -> int:
    """Longest rollout whose backward pass fits the deepest adstacks the device allows
    (AD_STACK_SIZE, the depth setup() passed to ti.init)."""
    return (BACKEND.ad_stack_limit or impl.current_cfg().ad_stack_size) - ADSTACK_MARGIN


def _use_stack(depth: int) -> None:
    # ad_stack_size is read when a kernel is compiled (compilation is lazy, at its first launch):
    # set it before every launch of an adstack kernel, whose template key carries the depth.
    impl.current_cfg().ad_stack_size = depth


class Kernel(FieldKernel):
    fused: bool | None = None          # None: as the variant says (tests force either path)
    segment: int | None = None         # checkpoint variant's segment length (None: ~sqrt(steps))
    layout: str | None = None          # memory order of the [s, b] fields (None: by device)

    def _allocate(self, params: ProjectileParams, device: str, variant: str) -> list:
        nb = self.batch
        self.checkpoint = variant == "checkpoint"
        self.layout = self.layout or ("step-major" if device == "cuda" else "trajectory-major")
        tmajor = self.layout == "trajectory-major"
        if self.checkpoint:            # segments of K steps, recomputed in the backward pass
            k = self.segment or math.isqrt(params.steps - 1) + 1      # ceil(sqrt(steps))
            self.seg_len = max(1, min(k, params.steps, fused_steps_limit()))
            self.n_seg = -(-params.steps // self.seg_len)
            n, self.fused = self.seg_len + 1, True
        else:
            n = params.steps + 1
        rows = max(n, params.iters + 1, self.n_seg + 1 if self.checkpoint else 0)
        if rows * nb >= 2**31:         # Taichi indexes a field's elements with 32-bit integers
            raise ValueError(f"taichi projectile: a field of {rows} x {nb} elements exceeds "
                             f"Taichi's 32-bit element index (2^31)")
        if self.checkpoint:
            self.ck = _fields(4, self.n_seg + 1, nb, tmajor)
        self.state = _fields(4, n, nb, tmajor)                   # xs, ys, vxs, vys
        # exp(w) and w per step and trajectory, read only with soft contact (a token field else)
        ew = (n - 1, nb) if self.contact == SOFT else (1, 1)
        self.exp_w = _fields(2, *ew, tmajor, needs_grad=False)  # es, ws
        if self.fused is None:
            self.fused = variant != "per_step" and params.steps <= fused_steps_limit()
        self.path = "checkpoint" if self.checkpoint else "fused" if self.fused else "per_step"
        # the adstack depth of the backward kernel: the steps of one launch + the margin
        self.ad_stack = {"fused": params.steps, "checkpoint": n - 1}.get(self.path)
        if self.ad_stack is not None:
            self.ad_stack += ADSTACK_MARGIN
        # the update kernel clears the checkpoints' gradients (the scratch is cleared per segment)
        return self.ck if self.checkpoint else self.state

    def _evaluate(self) -> None:
        """Losses at the current v into loss, their gradients into v.grad (grads zeroed before)."""
        p, c, st = self.p, self.consts, self.state
        if self.path == "checkpoint":
            self._evaluate_checkpointed()
        elif self.path == "fused":
            args = (self.ad_stack, p.steps, self.contact)
            rest = (*c, self.target, self.v, *st, *self.exp_w, self.loss)
            _use_stack(self.ad_stack)
            _rollout(*args, False, *rest)
            _rollout.grad(*args, True, *rest)
        else:
            self._evaluate_per_step(_step_k, *st, *self.exp_w)

    def _evaluate_checkpointed(self) -> None:
        """Forward: segment by segment, keeping only the states at segment starts. Backward, last
        segment first: recompute the segment from its checkpoint (the last one is still in the
        scratch), then its fused backward pass carries the adjoint from checkpoint j + 1 to j."""
        p, c, st, ck, m, k = self.p, self.consts, self.state, self.ck, self.n_seg, self.seg_len
        args = (*c, *ck, *st, *self.exp_w)
        n = [min(k, p.steps - j * k) for j in range(m)]
        _use_stack(self.ad_stack)
        _init_k(self.v, *ck)
        for j in range(m):
            _segment(self.ad_stack, j, n[j], self.contact, False, *args)
        _loss_k(m, self.target, ck[0], ck[1], self.loss)
        _loss_k.grad(m, self.target, ck[0], ck[1], self.loss)
        for j in reversed(range(m)):
            if j < m - 1:
                _segment(self.ad_stack, j, n[j], self.contact, False, *args)
            _zero_scratch(*st)
            _segment.grad(self.ad_stack, j, n[j], self.contact, True, *args)
        _init_k.grad(self.v, *ck)

    def design_bytes(self) -> dict[str, int]:
        """The bytes the design predicts (module doc): fields, and the adstacks per thread."""
        nb, e, rows = self.batch, self.elem, self.state[0].shape[0]
        out = {"state": 4 * rows * nb * 2 * e,
               "exp_store": 2 * (rows - 1) * nb * e if self.contact == SOFT else 0}
        if self.checkpoint:
            out["checkpoints"] = 4 * (self.n_seg + 1) * nb * 2 * e
        if self.ad_stack is not None:
            out["adstack_per_stack_per_thread"] = 4 + 2 * e * self.ad_stack
        return out

    def info(self) -> dict[str, Any]:
        out = {**super().info(), "state_layout": f"(steps+1, batch), {self.layout}",
               "ad_stack_size": self.ad_stack, "design_bytes": self.design_bytes()}
        if self.checkpoint:
            out.update(checkpoint_segment=self.seg_len, checkpoint_segments=self.n_seg,
                       launches_per_iteration=4 * self.n_seg + 4,
                       state_layout=f"checkpoints (segments+1, batch), scratch (segment+1, batch), "
                                    f"{self.layout}")
        return out
