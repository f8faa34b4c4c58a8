"""Differentiable projectile in NumPy: a hand-written discrete adjoint, vectorised over the batch.

NumPy has no autodiff, so the gradient is the reverse sweep written out, as in the Numba port and
the scenario's float64 oracle, with the B trajectories (B = 1 for the seed case) as the array
axis: every ufunc advances all trajectories by one step, and each trajectory descends on its own
loss, v_b <- v_b - lr*grad_b. The Python loops left are the inherent ones, over the iters + 1
evaluations and, in each, the steps forward and back (so a single trajectory pays ~4-18 ufunc
calls per step, and a batch spreads that over its trajectories).

Forward in Warp's operation order; the tape is what the reverse sweep reads and nothing else,
preallocated (steps, B) so a step is one contiguous row: y before each step for soft contact (the
forward writes y straight into the tape's next row: no copy), the hit flag for hard contact,
nothing for 'none'. The reverse sweep is ``adjoint`` of scenarios/projectile_adjoint.py with the
soft-contact term in the order of the other ports (Warp's tape; see backends/numba/projectile.py):
a_sp = eps*(k*(dt*avy)), a_z = e*((1/(1+e))*a_sp) with e = exp(-|z|) recomputed from the taped y,
a_z = a_sp - a_z where z > 0, ay -= a_z/eps. Terms that do not change over a sweep are computed
once with the same rounding (g*dt; vx*dt and ay*dt without contact; ax*dt always), which gives the
same bits as computing them per step. Every trajectory's arithmetic is independent of B, so batch
row 0 equals the batch = 1 run bit for bit.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import kernel_info, scalar_type
from ..base import ScenarioKernel

CONSTANTS = ("dt", "gravity", "bounce", "damping", "stiffness", "softness", "lr")


class Kernel(ScenarioKernel):
    def __init__(self, params, inputs: dict[str, np.ndarray], device: str, precision: str,
                 variant: str) -> None:
        S = scalar_type(precision)
        self.p, self.single = params, params.batch == 1
        B, steps = params.batch, params.steps
        dt, g, bounce, damping, k, eps, lr = (S(inputs[n]) for n in CONSTANTS)
        # -y/eps == y/(-eps) and -bounce*v == (-bounce)*v bit for bit (negation is exact)
        self.c = {"dt": dt, "gdt": g * dt, "g": g, "nbounce": -bounce, "damping": damping,
                  "k": k, "eps": eps, "neps": -eps, "lr": lr, "zero": S(0.0), "one": S(1.0),
                  "two": S(2.0)}
        self.v0 = np.empty((B, 2), S)
        self.target = np.empty((B, 2), S)
        self.tgx, self.tgy = np.empty(B, S), np.empty(B, S)    # contiguous target columns
        self.set_input("v0", inputs["v0"])
        self.set_input("target", inputs["target"])
        # the tape: y before each step (soft), the contact flag (hard); (steps, B), row per step
        self.ys = np.zeros((steps, B), S) if params.contact == "soft" else None
        self.hit = np.empty((steps, B), np.bool_) if params.contact == "hard" else None
        names = ("vxk", "vyk", "x", "y", "vx", "vy", "ax", "ay", "avx", "avy", "axdt", "t1", "t2", "t3")
        self.b = {n: np.empty(B, S) for n in names}
        self.mask = np.empty(B, np.bool_)
        self.history = np.empty((params.iters + 1, B), S)
        self.grad0 = np.empty((B, 2), S)
        self.v = np.empty((B, 2), S)
        self.forward, self.reverse = {"none": (self._fwd_none, self._rev_none),
                                      "hard": (self._fwd_hard, self._rev_hard),
                                      "soft": (self._fwd_soft, self._rev_soft)}[params.contact]

    def set_input(self, name: str, value: np.ndarray) -> None:
        if name not in ("v0", "target"):
            super().set_input(name, value)
        a = self.v0 if name == "v0" else self.target
        a[...] = np.reshape(value, a.shape)
        if name == "target":
            np.copyto(self.tgx, a[:, 0]); np.copyto(self.tgy, a[:, 1])

    # ---- forward passes: (x, y) final from (vx, vy) in b; the state buffers are overwritten ----
    def _fwd_none(self) -> np.ndarray:
        b, c = self.b, self.c
        x, y, vy, vxdt, t = b["x"], b["y"], b["vy"], b["t1"], b["t2"]
        gdt, dt = c["gdt"], c["dt"]
        np.multiply(b["vx"], dt, out=vxdt)             # vx is constant without contact
        for _ in range(self.p.steps):
            np.add(vy, gdt, out=vy)                    # vy += g*dt
            np.add(x, vxdt, out=x)                     # x += vx*dt
            np.multiply(vy, dt, out=t); np.add(y, t, out=y)   # y += vy*dt
        return y

    def _fwd_hard(self) -> np.ndarray:
        b, c = self.b, self.c
        x, y, vx, vy, t = b["x"], b["y"], b["vx"], b["vy"], b["t1"]
        gdt, dt, zero, nbounce, damping = c["gdt"], c["dt"], c["zero"], c["nbounce"], c["damping"]
        for hit in self.hit:
            np.add(vy, gdt, out=vy)
            np.multiply(vx, dt, out=t); np.add(x, t, out=x)
            np.multiply(vy, dt, out=t); np.add(y, t, out=y)
            np.less(y, zero, out=hit)                  # contact: y = 0, vy = -bounce*vy, vx = damping*vx
            np.copyto(y, zero, where=hit)
            np.multiply(vy, nbounce, out=vy, where=hit)
            np.multiply(vx, damping, out=vx, where=hit)
        return y

    def _fwd_soft(self) -> np.ndarray:
        b, c = self.b, self.c
        x, vy, z, e, t = b["x"], b["vy"], b["t1"], b["t2"], b["t3"]
        ys, steps = self.ys, self.p.steps
        dt, g, k, eps, neps, zero, one = (c[n] for n in ("dt", "g", "k", "eps", "neps", "zero", "one"))
        vxdt = b["axdt"]                               # free until the reverse sweep
        np.multiply(b["vx"], dt, out=vxdt)             # vx is constant with soft contact
        for s in range(steps):
            y = ys[s]                                  # ys[0] holds y_0 = 0
            np.divide(y, neps, out=z)                  # z = -y/eps
            np.abs(z, out=e); np.negative(e, out=e); np.exp(e, out=e)   # exp(-|z|)
            np.add(e, one, out=e); np.log(e, out=e)    # log(1 + exp(-|z|))
            np.maximum(z, zero, out=z); np.add(z, e, out=z)             # sp
            np.multiply(z, eps, out=z); np.multiply(z, k, out=z)        # k*(eps*sp)
            np.add(z, g, out=z); np.multiply(z, dt, out=z)              # acc*dt
            np.add(vy, z, out=vy)
            np.add(x, vxdt, out=x)
            np.multiply(vy, dt, out=t)
            np.add(y, t, out=ys[s + 1] if s + 1 < steps else b["y"])   # y_{s+1} into the tape
        return b["y"]

    # ---- reverse sweeps: (avx, avy) = d loss/d(vx0, vy0) from (ax, ay) = d loss/d(x_N, y_N) ----
    def _rev_none(self) -> None:
        b, dt = self.b, self.c["dt"]
        avx, avy, axdt, aydt = b["avx"], b["avy"], b["axdt"], b["t1"]
        np.multiply(b["ay"], dt, out=aydt)             # ay is constant without contact
        for _ in range(self.p.steps):
            np.add(avy, aydt, out=avy)                 # y1 = y + vy1*dt
            np.add(avx, axdt, out=avx)                 # x1 = x + vx*dt

    def _rev_hard(self) -> None:
        b, c = self.b, self.c
        ay, avx, avy, axdt, t = b["ay"], b["avx"], b["avy"], b["axdt"], b["t1"]
        dt, zero, nbounce, damping = c["dt"], c["zero"], c["nbounce"], c["damping"]
        for hit in self.hit[::-1]:
            np.copyto(ay, zero, where=hit)
            np.multiply(avy, nbounce, out=avy, where=hit)
            np.multiply(avx, damping, out=avx, where=hit)
            np.multiply(ay, dt, out=t); np.add(avy, t, out=avy)
            np.add(avx, axdt, out=avx)

    def _rev_soft(self) -> None:
        b, c = self.b, self.c
        ay, avx, avy, axdt, t, z, e = (b[n] for n in ("ay", "avx", "avy", "axdt", "t1", "t2", "t3"))
        dt, k, eps, neps, zero, one = (c[n] for n in ("dt", "k", "eps", "neps", "zero", "one"))
        pos = self.mask
        for y in self.ys[::-1]:
            np.multiply(ay, dt, out=t); np.add(avy, t, out=avy)         # y1 = y + vy1*dt
            np.add(avx, axdt, out=avx)                                  # x1 = x + vx*dt
            # vy1 = vy + acc(y)*dt, acc = g + k*(eps*sp(z)), z = -y/eps
            np.multiply(avy, dt, out=t); np.multiply(t, k, out=t); np.multiply(t, eps, out=t)  # a_sp
            np.divide(y, neps, out=z)
            np.greater(z, zero, out=pos)
            np.abs(z, out=e); np.negative(e, out=e); np.exp(e, out=e)   # e = exp(-|z|)
            np.add(e, one, out=z); np.divide(one, z, out=z)             # 1/(1+e)
            np.multiply(z, t, out=z); np.multiply(e, z, out=z)          # a_z = e*((1/(1+e))*a_sp)
            np.subtract(t, z, out=z, where=pos)                         # z > 0: a_sp - a_z
            np.divide(z, eps, out=z); np.subtract(ay, z, out=ay)        # ay -= a_z/eps

    def run(self) -> None:
        b, c, p = self.b, self.c, self.p
        vxk, vyk, ax, ay, avx, avy, t = (b[n] for n in ("vxk", "vyk", "ax", "ay", "avx", "avy", "t1"))
        two, lr = c["two"], c["lr"]
        np.copyto(vxk, self.v0[:, 0]); np.copyto(vyk, self.v0[:, 1])
        for it in range(p.iters + 1):
            b["x"].fill(0); b["y"].fill(0)
            np.copyto(b["vx"], vxk); np.copyto(b["vy"], vyk)
            y = self.forward()
            loss = self.history[it]
            np.subtract(b["x"], self.tgx, out=ax); np.subtract(y, self.tgy, out=ay)   # dx, dy
            np.multiply(ax, ax, out=loss); np.multiply(ay, ay, out=t); np.add(loss, t, out=loss)
            np.multiply(ax, two, out=ax); np.multiply(ay, two, out=ay)  # seeds 2 dx, 2 dy
            avx.fill(0); avy.fill(0)
            np.multiply(ax, c["dt"], out=b["axdt"])    # ax is constant over the sweep
            self.reverse()
            if it == 0:
                np.copyto(self.grad0[:, 0], avx); np.copyto(self.grad0[:, 1], avy)
            if it < p.iters:                           # v <- v - lr*grad
                np.multiply(avx, lr, out=t); np.subtract(vxk, t, out=vxk)
                np.multiply(avy, lr, out=t); np.subtract(vyk, t, out=vyk)
        np.copyto(self.v[:, 0], vxk); np.copyto(self.v[:, 1], vyk)

    def outputs(self) -> dict[str, np.ndarray]:
        hist, grad, v = self.history.copy(), self.grad0.copy(), self.v.copy()
        if self.single:
            hist, grad, v = hist[:, 0], grad[0], v[0]
        return {"loss": np.array(hist[0]), "grad": grad, "loss_history": hist, "v_final": v}

    def info(self) -> dict[str, Any]:
        tape = sum(a.nbytes for a in (self.ys, self.hit) if a is not None)
        return kernel_info(batch=self.p.batch, tape_layout="(steps, batch)", tape_bytes=tape)
