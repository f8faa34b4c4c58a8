"""Differentiable projectile in Warp, gradients through wp.Tape, one thread per trajectory.

Warp's adjoint needs every intermediate state kept and never overwritten, and loop-carried local
variables in a dynamic loop are not differentiated correctly. So the state lives in arrays indexed
by time step, and each thread runs its trajectory's time loop reading step s and writing step s+1
(no loop-carried locals): one launch over the batch whose adjoint Warp replays in reverse (one
launch per step measured ~100x slower on CPU: ~2*steps Python-side launches per iteration). The
per-step arrays are (steps+1, B) so that neighbouring threads touch neighbouring addresses on CUDA.
The B losses are independent, so seeding every loss with 1 (``tape.backward(grads={loss: ones})``,
Warp's way for a non-scalar output) gives each trajectory its own gradient in one backward pass.
One code path for every B, so batch row 0 is the unbatched run bit for bit.

Each gradient-descent iteration is: the forward, tape.backward, an update kernel (outside the
tape: it overwrites v), tape.zero(); the tape is recorded once and replayed. The loop stays on the
device; on CUDA it is captured once into a CUDA graph after the first (eager, compiling) call.

Variant "checkpoint": the plain tape keeps all steps+1 states per trajectory. Here the rollout runs
in segments of K = ceil(sqrt(steps)) steps through one (K+1, B) work buffer, and only each
segment's end state is kept, so memory per trajectory is O(steps/K + K). The backward pass needs
each segment's states again: ``Tape.record_func`` (Warp's hook for a custom step in the backward
pass) puts a re-run of segment j's forward just before segment j's adjoint in the replay. The same
kernel computes the same states, and the adjoint chains through the kept end states exactly, so the
gradient equals the plain tape's bit for bit (tests/backends/test_warp.py). The cost: every segment but the
last runs its forward twice (3 launches: forward, re-run, adjoint), all inside the same CUDA graph. K = sqrt(steps) minimises the states kept, steps/K + K + 1 per trajectory.
"""
# (no "from __future__ import annotations": Warp evaluates kernel annotations from the closure)
import functools
import math

import numpy as np
import warp as wp

from . import wp_device, wp_scalar
from ..base import ScenarioKernel

CONTACT = {"none": 0, "hard": 1, "soft": 2}
VARIANTS = ("default", "checkpoint")


@functools.cache
def _kernels(scalar):
    @wp.kernel(module="unique")
    def segment(seg: int, n: int, contact: int, dt: scalar, gravity: scalar, bounce: scalar,
                damping: scalar, stiffness: scalar, softness: scalar, v: wp.array2d(dtype=scalar),
                ex: wp.array2d(dtype=scalar), ey: wp.array2d(dtype=scalar),
                evx: wp.array2d(dtype=scalar), evy: wp.array2d(dtype=scalar),
                xs: wp.array2d(dtype=scalar), ys: wp.array2d(dtype=scalar),
                vxs: wp.array2d(dtype=scalar), vys: wp.array2d(dtype=scalar)):
        # n steps of segment seg: from v (seg 0) or segment seg-1's end state, through the work
        # buffers xs..vys (step-major), to this segment's end state e*[seg]
        b = wp.tid()
        if seg == 0:
            xs[0, b] = scalar(0.0)
            ys[0, b] = scalar(0.0)
            vxs[0, b] = v[b, 0]
            vys[0, b] = v[b, 1]
        else:
            xs[0, b] = ex[seg - 1, b]
            ys[0, b] = ey[seg - 1, b]
            vxs[0, b] = evx[seg - 1, b]
            vys[0, b] = evy[seg - 1, b]
        for s in range(n):
            x = xs[s, b]
            y = ys[s, b]
            vx = vxs[s, b]
            vy = vys[s, b]
            acc = gravity
            if contact == 2:
                z = -y / softness
                sp = wp.max(z, scalar(0.0)) + wp.log(scalar(1.0) + wp.exp(-wp.abs(z)))
                acc = gravity + stiffness * (softness * sp)
            vy = vy + acc * dt
            x = x + vx * dt
            y = y + vy * dt
            if contact == 1:
                if y < scalar(0.0):
                    y = scalar(0.0)
                    vy = -bounce * vy
                    vx = damping * vx
            xs[s + 1, b] = x
            ys[s + 1, b] = y
            vxs[s + 1, b] = vx
            vys[s + 1, b] = vy
        ex[seg, b] = xs[n, b]
        ey[seg, b] = ys[n, b]
        evx[seg, b] = vxs[n, b]
        evy[seg, b] = vys[n, b]

    @wp.kernel(module="unique")
    def loss_k(last: int, target: wp.array2d(dtype=scalar), ex: wp.array2d(dtype=scalar),
               ey: wp.array2d(dtype=scalar), loss: wp.array(dtype=scalar)):
        b = wp.tid()
        dx = ex[last, b] - target[b, 0]
        dy = ey[last, b] - target[b, 1]
        loss[b] = dx * dx + dy * dy

    @wp.kernel(module="unique")
    def update(k: int, iters: int, lr: scalar, loss: wp.array(dtype=scalar),
               v: wp.array2d(dtype=scalar), g: wp.array2d(dtype=scalar),
               history: wp.array2d(dtype=scalar), grad0: wp.array2d(dtype=scalar)):
        b = wp.tid()
        history[k, b] = loss[b]
        if k == 0:
            grad0[b, 0] = g[b, 0]
            grad0[b, 1] = g[b, 1]
        if k < iters:
            v[b, 0] = v[b, 0] - lr * g[b, 0]
            v[b, 1] = v[b, 1] - lr * g[b, 1]

    @wp.kernel(module="unique")
    def reset(v0: wp.array2d(dtype=scalar), v: wp.array2d(dtype=scalar)):
        b = wp.tid()
        v[b, 0] = v0[b, 0]
        v[b, 1] = v0[b, 1]

    return segment, loss_k, update, reset


