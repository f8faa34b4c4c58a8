"""Differentiable projectile in Dr.Jit: reverse-mode AD (``dr.backward``) through ``dr.while_loop``.

Each gradient-descent iteration makes (vx, vy) fresh AD leaves, runs the steps as a
``dr.while_loop`` with ``max_iterations=steps`` (Dr.Jit's "general loop": reverse mode needs the
bound to size the trajectory it records), forms the loss and calls ``dr.backward(loss)``. The B
losses are independent, so seeding every element with 1 gives each trajectory its own gradient in
one backward pass; then ``v <- v - lr*grad`` (outside AD) and ``dr.eval`` of the loss, gradient and
new v. Iteration k records loss(v_k), keeps the gradient of iteration 0 and updates v only while
k < iters, so v_final = v_iters. The iterations are a host loop: each traces the same program,
which hits the kernel cache after the first call.

Variants (what each trades, memory against speed):

* ``default``: a symbolic loop. Dr.Jit compiles the forward loop, the loss and the reversed loop
  into one kernel per iteration; the forward stores each step's loop state in per-thread local
  arrays of ``max_iterations`` entries (one per state variable that changes, the step counter
  included), which the reverse loop reads back. Nothing of the tape reaches device arrays, but
  each thread's local storage grows with the horizon (on CUDA the driver reserves it for every
  resident thread; on the CPU it is stack).
* ``checkpoint``: the same steps as a symbolic loop over ceil(steps/K) segments of an inner
  symbolic loop of K = round(sqrt(steps)) steps, each loop with its own ``max_iterations``. The
  outer tape keeps segment boundaries; in reverse, each segment's forward is re-run to rebuild its
  K-step tape, so per-thread storage is O(steps/K + K) for one more forward pass. The forward
  arithmetic is the default's (losses bit for bit); the adjoint adds each segment's contributions
  in another order, so gradients agree to rounding, not bit for bit.
* ``evaluated``: ``mode="evaluated"``, Dr.Jit's other loop compilation: every step is a kernel
  launch and the AD graph records each step's operations, so the tape lives in device arrays
  (B x steps per recorded value) and is not bounded by per-thread local storage, at the price of
  about 2 x steps launches per iteration and the tape's device traffic. Same arithmetic as the
  default: the same outputs bit for bit on the CPU.

Memory (what ``info()["design_bytes"]`` predicts): the inputs (v0 and target, 2 x B each), the
loss history the scenario returns ((iters + 1) x B), the first gradient (2 x B) and the descent's
live state at its peak (v, its gradient and the next v: 6 x B), each of the cell's precision. One
call's history grows with the descent: on the CPU (LLVM, B = 2^18, float32) Dr.Jit's watermark
after a call is (iters + 8) x B x 4 bytes: 13, 28 and 68 MiB at iters = 5, 20 and 60. ``run()``
used to keep the previous call's result until it returned, so every call after the first held
two histories: 23, 53 and 133 MiB at the second call, the same slope as the H100's NVML figure
(362 MiB at 20 iterations, 682 at 60: 8 MiB per iteration at B = 2^20 where one history row is
4 MiB). ``run()`` now drops the last result first and returns nothing (a caller's ``r = run()``
would hold it too): the second call peaks at the first call's bytes, outputs unchanged.

The default's per-thread tape is also a limit on the CPU: Dr.Jit keeps it on the stack of its
worker threads (the process's stack size, ``ulimit -s``) with no check, so a horizon whose tape
outgrows the stack ends the process with a segmentation fault (docs/findings.md); the checkpoint
variant needs ~2 sqrt(steps) entries instead.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from . import download, fast_math, jit_module, real_type, scalar, upload
from ..base import ScenarioKernel
from scenarios.projectile import ProjectileParams
from ..base import Device
from scenarios.base import Precision

CONSTANTS = ("dt", "gravity", "bounce", "damping", "stiffness", "softness", "lr")
VARIANTS = ("default", "fastmath", "checkpoint", "evaluated")


def checkpoint_segment(steps: int) -> int:
    """The "checkpoint" variant's inner loop length: round(sqrt(steps))."""
    return max(1, round(steps ** 0.5))


