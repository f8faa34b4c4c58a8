"""Differentiable projectile: loss, gradient and a gradient-descent history.

State (x, y, vx, vy) starts at the origin with velocity v0 = (vx0, vy0). One step:
    none:  vy += g*dt;                         x += vx*dt;  y += vy*dt
    soft:  vy += (g + k*pen(y))*dt;            x += vx*dt;  y += vy*dt
           pen(y) = eps*softplus(-y/eps), softplus(z) = max(z, 0) + log(1 + exp(-|z|)),
           a smooth penetration depth (-> max(-y, 0) as eps -> 0): a stiff, smooth ground spring.
    hard:  the 'none' step, then the particles' rule at the ground y = 0:
           if y < 0: y = 0; vy = -bounce*vy; vx = damping*vx
Loss = (x_N - tx)^2 + (y_N - ty)^2. Outputs: ``loss`` and ``grad`` = d loss/d(vx0, vy0) at v0, and
``loss_history``: iters steps of plain gradient descent v <- v - lr*grad, history[k] = loss(v_k)
for k = 0..iters (so history[0] == loss), and ``v_final`` = v_iters.

Default lr. The seed's lr = 0.08 diverges: with contact 'none' the loss is quadratic with Hessian
2 (N dt)^2 I = 40.5 I, so gradient descent is stable only for lr < 2/40.5 = 0.049. We default to
lr = 0.01 (also one of the seed's suggested rates, contraction factor 0.595 per step); 0.08 and
0.2 are exercised by the stability suite.

Oracle: for 'none' the closed form (x_N = vx0 N dt, y_N = vy0 N dt + g dt^2 N(N+1)/2); for
'hard' and 'soft' a float64 rollout with its hand-written discrete adjoint (checked against
central finite differences in the tests). The oracle also carries first-order running bounds on
the rounding error of the state (as in the particles scenario), from which the tolerances for
loss, gradient and history are derived (see ``check``).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Literal

import numpy as np

from .base import (REF_FACTOR, Check, Scenario, UNIT_ROUNDOFF, dt_reference, dtype_of, precision_of,
                   require, run_label)

CONSTANTS = ("dt", "gravity", "target_x", "target_y", "bounce", "damping", "stiffness",
             "softness", "lr")
# Time-against-error sweep: dt halves down the list at a fixed simulated time SWEEP_T (the
# default 180 steps of 0.025 s; every dt divides it exactly), loss and gradient at v0 (iters 0),
# soft contact unless the sweep's --set contact=... says otherwise.
SWEEP_T = 4.5
SWEEP_DT = {False: (0.05, 0.025, 0.0125, 0.00625, 0.003125, 0.0015625), True: (0.05, 0.025, 0.0125)}
SWEEP_CONTACT = "soft"


@dataclasses.dataclass(frozen=True)
class ProjectileParams:
    steps: int = 180
    dt: float = 0.025
    gravity: float = -9.8
    target_x: float = 3.8
    target_y: float = 0.0
    vx0: float = 2.0
    vy0: float = 6.5
    contact: Literal["none", "hard", "soft"] = "none"
    bounce: float = 0.82
    damping: float = 0.985
    stiffness: float = 1000.0
    softness: float = 0.01
    iters: int = 60
    lr: float = 0.01

    def validate(self) -> None:
        require(1 <= self.steps <= 10**7, f"steps must be in [1, 1e7], got {self.steps}")
        require(math.isfinite(self.dt) and 0.0 < self.dt <= 1.0,
                f"dt must be finite and in (0, 1], got {self.dt}")
        for k in ("gravity", "target_x", "target_y", "vx0", "vy0"):
            v = getattr(self, k)
            require(math.isfinite(v) and abs(v) <= 1e6, f"{k} must be finite with |{k}| <= 1e6, got {v}")
        require(math.isfinite(self.bounce) and 0.0 <= self.bounce <= 10.0,
                f"bounce must be in [0, 10], got {self.bounce}")
        require(math.isfinite(self.damping) and 0.0 <= self.damping <= 10.0,
                f"damping must be in [0, 10], got {self.damping}")
        require(math.isfinite(self.stiffness) and 0.0 <= self.stiffness <= 1e8,
                f"stiffness must be in [0, 1e8], got {self.stiffness}")
        require(math.isfinite(self.softness) and 0.0 < self.softness <= 1e3,
                f"softness must be in (0, 1e3], got {self.softness}")
        require(0 <= self.iters <= 10**6, f"iters must be in [0, 1e6], got {self.iters}")
        require(math.isfinite(self.lr) and 0.0 <= self.lr <= 1e3, f"lr must be in [0, 1e3], got {self.lr}")


def _softplus(z: float) -> float:
    return max(z, 0.0) + math.log(1.0 + math.exp(-abs(z)))


def _sigmoid(z: float) -> float:
    return 1.0 / (1.0 + math.exp(-z)) if z >= 0 else math.exp(z) / (1.0 + math.exp(z))


def rollout(c: dict[str, float], contact: str, steps: int, vx: float, vy: float):
    """Float64 forward pass. Returns the final state and, per step, what the analyses need."""
    dt, g = c["dt"], c["gravity"]
    eps, k = c["softness"], c["stiffness"]
    x = y = 0.0
    tape = []
    for _ in range(steps):
        state = (x, y, vx, vy)
        acc, dacc, d2acc, racc = g, 0.0, 0.0, 0.0
        if contact == "soft":
            z = -y / eps
            e = math.exp(-abs(z))
            lg = math.log(1.0 + e)
            sp = max(z, 0.0) + lg
            acc = g + k * eps * sp
            sig = _sigmoid(z)
            dacc = -k * sig                           # d acc / d y
            d2acc = k * sig * (1.0 - sig) / eps       # d^2 acc / d y^2
            # rounding of acc, operation by operation (z, exp, log1p, sum, eps*, k*, g+)
            racc = k * eps * (abs(z) + 3.0 * e + 2.0 * lg + sp) + 2.0 * k * eps * sp + abs(acc)
        vy = vy + acc * dt
        x = x + vx * dt
        y = y + vy * dt
        hit = contact == "hard" and y < 0.0
        if hit:
            y = 0.0
            vy = -c["bounce"] * vy
            vx = c["damping"] * vx
        tape.append((state, (x, y, vx, vy), acc, dacc, d2acc, racc, hit))
    return (x, y, vx, vy), tape


def adjoint(c: dict[str, float], tape, ax: float, ay: float, record: bool = False):
    """Reverse sweep of ``rollout``: given d/d(x_N, y_N), return d/d(vx0, vy0).

    With ``record`` it also returns, per step (forward order), the adjoint of vy after the
    velocity update and the magnitudes the sweep rounds (for the error analysis).
    """
    dt = c["dt"]
    avx = avy = 0.0
    trace = []
    for _, _, _, dacc, _, _, hit in reversed(tape):
        r = np.zeros(4)
        if hit:
            ay = 0.0
            avy = -c["bounce"] * avy
            avx = c["damping"] * avx
            r[2] += abs(avx); r[3] += abs(avy)
        avy = avy + ay * dt          # y1 = y + vy1*dt
        avx = avx + ax * dt          # x1 = x + vx*dt
        r[2] += abs(ax * dt) + abs(avx); r[3] += abs(ay * dt) + abs(avy)
        if dacc != 0.0:
            ay = ay + avy * dacc * dt    # vy1 = vy + acc(y)*dt
            r[1] += 2.0 * abs(avy * dacc * dt) + abs(ay)
        trace.append((avy, r))
    if record:
        return (avx, avy), trace[::-1]
    return avx, avy


def step_jacobian(c: dict[str, float], dacc: float, hit: bool) -> np.ndarray:
    """d(x1, y1, vx1, vy1)/d(x, y, vx, vy) of one step."""
    dt = c["dt"]
    a = np.array([[1.0, 0.0, dt, 0.0],
                  [0.0, 1.0 + dt * dt * dacc, 0.0, dt],
                  [0.0, 0.0, 1.0, 0.0],
                  [0.0, dt * dacc, 0.0, 1.0]])
    if hit:
        a[1, :] = 0.0
        a[2, :] *= c["damping"]
        a[3, :] *= -c["bounce"]
    return a


def error_bounds(c: dict[str, float], contact: str, tape, loss: float, dx: float, dy: float,
                 u: float) -> tuple[float, np.ndarray]:
    """First-order rounding-error bounds on the loss and on each gradient component.

    Linear error analysis with exact propagation: every operation of step k rounds with
    |delta| <= u|result|, giving a local error vector r_k; it reaches step m through the transition
    matrix Phi(m, k) = A_m ... A_{k+1}, so |err_m| <= sum_k |Phi(m, k)| r_k (elementwise |.|),
    which keeps the cancellation of an oscillating or contracting scheme instead of adding
    absolute values step by step.
      loss:  |d loss| <= 2|dx|(E_x + u|dx|) + 2|dy|(E_y + u|dy|) + 3u*loss
      grad:  (a) the seeds 2(dx, dy) carry 2 E_N through J^T;  (b) the reverse sweep's own
             rounding rr_k reaches the gradient through Phi(k, 0)^T;  (c) for soft contact the
             sweep's coefficient dacc(y_k) is off by |d2acc| E_k,y + 4u|dacc| (y_k's error E_k,y).
    """
    dt = c["dt"]
    n = len(tape)
    local = np.zeros((n, 4))
    mats = np.zeros((n, 4, 4))
    for i, (_, (x1, y1, vx1, vy1), acc, dacc, _, racc, hit) in enumerate(tape):
        (x0, y0, vx0, vy0) = tape[i][0]
        vy_mid = vy0 + acc * dt
        r_vy = dt * u * racc + u * abs(acc * dt) + u * abs(vy_mid)
        r = np.array([u * (abs(vx0 * dt) + abs(x1)),
                      u * (abs(vy_mid * dt) + abs(y0 + vy_mid * dt)) + dt * r_vy,
                      0.0, r_vy])
        if hit:
            r[1] = 0.0
            r[3] = c["bounce"] * r[3] + u * abs(vy1)
            r[2] = u * abs(vx1)
        local[i] = r
        mats[i] = step_jacobian(c, dacc, hit)
    # Phi(N, k) for every k by a backward product; forward tangents Phi(k, 0) by a forward one.
    back = np.eye(4)
    err_final = np.zeros(4)
    for i in range(n - 1, -1, -1):
        err_final += np.abs(back) @ local[i]
        back = back @ mats[i]
    jac_v = back[:2, 2:4]                      # d(x_N, y_N)/d(vx0, vy0)
    ex, ey = err_final[0], err_final[1]
    tol_loss = 2 * abs(dx) * (ex + u * abs(dx)) + 2 * abs(dy) * (ey + u * abs(dy)) + 3 * u * loss
    seeds = 2.0 * np.array([ex + u * abs(dx), ey + u * abs(dy)])
    tol_grad = np.abs(jac_v).T @ seeds
    _, trace = adjoint(c, tape, 2.0 * dx, 2.0 * dy, record=True)
    fwd = np.eye(4)
    ey_k = 0.0
    errs = np.zeros((0, 4))        # rounding injected so far, for E_k,y (soft only)
    mats_so_far = np.zeros((0, 4, 4))
    for i, (_, _, _, dacc, d2acc, _, _) in enumerate(tape):
        avy, rr = trace[i]
        # (b): error injected into the adjoint at step i reaches the gradient via Phi(i, 0)^T
        tol_grad += np.abs(fwd[:, 2:4]).T @ (u * rr)
        if contact == "soft":
            if len(errs):
                ey_k = float(np.sum(np.abs(mats_so_far[:, 1, :]) * errs))
            coeff_err = abs(d2acc) * ey_k + 4.0 * u * abs(dacc)
            tol_grad += abs(avy) * dt * coeff_err * np.abs(fwd[1, 2:4])
            # Phi(i+1, j) = A_i Phi(i, j): update the stack, then add step i's own rounding
            mats_so_far = np.concatenate([np.einsum("ab,kbc->kac", mats[i], mats_so_far),
                                          np.eye(4)[None]], axis=0) if len(errs) else np.eye(4)[None]
            errs = np.vstack([errs, local[i]])
        fwd = mats[i] @ fwd
    return float(tol_loss), tol_grad


def evaluate(c: dict[str, float], contact: str, steps: int, v, u: float):
    """loss, gradient and their rounding-error bounds for the precision with unit roundoff u."""
    (x, y, _, _), tape = rollout(c, contact, steps, float(v[0]), float(v[1]))
    dx, dy = x - c["target_x"], y - c["target_y"]
    loss = dx * dx + dy * dy
    grad = np.array(adjoint(c, tape, 2.0 * dx, 2.0 * dy))
    tol_loss, tol_grad = error_bounds(c, contact, tape, loss, dx, dy, u)
    return loss, grad, tol_loss, tol_grad


def gradient(c: dict[str, float], contact: str, steps: int, v) -> np.ndarray:
    (x, y, _, _), tape = rollout(c, contact, steps, float(v[0]), float(v[1]))
    return np.array(adjoint(c, tape, 2.0 * (x - c["target_x"]), 2.0 * (y - c["target_y"])))


def loss_of(c: dict[str, float], contact: str, steps: int, v) -> float:
    (x, y, _, _), _ = rollout(c, contact, steps, float(v[0]), float(v[1]))
    return (x - c["target_x"]) ** 2 + (y - c["target_y"]) ** 2


def loss_and_gradient(c: dict[str, float], contact: str, steps: int, v) -> tuple[float, np.ndarray]:
    """Loss and adjoint gradient from one float64 rollout (as ``evaluate``, without the bounds):
    what a host loop needs per evaluation."""
    (x, y, _, _), tape = rollout(c, contact, steps, float(v[0]), float(v[1]))
    dx, dy = x - c["target_x"], y - c["target_y"]
    return dx * dx + dy * dy, np.array(adjoint(c, tape, 2.0 * dx, 2.0 * dy))


def finite_difference_gradient(c: dict[str, float], contact: str, steps: int, v,
                               h: float = 1e-4) -> np.ndarray:
    """Float64 central differences with one Richardson step (error O(h^4)), so a stiff soft
    contact needs no tiny h (whose rounding error, eps/h, would dominate)."""
    v = np.asarray(v, np.float64)

    def central(step: float) -> np.ndarray:
        e = np.eye(2) * step
        return np.array([(loss_of(c, contact, steps, v + e[i]) - loss_of(c, contact, steps, v - e[i]))
                         / (2 * step) for i in range(2)])
    return (4.0 * central(h / 2) - central(h)) / 3.0


def hessian(c: dict[str, float], contact: str, steps: int, v, rel_step: float = 1e-6) -> np.ndarray:
    """Loss Hessian by central differences of the float64 adjoint gradient (symmetrised)."""
    h = rel_step * max(1.0, float(np.max(np.abs(v))))
    cols = [(gradient(c, contact, steps, v + h * e) - gradient(c, contact, steps, v - h * e)) / (2 * h)
            for e in np.eye(2)]
    m = np.array(cols).T
    return 0.5 * (m + m.T)


def closed_form(c: dict[str, float], steps: int, v: tuple[float, float]) -> tuple[float, np.ndarray]:
    """Exact loss and gradient of the discrete scheme without contact."""
    t = steps * c["dt"]
    x = v[0] * t
    y = v[1] * t + c["gravity"] * c["dt"] ** 2 * steps * (steps + 1) / 2.0
    dx, dy = x - c["target_x"], y - c["target_y"]
    return dx * dx + dy * dy, np.array([2.0 * dx * t, 2.0 * dy * t])


def _ratio(err, bound) -> float:
    """max(err/bound); an exact zero with a zero bound (e.g. a gradient component killed by a
    final hard-contact clamp) is 0, a nonzero error against a zero bound is inf."""
    err = np.atleast_1d(np.asarray(err, np.float64))
    bound = np.atleast_1d(np.asarray(bound, np.float64))
    r = np.divide(err, bound, out=np.zeros_like(err), where=bound > 0)
    r[(bound <= 0) & (err != 0)] = np.inf
    r[~np.isfinite(err)] = np.inf
    return float(np.max(r))


class Projectile(Scenario):
    name = "projectile"
    title = "Differentiable projectile"
    Params = ProjectileParams
    quick = {"iters": 20}
    outputs = ("loss", "grad", "loss_history", "v_final")
    has_gradient = True
    error_metric = "max(rel. error of loss, rel. error of |grad|) at v0 against the reference"
    sweep_labels = {"error_axis": "max rel. error of loss, grad vs converged ref. (log)"}

    def sweep_points(self, kind, device, quick):
        if kind != "error":
            return []
        ref = {"dt": min(SWEEP_DT[quick]) / REF_FACTOR}   # reference: the smallest dt / REF_FACTOR
        return [{"params": {"dt": dt, "steps": round(SWEEP_T / dt), "iters": 0,
                            "contact": SWEEP_CONTACT},
                 "knob": {"name": "dt", "value": dt}, "reference": ref} for dt in SWEEP_DT[quick]]

    def converged_loss_grad(self, params: dict, dt: float, steps: int) -> tuple[float, np.ndarray]:
        """Float64 loss and discrete-adjoint gradient at v0 (``loss_and_gradient``: ``rollout`` +
        ``adjoint``) after ``steps`` steps of ``dt``, the other parameters from ``params``."""
        p = self.params({**params, "dt": dt, "steps": steps})
        c = {k: float(getattr(p, k)) for k in CONSTANTS}
        return loss_and_gradient(c, p.contact, steps, (p.vx0, p.vy0))

    @staticmethod
    def loss_grad_error(loss, grad, rloss: float, rgrad: np.ndarray) -> dict[str, float]:
        """max(relative error of the loss, relative 2-norm error of the gradient) (``error``)."""
        el = abs(float(np.asarray(loss).reshape(())) - rloss) / abs(rloss)
        eg = float(np.linalg.norm(np.asarray(grad, np.float64).reshape(2) - rgrad) / np.linalg.norm(rgrad))
        return {"error": max(el, eg), "loss_rel": el, "grad_rel": eg}

    def converged_error(self, params, outputs, record, cache, reference=None):
        """Loss and gradient at v0 against a float64 rollout + adjoint at the sweep point's
        reference dt (default: the full sweep's smallest dt / REF_FACTOR)."""
        if outputs is None:
            return None
        ref, info = dt_reference(cache, self.name, params, reference, min(SWEEP_DT[False]) / REF_FACTOR,
                                 self.converged_loss_grad,
                                 lambda a, b: self.loss_grad_error(*a, *b)["error"], SWEEP_T)
        return {**self.loss_grad_error(outputs["loss"], outputs["grad"], *ref),
                "metric": self.error_metric, "reference": info}

    def stress_experiments(self):
        from . import projectile_stress
        return projectile_stress.EXPERIMENTS

    def inputs(self, params: ProjectileParams, precision: str) -> dict[str, np.ndarray]:
        dt = dtype_of(precision)
        out = {k: np.array(getattr(params, k), dtype=dt) for k in CONSTANTS}
        out["v0"] = np.array([params.vx0, params.vy0], dtype=dt)
        return out

    def output_shapes(self, params: ProjectileParams) -> dict[str, tuple[int, ...]]:
        return {"loss": (), "grad": (2,), "loss_history": (params.iters + 1,), "v_final": (2,)}

    def oracle(self, params: ProjectileParams, inputs) -> dict[str, np.ndarray]:
        # the port's rounding (u) plus the float64 oracle's own (u64): the bounds are linear in u
        u = UNIT_ROUNDOFF[precision_of(inputs["v0"])] + UNIT_ROUNDOFF["float64"]
        c = {k: float(inputs[k]) for k in CONSTANTS}
        lr = c["lr"]
        v = inputs["v0"].astype(np.float64)
        hist, grads, tol_l, tol_g, tol_h = [], [], [], [], []
        dv = 0.0           # bound on |v_k - v_ref_k| (2-norm)
        for k in range(params.iters + 1):
            loss, grad, tl, tg = evaluate(c, params.contact, params.steps, v, u)
            if params.contact == "none":       # the closed form is the oracle; the rollout gives bounds
                loss, grad = closed_form(c, params.steps, v)
            hess = hessian(c, params.contact, params.steps, v) if params.iters else np.zeros((2, 2))
            hist.append(loss); grads.append(grad); tol_l.append(tl); tol_g.append(tg)
            tol_h.append(tl + np.linalg.norm(grad) * dv + 0.5 * np.linalg.norm(hess, 2) * dv * dv)
            if k < params.iters:
                v_new = v - lr * grad
                gain = np.linalg.norm(np.eye(2) - lr * hess, 2)
                dv = gain * dv + lr * np.linalg.norm(tg) + u * (np.linalg.norm(v_new) + lr * np.linalg.norm(grad))
                v = v_new
        fd = finite_difference_gradient(c, params.contact, params.steps, inputs["v0"])
        return {"loss": np.float64(hist[0]), "grad": grads[0], "grad_fd": fd, "loss_history": np.array(hist),
                "v_final": v, "grad_history": np.array(grads), "tol_loss": np.array(tol_l),
                "tol_grad": np.array(tol_g), "tol_history": np.array(tol_h), "gradient_reference":
                np.array("closed-form" if params.contact == "none" else "adjoint64")}

    def check(self, params, inputs, outputs, reference, precision) -> Check:
        """Loss, gradient and history within their derived bounds.

        History: an error dv_k in v_k evolves through the descent map v -> v - lr*grad(v), whose
        Jacobian is I - lr*H_k (H_k the loss Hessian at v_k, from central differences of the
        float64 adjoint), so dv_{k+1} <= |I - lr H_k|_2 dv_k + lr |tol_grad_k| + u(|v_{k+1}| + lr|grad_k|)
        and |h_k - h_ref_k| <= tol_loss_k + |grad_k| dv_k + |H_k| dv_k^2 / 2. Where descent is
        unstable (|I - lr H| > 1, e.g. the seed's lr = 0.08) the bound grows with the amplification,
        as the error itself does. The reported error is the worst ratio error/bound over loss,
        gradient and history (ok when <= 1).
        """
        loss = float(np.asarray(outputs["loss"]).reshape(()))
        grad = np.asarray(outputs["grad"], np.float64).reshape(2)
        hist = np.asarray(outputs["loss_history"], np.float64).reshape(-1)
        e_loss = abs(loss - float(reference["loss"]))
        e_grad_vec = np.abs(grad - reference["grad"])
        e_grad = float(np.max(e_grad_vec))
        tol_loss = float(reference["tol_loss"][0]); tol_grad_vec = reference["tol_grad"][0]
        ref_hist = reference["loss_history"]
        if hist.shape != ref_hist.shape:
            return Check(math.inf, 1.0, False, {"reason": f"loss_history shape {hist.shape} != {ref_hist.shape}"})
        tol_hist = reference["tol_history"]
        e_hist = np.abs(hist - ref_hist)
        ratios = [_ratio(e_loss, tol_loss), _ratio(e_grad_vec, tol_grad_vec), _ratio(e_hist, tol_hist)]
        finite = all(math.isfinite(r) for r in ratios) and np.all(np.isfinite(hist))
        worst = max(ratios) if finite else math.inf
        rel_grad = e_grad / max(float(np.max(np.abs(reference["grad"]))), 1e-300)
        return Check(worst, 1.0, bool(finite and worst <= 1.0), {
            "metric": "max(error/bound) over loss, gradient, history",
            "loss_rel_error": e_loss / max(abs(float(reference["loss"])), 1e-300),
            "gradient_error": e_grad, "gradient_rel_error": rel_grad,
            "gradient_vs_fd64_rel": float(np.max(np.abs(grad - reference["grad_fd"]))
                                         / max(float(np.max(np.abs(reference["grad_fd"]))), 1e-300)), "gradient_tolerance": [float(t) for t in tol_grad_vec],
            "gradient_reference": str(reference["gradient_reference"]),
            "history_max_abs_error": float(np.max(e_hist)),
        })

    def distance(self, params, inputs, outputs, other) -> float:
        """Largest relative difference of loss and gradient at v0.

        The descent history is left out: where descent is unstable (soft contact, large lr) it
        amplifies one-ulp differences (an FMA, an operation order) by orders of magnitude, which
        says nothing about whether two ports compute the same thing; ``check`` bounds it instead.
        """
        def rel(a, b):
            a = np.asarray(a, np.float64).reshape(-1); b = np.asarray(b, np.float64).reshape(-1)
            if a.shape != b.shape:
                return math.inf
            return float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-300)))
        d = max(rel(outputs[k], other[k]) for k in ("loss", "grad"))
        return d if math.isfinite(d) else math.inf

    def figure(self, runs):
        """Left: loss against descent iteration for every run over the float64 oracle's descent.
        Right: each run's relative distance to the oracle's history (the oracle run from the same
        rounded inputs) and the derived bound for its precision."""
        import matplotlib.pyplot as plt
        rec0 = runs[0][0]
        p = self.params(rec0["params"])
        refs = {prec: self.oracle(p, self.inputs(p, prec)) for prec in {r["precision"] for r, _ in runs}}
        fig, (ax, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
        ref = refs.get("float64", next(iter(refs.values())))["loss_history"]
        ax.plot(np.arange(ref.size), np.maximum(ref, 1e-30), "k--", lw=2, alpha=0.5, label="float64 oracle")
        for prec, o in refs.items():
            scale = np.maximum(np.abs(o["loss_history"]), 1e-300)
            ax2.plot(np.arange(scale.size), np.maximum(o["tol_history"] / scale, 1e-18), "k",
                     ls=":" if prec == "float32" else "-.", lw=1.5,
                     label=f"derived bound, {prec}")
        for r, o in runs:
            h = np.asarray(o["loss_history"], np.float64)
            line, = ax.plot(np.arange(h.size), np.maximum(h, 1e-30), lw=1, label=run_label(r))
            ho = refs[r["precision"]]["loss_history"]
            if h.shape == ho.shape:
                with np.errstate(invalid="ignore", divide="ignore"):
                    rel = np.abs(h - ho) / np.maximum(np.abs(ho), 1e-300)
                ax2.plot(np.arange(h.size), np.maximum(rel, 1e-18), lw=1, color=line.get_color(),
                         label=run_label(r))
        ax.set_yscale("log"); ax.set_xlabel("gradient-descent iteration"); ax.set_ylabel("loss [m²]")
        ax.set_title(f"projectile: contact={p.contact}, lr={p.lr:g}, {p.steps} steps", fontsize=9)
        ax.legend(fontsize=6, ncol=2)
        ax2.set_yscale("log"); ax2.set_xlabel("gradient-descent iteration")
        ax2.set_ylabel("|loss - oracle| / oracle (0 drawn at 1e-18)")
        ax2.set_title("distance to the oracle's descent, same rounded inputs", fontsize=9)
        ax2.legend(fontsize=6, ncol=2)
        fig.tight_layout()
        return fig

    def work(self, params: ProjectileParams, precision: str) -> dict[str, float]:
        return {"items": float(params.steps) * (params.iters + 1)}

    def footprint(self, params: ProjectileParams, precision: str) -> float:
        # the per-step states of the port's tape and of the float64 oracle's rollout + adjoint;
        # measured on CPU (all four backends): at most 173 MiB at 200 000 steps (~900 B/step)
        # and 22 MiB at 10 000 (JAX's fixed part); bound ~1.6x that (docs/reliability.md)
        return 32.0 * 2**20 + params.steps * 1400.0 + params.iters * 64.0

    def floor(self, params: ProjectileParams, precision: str, hardware: dict) -> dict | None:
        """One trajectory is a serial chain: each step's forward pass needs vy <- vy + acc dt, then
        y <- y + vy dt (two dependent FMAs), and the reverse sweep two more, so an evaluation is at
        least 4 x steps dependent operations; at 4 cycles each (the FMA latency of recent NVIDIA
        GPUs) and the GPU's maximum SM clock, iters + 1 evaluations take at least
        16 x steps x (iters + 1) / clock. GPU only (the clock comes from NVML)."""
        clock = hardware.get("sm_clock_max_hz")
        if not clock:
            return None
        n = 16.0 * params.steps * (params.iters + 1)
        return {"kind": "serial latency", "seconds": n / clock,
                "derivation": f"4 dependent FMAs x 4 cycles x {params.steps} steps x {params.iters + 1} "
                              f"evaluations at {clock / 1e9:.3g} GHz"}
