"""What the Taichi and Quadrants projectile ports share: one definition, built for either module.

Not a scenario file: backends/taichi/projectile.py and backends/quadrants/projectile.py call
``build(ti)`` with ``taichi`` or ``quadrants`` (Taichi's fork, the same API) and keep what
differs themselves: the step, the fused rollout and the per-step kernel (the Taichi port's
guards against Taichi 1.7's autodiff defects, which the Quadrants port does not carry), the
state allocation and how a gradient is evaluated. Shared here: the initial state and the loss
(``@func``s the ports' rollouts call), the per-step path's init and loss kernels, the reset and
update kernels (which also zero the gradients and re-seed loss.grad), and ``FieldKernel``, the
base of both ports' ``Kernel``: inputs, the per-trajectory fields, run(), set_input, outputs.
Importing this module imports neither framework.
"""
# (no "from __future__ import annotations": Taichi and Quadrants read kernel annotations as objects)

import functools
from types import ModuleType
from typing import Any

import numpy as np

from . import framework_config_info
from ..base import ScenarioKernel
from scenarios.projectile import ProjectileParams
from ..base import Device
from scenarios.base import Precision

NONE, HARD, SOFT = 0, 1, 2
CONTACT = {"none": NONE, "hard": HARD, "soft": SOFT}


@functools.cache
def build(ti: ModuleType) -> tuple[Any, ...]:
    """(_init, _loss, _init_k, _loss_k, _reset, _update, FieldKernel) in ``ti``: ``taichi`` or
    ``quadrants``."""

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
    def _init_k(v: ti.template(), xs: ti.template(), ys: ti.template(), vxs: ti.template(),
                vys: ti.template()):
        for b in range(xs.shape[1]):
            _init(b, v, xs, ys, vxs, vys)

    @ti.kernel
    def _loss_k(steps: ti.i32, target: ti.template(), xs: ti.template(), ys: ti.template(),
                loss: ti.template()):
        for b in range(loss.shape[0]):
            _loss(b, steps, target, xs, ys, loss)

    @ti.func
    def _zero_grads(v: ti.template(), loss: ti.template(), xs: ti.template(), ys: ti.template(),
                    vxs: ti.template(), vys: ti.template()):
        # Backward passes accumulate (+=) into every .grad: clear them and re-seed
        # d loss_b/d loss_b = 1 (independent losses: no cross terms).
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
                history: ti.template(), grad0: ti.template(), xs: ti.template(),
                ys: ti.template(), vxs: ti.template(), vys: ti.template()):
        for b in range(loss.shape[0]):     # each trajectory descends on its own loss
            history[k, b] = loss[b]
            if k == 0:
                grad0[b, 0] = v.grad[b, 0]
                grad0[b, 1] = v.grad[b, 1]
            if k < iters:                  # no update after the last evaluation
                v[b, 0] = v[b, 0] - lr * v.grad[b, 0]
                v[b, 1] = v[b, 1] - lr * v.grad[b, 1]
        _zero_grads(v, loss, xs, ys, vxs, vys)

    class FieldKernel(ScenarioKernel):
        """A port's ``Kernel`` implements ``_allocate`` (its state fields) and ``_evaluate``, and
        says which ``path`` the rollout takes: "fused" (one launch each way, the step loop a
        run-time loop reversed through adstacks), "per_step" (one launch per step) or
        "checkpoint" (Taichi only)."""
        path = "fused"

        def __init__(self, params: ProjectileParams, inputs: dict[str, np.ndarray], device: Device,
                     precision: Precision, variant: str) -> None:
            self.p = params
            self.batch = nb = int(params.batch)
            self.contact = CONTACT[params.contact]
            self.consts = [float(inputs[k]) for k in ("dt", "gravity", "bounce", "damping",
                                                      "stiffness", "softness")]
            self.lr = float(inputs["lr"])
            self.elem = 8 if precision == Precision.FLOAT64 else 4    # bytes of a float
            # the fields whose gradients the update kernel clears
            self.cleared = self._allocate(params, device, variant)
            self.v = ti.field(float, (nb, 2), needs_grad=True)
            self.loss = ti.field(float, nb, needs_grad=True)
            self.v0 = ti.field(float, (nb, 2))
            self.target = ti.field(float, (nb, 2))
            self.set_input("v0", inputs["v0"])
            self.target.from_numpy(np.ascontiguousarray(np.reshape(inputs["target"], (nb, 2))))
            self.history = ti.field(float, (params.iters + 1, nb))
            self.grad0 = ti.field(float, (nb, 2))

        def _allocate(self, params: ProjectileParams, device: str, variant: str) -> list:
            """Allocate ``self.state`` (xs, ys, vxs, vys, indexed [s, b]) and whatever else the
            port needs; return the fields whose gradients the update kernel clears."""
            raise NotImplementedError

        def _evaluate(self) -> None:
            """Losses at the current v into loss, their gradients into v.grad (grads zeroed
            before)."""
            raise NotImplementedError

        def _evaluate_per_step(self, step_k: Any, *step_fields: Any) -> None:
            """``_evaluate`` by one launch per step over the B trajectories (Warp's scheme):
            ``step_k(s, contact, *consts, *step_fields)`` advances step s."""
            p, c, st = self.p, self.consts, self.state
            _init_k(self.v, *st)
            for s in range(p.steps):
                step_k(s, self.contact, *c, *step_fields)
            _loss_k(p.steps, self.target, st[0], st[1], self.loss)
            _loss_k.grad(p.steps, self.target, st[0], st[1], self.loss)
            for s in reversed(range(p.steps)):
                step_k.grad(s, self.contact, *c, *step_fields)
            _init_k.grad(self.v, *st)

        def run(self) -> None:
            _reset(self.v0, self.v, self.loss, *self.cleared)
            for k in range(self.p.iters + 1):
                self._evaluate()
                _update(k, self.p.iters, self.lr, self.loss, self.v, self.history, self.grad0,
                        *self.cleared)

        def set_input(self, name: str, value: np.ndarray) -> None:
            if name != "v0":
                super().set_input(name, value)
            value = np.asarray(value)
            if value.shape != ((2,) if self.batch == 1 else (self.batch, 2)):
                raise ValueError(f"v0 must keep its shape, got {value.shape}")
            self.v0.from_numpy(np.ascontiguousarray(value.reshape(self.batch, 2)))

        def outputs(self) -> dict[str, np.ndarray]:
            hist, grad, v = self.history.to_numpy(), self.grad0.to_numpy(), self.v.to_numpy()
            if self.batch == 1:        # the unbatched shapes: loss (), grad (2,), history (iters+1,)
                return {"loss": hist[0, 0], "grad": grad[0],
                        "loss_history": np.ascontiguousarray(hist[:, 0]), "v_final": v[0]}
            return {"loss": hist[0], "grad": grad, "loss_history": hist, "v_final": v}

        def info(self) -> dict[str, Any]:
            fused = self.path == "fused"               # one launch forward, one backward
            return {"storage": "field", **framework_config_info(ti.__name__), "rollout": self.path,
                    "fused_rollout": fused,
                    "launches_per_iteration": 3 if fused else 2 * self.p.steps + 5,
                    "batch": self.batch}

    return _init, _loss, _init_k, _loss_k, _reset, _update, FieldKernel