def make_body(contact: str, c: dict[str, Any]):
    """One step of the scenario (its exact operation order) for a static contact model, as a
    ``dr.while_loop`` body over (step, x, y, vx, vy)."""
    import drjit as dr

    def body(i, x, y, vx, vy):
        acc = c["gravity"]
        if contact == "soft":
            z = -y / c["softness"]
            sp = dr.maximum(z, 0.0) + dr.log(1.0 + dr.exp(-dr.abs(z)))
            acc = c["gravity"] + c["stiffness"] * (c["softness"] * sp)
        vy = vy + acc * c["dt"]
        x = x + vx * c["dt"]
        y = y + vy * c["dt"]
        if contact == "hard":
            hit = y < 0.0
            y = dr.select(hit, 0.0, y)
            vy = dr.select(hit, -c["bounce"] * vy, vy)
            vx = dr.select(hit, c["damping"] * vx, vx)
        return i + 1, x, y, vx, vy

    return body


def simulate(steps: int, contact: str, c: dict[str, Any], vx: Any, vy: Any, uint: Any,
             variant: str) -> tuple[Any, Any]:
    """(x_N, y_N) from the origin at velocity (vx, vy), differentiable in reverse mode."""
    import drjit as dr
    n = dr.width(vx)
    zero = dr.zeros(type(vx), n)
    body = make_body(contact, c)
    state = (dr.zeros(uint, n), zero, zero, vx, vy)
    labels = ("step", "x", "y", "vx", "vy")
    k = checkpoint_segment(steps)
    if variant == "checkpoint" and k < steps:
        segments = math.ceil(steps / k)

        def segment(j, x, y, u, w):
            m = dr.minimum(uint(k), steps - j * k)          # the last segment may be shorter
            out = dr.while_loop((dr.zeros(uint, n), x, y, u, w), lambda i, *_: i < m, body,
                                labels=labels, label="segment", mode="symbolic", max_iterations=k)
            return (j + 1, *out[1:])

        out = dr.while_loop(state, lambda j, *_: j < segments, segment, labels=("segment",) + labels[1:],
                            label="segments", mode="symbolic", max_iterations=segments)
    else:
        mode = "evaluated" if variant == "evaluated" else "symbolic"
        out = dr.while_loop(state, lambda i, *_: i < steps, body, labels=labels, label="steps",
                            mode=mode, max_iterations=steps)
    return out[1], out[2]


