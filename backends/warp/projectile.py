"""Differentiable projectile in Warp, gradients through wp.Tape, one thread per trajectory.

Each gradient-descent iteration is: the forward, tape.backward, an update kernel (outside the
tape: it overwrites v), then v's gradient is cleared; the tape is recorded once and replayed.
The loop stays on the device; on CUDA it is captured once into a CUDA graph after the first (eager,
compiling) call. The B losses are independent, so seeding every loss with 1
(``tape.backward(grads={loss: ones})``, Warp's way for a non-scalar output) gives each trajectory
its own gradient in one backward pass. One code path for every B, so batch row 0 is the unbatched
run bit for bit. The variants (``VARIANTS``) differ in where the states live and what is cleared:

"default": the arrays of Warp's differentiable examples. Warp's adjoint needs every intermediate
state kept and never overwritten, and loop-carried local variables in a dynamic loop are not
differentiated correctly, so the state lives in four (steps+1, B) arrays with gradients, step-major
so that neighbouring threads touch neighbouring addresses on CUDA; each thread runs its time loop
reading step s and writing step s+1 in one launch whose adjoint Warp replays in reverse (one launch
per step would be ~2*steps Python-side launches per iteration). Clearing: Warp's adjoint adds into
gradients, but the adjoint of a store zeroes the gradient entry it reads (the differentiability
guide: output gradients are consumed, so only an element's final write propagates;
``CONSUMES_GRADIENTS``). So after a backward pass every array written on the tape (the states, the
loss) holds a zero gradient, and only v's (read, never written) must be cleared for the next one.
Clearing just that is exact ("tape_zero" gives the same bits) and writes 2B scalars per iteration
instead of every gradient the tape holds, (4 steps + 11) B. Every path but "tape_zero" clears so.

"tape_zero": the default with ``tape.zero()`` after each backward pass, as Warp's differentiable
examples write it: it clears every gradient the tape holds, already zero but for v's.

"checkpoint": the rollout runs in segments of K = ceil(sqrt(steps)) steps through one (K+1, B)
work buffer, and only each segment's end state is kept, O(steps/K + K) states per trajectory. The
backward pass needs each segment's states again: ``Tape.record_func`` (Warp's hook for a custom
step in the backward pass) puts a re-run of segment j's forward just before segment j's adjoint.
The same kernel computes the same states and the adjoint chains through the kept end states
exactly, so the gradient is the default's bit for bit; every segment but the last runs its forward
twice (3 launches: forward, re-run, adjoint), all inside the same CUDA graph.

"unrolled": the state in per-thread local variables, as Dr.Jit keeps it. The step loop's bound is
a compile-time constant and the module option ``max_unroll`` is raised to it, so Warp unrolls the
loop at code generation: the differentiability guide ("Dynamic Loops") says a dynamic loop's
intermediates are not replayed in the backward pass, while a static loop within ``max_unroll`` is
unrolled and stores each iteration's values. The adjoint is Warp's generated reverse of the
unrolled code, which replays the segment's forward from its start state in registers or local
memory. Every kernel takes its steps from one wp.func (``_step``): the same arithmetic in the same
order, so the same bits; here the contact model is a constant argument, whose other branches the
compiler folds away in the inlined step. Only v, target and loss are arrays (v and loss with
gradients); the loss is computed in the same kernel.
Code size and compile time grow with the unrolled length, so a horizon longer than UNROLL_MAX is
cut into ceil(steps / UNROLL_MAX) equal segments, launched in turn, whose start states are kept in
(segments - 1, B) arrays with gradients; the segments' adjoints chain through their gradients.

``info()["design_bytes"]``: the bytes of the arrays the design keeps on the device, gradients
included, S = scalar size, K and n the steps and number of segments:
  every path:   (iters + 14) B S   (v0, target, v + grad, loss + grad, seed, grad0, the history)
  default, tape_zero, checkpoint: + 8 (K + 1 + n) B S   (work states and end states, + grads;
                default: K = steps, n = 1, so 8 (steps + 2) B S)
  unrolled:     + 8 (n - 1) B S   (segment start states + grads; none for steps <= UNROLL_MAX)
The unrolled rollout's own states are registers or local memory, which the port does not allocate:
on CUDA, info() reports the registers and local bytes per thread of the compiled forward and
backward functions (cuFuncGetAttribute) and the local memory the driver reserves for them, local
bytes per thread x resident threads (SMs x threads per SM).
"""
# (no "from __future__ import annotations": Warp evaluates kernel annotations from the closure)
import ctypes
import functools
import inspect
import math

import numpy as np
import warp as wp

from . import wp_device, wp_scalar
from ..base import ScenarioKernel