def segments(steps: int, variant: str) -> list[int]:
    """Steps per segment: the whole horizon, or K = ceil(sqrt(steps)) each (the last the rest)."""
    k = steps if variant == "default" else math.isqrt(steps - 1) + 1
    return [min(k, steps - i) for i in range(0, steps, k)]


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs, device, precision, variant):
        if variant not in VARIANTS:
            raise ValueError(f"warp projectile has no variant {variant!r} (has {', '.join(VARIANTS)})")
        self.dev = wp_device(device)
        scalar = wp_scalar(precision)
        self.k_segment, self.k_loss, self.k_update, self.k_reset = _kernels(scalar)
        self.p = params
        self.c = {k: scalar(float(inputs[k])) for k in ("dt", "gravity", "bounce", "damping",
                                                        "stiffness", "softness", "lr")}
        self.batch = b = params.batch
        self.seg_steps = segments(params.steps, variant)
        nseg, work = len(self.seg_steps), max(self.seg_steps) + 1

        def z(*shape, grad=True):
            return wp.zeros(shape, dtype=scalar, device=self.dev, requires_grad=grad)
        as2 = lambda a: wp.array(np.asarray(a).reshape(b, 2), dtype=scalar, device=self.dev)  # noqa: E731
        self.v0, self.target = as2(inputs["v0"]), as2(inputs["target"])
        self.v = z(b, 2)
        self.work = [z(work, b) for _ in range(4)]      # x, y, vx, vy of one segment, step-major
        self.ends = [z(nseg, b) for _ in range(4)]      # each segment's end state
        self.loss = z(b)
        self.seed = wp.ones(b, dtype=scalar, device=self.dev)   # d(sum of losses)/d loss_b
        self.history = z(params.iters + 1, b, grad=False)
        self.grad0 = z(b, 2, grad=False)
        self.graph = None
        # Record the forward once; later iterations relaunch the same forward and replay backward.
        self.tape = wp.Tape()
        with self.tape:
            self._forward(checkpoint=True)

    def _segment(self, j: int) -> None:
        p, c = self.p, self.c
        wp.launch(self.k_segment, dim=self.batch,
                  inputs=[j, self.seg_steps[j], CONTACT[p.contact], c["dt"], c["gravity"], c["bounce"],
                          c["damping"], c["stiffness"], c["softness"], self.v],
                  outputs=[*self.ends, *self.work], device=self.dev)

    def _recompute(self, j: int):
        """Backward-pass step before segment j's adjoint: clear the work buffers' gradients (left
        by segment j+1's adjoint) and refill them with segment j's forward states."""
        def run():
            for a in self.work:
                a.grad.zero_()
            self._segment(j)
        return run

    def _forward(self, checkpoint: bool = False) -> None:
        last = len(self.seg_steps) - 1
        for j in range(last + 1):
            self._segment(j)
            if checkpoint and j < last:     # (the last segment's states are still in the buffers)
                self.tape.record_func(self._recompute(j), arrays=self.work)
        wp.launch(self.k_loss, dim=self.batch, inputs=[last, self.target, self.ends[0], self.ends[1]],
                  outputs=[self.loss], device=self.dev)

    def _optimise(self):
        wp.launch(self.k_reset, dim=self.batch, inputs=[self.v0], outputs=[self.v], device=self.dev)
        for k in range(self.p.iters + 1):
            self._forward()
            self.tape.backward(grads={self.loss: self.seed})
            wp.launch(self.k_update, dim=self.batch,
                      inputs=[k, self.p.iters, self.c["lr"], self.loss, self.v, self.v.grad],
                      outputs=[self.history, self.grad0], device=self.dev)
            self.tape.zero()

    def run(self):
        if self.graph is not None:
            wp.capture_launch(self.graph)
            return
        self._optimise()                    # first call: eager (compiles the module)
        if self.dev.startswith("cuda"):
            with wp.ScopedCapture(device=self.dev) as capture:
                self._optimise()
            self.graph = capture.graph

    def set_input(self, name: str, value: np.ndarray) -> None:
        if name != "v0":
            super().set_input(name, value)
        # same buffer: the captured graph reads the new v0
        self.v0.assign(np.asarray(value).reshape(self.v0.shape))

    def outputs(self) -> dict[str, np.ndarray]:
        hist, grad, v = self.history.numpy(), self.grad0.numpy(), self.v.numpy()
        if self.batch == 1:
            hist, grad, v = hist[:, 0], grad[0], v[0]
        return {"loss": hist[0], "grad": grad, "loss_history": hist, "v_final": v}

    def info(self) -> dict:
        nseg = len(self.seg_steps)
        return {"cuda_graph": self.graph is not None, "threads": self.batch,
                "segments": nseg, "segment_steps": self.seg_steps[0],
                "states_kept_per_trajectory": nseg + self.seg_steps[0] + 1,
                # kernel launches besides the tape's adjoint replays (nseg + 1 of them)
                "launches_per_iteration": 2 * nseg + 1}