class Kernel(ScenarioKernel):
    def __init__(self, params: ProjectileParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str) -> None:
        import drjit as dr
        if variant not in VARIANTS:
            raise ValueError(f"drjit projectile has no variant {variant!r} (has {', '.join(VARIANTS)})")
        self.cls = real_type(device, precision, ad=True)
        self.uint = jit_module(device, ad=True).UInt32
        self.params, self.variant, self.dtype = params, variant, np.dtype(precision)
        self.backend = dr.JitBackend.CUDA if device == "cuda" else dr.JitBackend.LLVM
        self.host = {k: np.asarray(inputs[k]) for k in ("v0", "target", *CONSTANTS)}
        self._upload()
        self.result: tuple = ()
        self.launches: float | None = None

    def _upload(self) -> None:
        # Dr.Jit orders a kernel's parameters by variable age, and the order is part of the IR the
        # kernel cache hashes: re-uploading everything in one order keeps set_input cache hits.
        self.v0 = self._columns(self.host["v0"])
        self.target = self._columns(self.host["target"])
        self.c = {k: scalar(self.host[k], self.cls) for k in CONSTANTS}

    def _columns(self, a: np.ndarray) -> tuple[Any, Any]:
        a = np.asarray(a).reshape(-1, 2)
        return upload(a[:, 0], self.cls), upload(a[:, 1], self.cls)

    def _value_and_grad(self, vx: Any, vy: Any) -> tuple[Any, Any, Any]:
        import drjit as dr
        vx, vy = dr.detach(vx), dr.detach(vy)      # fresh leaves: nothing accumulates across calls
        dr.enable_grad(vx, vy)
        p = self.params
        x, y = simulate(p.steps, p.contact, self.c, vx, vy, self.uint, self.variant)
        dx = x - self.target[0]
        dy = y - self.target[1]
        loss = dx * dx + dy * dy
        dr.backward(loss)                          # d loss_b / d v_b for every trajectory b
        return dr.detach(loss), dr.grad(vx), dr.grad(vy)

    def run(self) -> None:
        import drjit as dr
        iters, lr = self.params.iters, self.c["lr"]
        self.result = ()           # the last call's history is freed before this one builds its own
        before = dr.detail.launch_stats()[0]
        vx, vy = self.v0
        history, grad0 = [], ()
        for k in range(iters + 1):
            loss, gx, gy = self._value_and_grad(vx, vy)
            if k == 0:
                grad0 = (gx, gy)
            history.append(loss)
            if k < iters:                          # no update after the last evaluation
                vx, vy = vx - lr * gx, vy - lr * gy
            dr.eval(loss, gx, gy, vx, vy)
        self.launches = (dr.detail.launch_stats()[0] - before) / (iters + 1)
        self.result = (history, grad0, (vx, vy))
        # nothing returned: a caller's ``r = run()`` would keep this call's history alive through the next

    def set_input(self, name: str, value: np.ndarray) -> None:
        """``v0`` or ``target``, same shape: later runs trace the same program (kernel cache hits)."""
        if name not in ("v0", "target"):
            super().set_input(name, value)
        old = self.host[name]
        if np.shape(value) != old.shape:
            raise ValueError(f"{name} must keep its shape {old.shape}, got {np.shape(value)}")
        self.host[name] = np.asarray(value, dtype=old.dtype)
        self._upload()

    def outputs(self) -> dict[str, np.ndarray]:
        history, grad0, v = self.result
        b = self.params.batch
        shape = () if b == 1 else (b,)
        col = lambda a: download(a, self.dtype, (b,))      # noqa: E731
        hist = np.stack([col(h) for h in history]).reshape((len(history),) + shape)
        return {"loss": hist[0].copy(), "grad": np.stack([col(g) for g in grad0], -1).reshape(shape + (2,)),
                "loss_history": hist, "v_final": np.stack([col(a) for a in v], -1).reshape(shape + (2,))}

    def info(self) -> dict[str, Any]:
        import drjit as dr
        steps, k = self.params.steps, checkpoint_segment(self.params.steps)
        ckpt = self.variant == "checkpoint" and k < steps
        kept = math.ceil(steps / k) + k if ckpt else steps
        where = "device arrays (AD graph)" if self.variant == "evaluated" else "per-thread local arrays"
        return {"gradient": "dr.backward through dr.while_loop(max_iterations=steps)",
                "loop": ("symbolic, nested segments" if ckpt else
                         "evaluated" if self.variant == "evaluated" else "symbolic"),
                "segment_steps": k if ckpt else steps, "states_kept_per_trajectory": kept,
                "tape": where, "launches_per_iteration": self.launches, "batch": self.params.batch,
                "jit_peak_bytes": int(dr.detail.malloc_watermark(self.backend)), **self.design(), **fast_math()}

    def design(self) -> dict[str, Any]:
        """The device arrays the design keeps at its peak (module docstring, "Memory"), in bytes,
        and the per-thread local storage of the symbolic loops (not in the sum: the driver sizes
        it by resident threads, not by the batch). The evaluated variant's tape is Dr.Jit's AD
        graph, not predicted here."""
        p, item = self.params, self.dtype.itemsize
        col = p.batch * item                                  # one value per trajectory
        steps, k = p.steps, checkpoint_segment(p.steps)
        kept = math.ceil(steps / k) + k if self.variant == "checkpoint" and k < steps else steps
        if self.variant == "evaluated":
            return {}
        return {"local_bytes_per_thread": kept * (4 + 4 * item),      # step counter + x, y, vx, vy
                "design_bytes": {"inputs": 4 * col, "loss_history": (p.iters + 1) * col,
                                 "first_gradient": 2 * col, "descent_state": 6 * col}}