CONTACT = {"none": 0, "hard": 1, "soft": 2}
VARIANTS = ("default", "checkpoint", "tape_zero", "unrolled")
UNROLL_MAX = 256        # most steps one unrolled kernel holds (its code grows with them)
# Warp from the version that added ``retain_grad`` zeroes an array's gradient entry when the adjoint
# of the store to it reads it, so after a backward pass only arrays that are read but never written
# on the tape (here v) hold gradients; before it, every accumulated gradient must be cleared.
CONSUMES_GRADIENTS = "retain_grad" in inspect.signature(wp.zeros).parameters
# A Warp with wp.func's inlining hint (1.18 has it) forces the shared step inline (CUDA
# __forceinline__), as it was when each kernel spelled it out; an older one leaves it to the compiler.
inline_func = (functools.partial(wp.func, inline=True) if "inline" in inspect.signature(wp.func).parameters
               else wp.func)


@functools.cache
def _step(scalar):
    """The one definition of a step's arithmetic (scenarios/projectile.py's docstring; contact: 0
    none, 1 hard, 2 soft), called by the segment and the unrolled kernel: the same bits in both."""
    @inline_func
    def step(contact: int, dt: scalar, gravity: scalar, bounce: scalar, damping: scalar,
             stiffness: scalar, softness: scalar, x: scalar, y: scalar, vx: scalar, vy: scalar):
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
        return x, y, vx, vy

    return step


@functools.cache
def _kernels(scalar):
    step = _step(scalar)

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
            x, y, vx, vy = step(contact, dt, gravity, bounce, damping, stiffness, softness,
                                xs[s, b], ys[s, b], vxs[s, b], vys[s, b])
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


@functools.cache
def _unrolled(scalar, n: int, contact: str, max_unroll: int | None = None):
    """n steps unrolled in one thread: from v (seg 0) or the start state segment seg-1 kept, to
    the loss (seg == last) or the next start state. ``max_unroll`` below n: a control for the
    tests (Warp then emits a dynamic loop, whose loop-carried locals it differentiates wrongly)."""
    step, code = _step(scalar), CONTACT[contact]      # code: a constant the compiler folds

    @wp.kernel(module="unique", module_options={"max_unroll": n if max_unroll is None else max_unroll})
    def rollout(seg: int, last: int, dt: scalar, gravity: scalar, bounce: scalar, damping: scalar,
                stiffness: scalar, softness: scalar, v: wp.array2d(dtype=scalar),
                target: wp.array2d(dtype=scalar), ex: wp.array2d(dtype=scalar),
                ey: wp.array2d(dtype=scalar), evx: wp.array2d(dtype=scalar),
                evy: wp.array2d(dtype=scalar), loss: wp.array(dtype=scalar)):
        b = wp.tid()
        x = scalar(0.0)
        y = scalar(0.0)
        vx = scalar(0.0)
        vy = scalar(0.0)
        if seg == 0:
            vx = v[b, 0]
            vy = v[b, 1]
        else:
            x = ex[seg - 1, b]
            y = ey[seg - 1, b]
            vx = evx[seg - 1, b]
            vy = evy[seg - 1, b]
        for s in range(n):      # n is a closure constant within max_unroll: unrolled
            x, y, vx, vy = step(code, dt, gravity, bounce, damping, stiffness, softness, x, y, vx, vy)
        if seg == last:
            dx = x - target[b, 0]
            dy = y - target[b, 1]
            loss[b] = dx * dx + dy * dy
        else:
            ex[seg, b] = x
            ey[seg, b] = y
            evx[seg, b] = vx
            evy[seg, b] = vy

    return rollout


