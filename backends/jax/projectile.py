"""Differentiable projectile in JAX: reverse-mode AD (jax.value_and_grad) through lax.scan.

One jitted program holds the whole run: a lax.scan over the iters+1 gradient-descent iterations,
each a value_and_grad of the step scan (static trip count, ``unroll`` steps per trip; its
transpose, the backward scan, is unrolled alike). Iteration k records loss(v_k), keeps the
gradient of iteration 0 and updates v only while k < iters, so v_final = v_iters.

Batch (B > 1 trajectories, each with its own v0 and target): jax.vmap of the one-trajectory
value_and_grad, so every trajectory runs the batch = 1 arithmetic unchanged (row 0 equals batch = 1
bit for bit on CPU; the loss keeps its two products apart, which XLA:CPU would otherwise contract
into an FMA in some shapes only) and each descends on its own loss. The alternative, broadcasting the state over
B and taking value_and_grad of the summed loss, gave the same results bit for bit, the same
temporary memory and the same run time on CPU (B = 4096, soft and hard, unroll 1 and 16; not yet
measured on a GPU): both lower to one scan of elementwise-over-B steps, and the optimised CPU HLO
is identical for soft contact (for hard it differs only in fusion operands). vmap is kept because
it leaves the per-trajectory code as is.

Memory: reverse mode keeps each step's residuals (a few scalars per step and trajectory). For long
horizons ``remat_segment`` = K > 0 (the variant "checkpoint": K = round(sqrt(steps))) checkpoints
the rollout in segments of K steps (jax.checkpoint around an inner scan): only segment boundaries
are kept and each segment is recomputed during the backward pass, so memory drops from O(steps)
to O(steps/K + K) for one extra forward pass. info() reports the compiled program's temporary and
argument memory either way.
"""
from __future__ import annotations

import functools
from typing import Any

import numpy as np

from . import UNROLL, Program, jax_device, put
from ..base import ScenarioKernel
from scenarios.projectile import ProjectileParams
from ..base import Device
from scenarios.base import Precision

# Shared scalar constants; v0 and target are per trajectory.
CONSTANTS = ("dt", "gravity", "bounce", "damping", "stiffness", "softness", "lr")
VARIANTS = ("default", "graph", "checkpoint")   # graph: XLA command buffers, set per process (__init__.GRAPH_FLAGS)


def checkpoint_segment(steps: int) -> int:
    """The "checkpoint" variant's segment length: round(sqrt(steps)) (O(sqrt(steps)) memory)."""
    return max(1, round(steps ** 0.5))


def _make_step(contact: str, c: dict[str, Any]):
    """One step of the scenario (its exact operation order) for a static contact model; works on
    scalars and, elementwise, on arrays of trajectories."""
    import jax.numpy as jnp
    zero = jnp.zeros((), dtype=c["dt"].dtype)
    one = jnp.ones((), dtype=c["dt"].dtype)
    dt, gravity = c["dt"], c["gravity"]

    def step(state, _):
        x, y, vx, vy = state
        acc = gravity
        if contact == "soft":
            z = -y / c["softness"]
            sp = jnp.maximum(z, zero) + jnp.log(one + jnp.exp(-jnp.abs(z)))
            acc = gravity + c["stiffness"] * (c["softness"] * sp)
        vy = vy + acc * dt
        x = x + vx * dt
        y = y + vy * dt
        if contact == "hard":
            hit = y < zero
            y = jnp.where(hit, zero, y)
            vy = jnp.where(hit, -c["bounce"] * vy, vy)
            vx = jnp.where(hit, c["damping"] * vx, vx)
        return (x, y, vx, vy), None

    return step


def _optimise(steps: int, iters: int, contact: str, remat_segment: int, unroll: int,
              v0, target, consts, out):
    import jax
    import jax.numpy as jnp
    from jax import lax
    del out  # donated: its buffers receive the results
    c = dict(zip(CONSTANTS, consts))
    step = _make_step(contact, c)

    def scan_steps(state, n):
        return lax.scan(step, state, None, length=n, unroll=max(1, min(unroll, n)))[0]

    def simulate(state):
        if not 0 < remat_segment < steps:
            return scan_steps(state, steps)
        segments, tail = divmod(steps, remat_segment)
        segment = jax.checkpoint(lambda s: scan_steps(s, remat_segment), prevent_cse=False)
        state = lax.scan(lambda s, _: (segment(s), None), state, None, length=segments)[0]
        return scan_steps(state, tail)

    def loss_fn(v, tgt):
        """One trajectory's loss: v, tgt of shape (2,)."""
        zero = jnp.zeros((), dtype=v.dtype)
        x, y, _, _ = simulate((zero, zero, v[0], v[1]))
        dx = x - tgt[0]
        dy = y - tgt[1]
        # the scenario's arithmetic, two roundings then a sum: without the barrier XLA:CPU may
        # contract dx*dx + dy*dy into an FMA in one compiled shape and not another
        dx2, dy2 = lax.optimization_barrier((dx * dx, dy * dy))
        return dx2 + dy2

    value_and_grad = jax.value_and_grad(loss_fn)
    if v0.ndim == 2:                     # a batch: the one-trajectory program, vectorised
        value_and_grad = jax.vmap(value_and_grad)

    def iteration(carry, k):
        v, grad0 = carry
        loss, g = value_and_grad(v, target)
        grad0 = jnp.where(k == 0, g, grad0)
        v = jnp.where(k < iters, v - c["lr"] * g, v)   # no update after the last evaluation
        return (v, grad0), loss

    (v, grad0), history = lax.scan(iteration, (v0, jnp.zeros_like(v0)), jnp.arange(iters + 1))
    return history[0], grad0, history, v


class Kernel(ScenarioKernel):
    def __init__(self, params: ProjectileParams, inputs: dict[str, np.ndarray], device: Device, precision: Precision,
                 variant: str, remat_segment: int | None = None, unroll: int | None = None) -> None:
        import jax.numpy as jnp
        if variant not in VARIANTS:
            raise ValueError(f"projectile has no variant {variant!r} in JAX (offered: {VARIANTS})")
        if remat_segment is None:
            remat_segment = checkpoint_segment(params.steps) if variant == "checkpoint" else 0
        dev = jax_device(device)
        self.params = params
        self.remat_segment = remat_segment
        self.precision, self.dev = precision, dev
        self.v0 = put(inputs["v0"], precision, dev)
        self.target = put(inputs["target"], precision, dev)
        self.consts = tuple(put(inputs[k], precision, dev) for k in CONSTANTS)
        dt, b = self.v0.dtype, self.v0.shape[:-1]
        self.out = (jnp.empty(b, dt, device=dev), jnp.empty(b + (2,), dt, device=dev),
                    jnp.empty((params.iters + 1,) + b, dt, device=dev), jnp.empty(b + (2,), dt, device=dev))
        self.unroll = unroll = UNROLL[device] if unroll is None else unroll
        fn = functools.partial(_optimise, params.steps, params.iters, params.contact, remat_segment,
                               unroll)
        self.program = Program(fn, donate=(3,))

    def run(self) -> Any:
        self.out = self.program(self.v0, self.target, self.consts, self.out)
        return self.out

    def set_input(self, name: str, value: np.ndarray) -> None:
        """``v0`` or ``target``, same shape: the compiled program is reused as is."""
        if name not in ("v0", "target"):
            super().set_input(name, value)
        old = getattr(self, name)
        if np.shape(value) != old.shape:
            raise ValueError(f"{name} must keep its shape {old.shape}, got {np.shape(value)}")
        setattr(self, name, put(value, self.precision, self.dev))

    def outputs(self) -> dict[str, np.ndarray]:
        loss, grad, history, v = (np.asarray(a) for a in self.out)
        return {"loss": loss, "grad": grad, "loss_history": history, "v_final": v}

    def info(self) -> dict[str, Any]:
        b = self.params.batch
        how = "" if b == 1 else ", jax.vmap over trajectories"
        return {**self.program.info(), "gradient": "jax.value_and_grad through lax.scan" + how,
                "remat_segment": self.remat_segment, "unroll": self.unroll, "batch": b,
                "design_bytes": self.design()}

    def design(self) -> dict[str, int]:
        """The bytes the design keeps (issue 56): inputs, the donated outputs and XLA's temporaries as
        its compiled program plans them (``memory_analysis``). XLA decides what the reverse pass
        keeps, and keeps only what the transposed step needs: for the hard contact one predicate
        byte per step and trajectory, not the four state values a tape would (53 float32 columns
        of temporaries for 180 steps on the CPU, against 720 for four values a step); the
        ``checkpoint`` variant's recomputed segments keep fewer still. Empty before the first call
        compiles the program."""
        i = self.program.info()
        if "temp_bytes" not in i:
            return {}
        return {"inputs": i["argument_bytes"] - i["alias_bytes"], "outputs": i["output_bytes"],
                "xla_temporaries": i["temp_bytes"]}