def segments(steps: int, variant: str) -> list[int]:
    """Steps per segment: the whole horizon; K = ceil(sqrt(steps)) each ("checkpoint"); or for
    "unrolled" ceil(steps / UNROLL_MAX) segments of nearly equal length (the last the rest)."""
    if variant == "checkpoint":
        k = math.isqrt(steps - 1) + 1
    elif variant == "unrolled":
        nseg = -(-steps // UNROLL_MAX)
        k = -(-steps // nseg)
    else:
        k = steps
    return [min(k, steps - i) for i in range(0, steps, k)]


def cuda_function_attributes(kernel, device: str) -> dict[str, int]:
    """Registers and local bytes per thread of ``kernel``'s compiled forward and backward CUDA
    functions (cuFuncGetAttribute), and the local memory the driver reserves for the larger:
    local bytes per thread x SMs x threads per SM. Empty on the CPU; the error, if the driver
    cannot say (the module not loaded yet, no libcuda)."""
    if not device.startswith("cuda"):
        return {}
    try:
        return _cuda_attributes(kernel, wp.get_device(device))
    except (OSError, RuntimeError, AttributeError) as exc:
        return {"cuda_attributes_error": f"{type(exc).__name__}: {exc}"}


def _cuda_attributes(kernel, dev) -> dict[str, int]:
    hooks = kernel.module.get_kernel_hooks(kernel, dev)
    cuda = ctypes.CDLL("libcuda.so.1")

    def attr(code: int, get, *handle) -> int:
        value = ctypes.c_int()
        rc = get(ctypes.byref(value), code, *handle)
        if rc != 0:
            raise RuntimeError(f"CUDA driver error {rc} reading attribute {code}")
        return value.value
    out = {}     # CUfunction_attribute 4: NUM_REGS, 3: LOCAL_SIZE_BYTES (CUDA driver API enums)
    for name, fn in (("forward", hooks.forward), ("backward", hooks.backward)):
        out[f"{name}_registers_per_thread"] = attr(4, cuda.cuFuncGetAttribute, ctypes.c_void_p(fn))
        out[f"{name}_local_bytes_per_thread"] = attr(3, cuda.cuFuncGetAttribute, ctypes.c_void_p(fn))
    per_sm = attr(39, cuda.cuDeviceGetAttribute, ctypes.c_int(dev.ordinal))   # max threads / SM
    local = max(out["forward_local_bytes_per_thread"], out["backward_local_bytes_per_thread"])
    out["local_reserved_bytes"] = local * per_sm * dev.sm_count
    return out


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs, device, precision, variant):
        if variant not in VARIANTS:
            raise ValueError(f"warp projectile has no variant {variant!r} (has {', '.join(VARIANTS)})")
        self.variant, self.unrolled = variant, variant == "unrolled"
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
        if self.unrolled:
            self.k_rollout = {n: _unrolled(scalar, n, params.contact) for n in set(self.seg_steps)}
            self.work = []                                      # the states stay in the threads
            self.ends = [z(nseg - 1, b) for _ in range(4)] if nseg > 1 else []  # start states
        else:
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
        consts = [c["dt"], c["gravity"], c["bounce"], c["damping"], c["stiffness"], c["softness"]]
        if self.unrolled:
            n, ends = self.seg_steps[j], self.ends or [None] * 4
            wp.launch(self.k_rollout[n], dim=self.batch,
                      inputs=[j, len(self.seg_steps) - 1, *consts, self.v, self.target],
                      outputs=[*ends, self.loss], device=self.dev)
            return
        wp.launch(self.k_segment, dim=self.batch,
                  inputs=[j, self.seg_steps[j], CONTACT[p.contact], *consts, self.v],
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
            # (the last segment's states are still in the buffers; unrolled adjoints replay their own)
            if checkpoint and self.variant == "checkpoint" and j < last:
                self.tape.record_func(self._recompute(j), arrays=self.work)
        if not self.unrolled:               # (the unrolled kernel computes the loss itself)
            wp.launch(self.k_loss, dim=self.batch, inputs=[last, self.target, self.ends[0], self.ends[1]],
                      outputs=[self.loss], device=self.dev)

    def accumulated(self) -> list:
        """The gradients a backward pass leaves nonzero, which the next one would add to: v's
        (read, never written, on the tape), and on a Warp that does not consume gradients
        (``CONSUMES_GRADIENTS``) the states' too. The loss's is overwritten by the seed."""
        return [self.v.grad] + ([] if CONSUMES_GRADIENTS else [a.grad for a in self.ends + self.work])

    def _clear(self) -> None:
        if self.variant == "tape_zero":
            self.tape.zero()
        else:
            for g in self.accumulated():
                g.zero_()

    def _optimise(self):
        wp.launch(self.k_reset, dim=self.batch, inputs=[self.v0], outputs=[self.v], device=self.dev)
        for k in range(self.p.iters + 1):
            self._forward()
            self.tape.backward(grads={self.loss: self.seed})
            wp.launch(self.k_update, dim=self.batch,
                      inputs=[k, self.p.iters, self.c["lr"], self.loss, self.v, self.v.grad],
                      outputs=[self.history, self.grad0], device=self.dev)
            self._clear()

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

    def design_bytes(self) -> int:
        """The device bytes the design keeps in arrays (module docstring's formula)."""
        p, b, nseg = self.p, self.batch, len(self.seg_steps)
        per_trajectory = p.iters + 14 + (8 * (nseg - 1) if self.unrolled
                                         else 8 * (self.seg_steps[0] + 1 + nseg))
        return per_trajectory * b * wp.types.type_size_in_bytes(self.v.dtype)

    def info(self) -> dict:
        nseg = len(self.seg_steps)
        info = {"path": self.variant, "cuda_graph": self.graph is not None, "threads": self.batch,
                "segments": nseg, "segment_steps": self.seg_steps[0],
                "states_kept_per_trajectory": nseg - 1 if self.unrolled else nseg + self.seg_steps[0] + 1,
                # kernel launches besides the tape's adjoint replays (one per segment, + the loss's)
                "launches_per_iteration": nseg + 1 if self.unrolled else 2 * nseg + 1,
                "gradients_cleared": "tape.zero()" if self.variant == "tape_zero"
                                     else f"{len(self.accumulated())} accumulated",
                "design_bytes": self.design_bytes()}
        if self.unrolled:
            info["arrays_kept"] = 7 + len(self.ends)        # v0, target, v, loss, seed, history, grad0
            info["arrays_with_grad"] = 2 + len(self.ends)
            info.update(cuda_function_attributes(self.k_rollout[self.seg_steps[0]], self.dev))
        return info
