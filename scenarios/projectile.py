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
from typing import Any, Literal

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
MAX_BATCH = 1 << 24
# Gradient-throughput sweep: B = 1 ... 2^20 on CUDA (to 2^16 on a CPU), hard contact (the seeds'
# bounce), 21 evaluations per run; 64 trajectories of each batch checked against the oracle.
BATCH_SWEEP = {("cuda", False): tuple(4**k for k in range(11)), ("cpu", False): tuple(16**k for k in range(5)),
               ("cuda", True): (1, 64, 4096), ("cpu", True): (1, 16, 256)}
BATCH_SWEEP_PARAMS = {"contact": "hard", "iters": 20}
# Horizon sweep (one loss + gradient per trajectory at a fixed batch): AD memory per trajectory-
# step and the share of gradients that agree with finite differences, per contact model. Soft
# contact stops at 2000 steps: its oracle bound costs O(steps^2) per checked trajectory.
HORIZON_BATCH = {("cuda", False): 4096, ("cpu", False): 256, ("cuda", True): 256, ("cpu", True): 16}
HORIZON_STEPS = {False: {"none": (180, 1000, 3000, 10000), "hard": (180, 1000, 3000, 10000),
                         "soft": (180, 600, 2000)},
                 True: {"none": (180, 600), "hard": (180, 600), "soft": (180, 300)}}
# Useful floating-point operations per trajectory-step, forward + reverse: 'none' 3 updates of 2
# FLOPs forward and 2 of 2 in reverse; 'hard' adds 3 multiplies on a bounce (counted always);
# 'soft' adds the softplus (2 transcendental + 6 FLOPs) and its derivative (~8) in each direction.
FLOPS_PER_STEP = {"none": 10.0, "hard": 13.0, "soft": 30.0}
# Batch (B > 1) draws, uniform on these ranges; row 0 is always the seed case (vx0, vy0, target_x,
# target_y), so batch row 0 reproduces batch = 1. Apex heights vy0^2/(2|g|) are 0.2-5.1 m and
# flight times 2 vy0/|g| at most 2.04 s, under the default horizon of 4.5 s: every trajectory
# reaches the ground, so 'hard' and 'soft' contact happens in all of them (and several times in
# most), and the targets lie on or just above the ground, within reach of a descent on v0.
BATCH_DRAW = {"vx0": (0.5, 3.5), "vy0": (2.0, 10.0), "target_x": (1.0, 7.0), "target_y": (0.0, 1.5)}
FD_AGREEMENT = 1e-2     # relative distance at which a gradient agrees with finite differences
LINEAR_MARGIN = 0.1    # how far the descent's error gain may be uncertain for the history bound
BATCH_CHECKED = 64     # trajectories of a batch checked against the oracle unless told otherwise


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
    batch: int = 1
    seed: int = 0

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
        require(1 <= self.batch <= MAX_BATCH, f"batch must be an integer in [1, {MAX_BATCH}], got {self.batch}")
        require(0 <= self.seed < 2**63, f"seed must be an integer in [0, 2^63), got {self.seed}")


# The float64 functions below take one trajectory (vx, vy scalars, v of shape (2,)) or a batch
# (arrays of shape (B,), v of shape (B, 2)); the constants in ``c`` are scalars except the targets,
# which may be arrays of shape (B,). One code path, vectorised over the batch axis.

def _sigmoid_of(z: np.ndarray, e: np.ndarray) -> np.ndarray:
    """sigmoid(z) from e = exp(-|z|), without overflow on either side."""
    return np.where(z >= 0, 1.0 / (1.0 + e), e / (1.0 + e))


def rollout(c: dict[str, float], contact: str, steps: int, vx, vy):
    """Float64 forward pass. Returns the final state and, per step, what the analyses need:
    (state before, state after, acc, d acc/dy, d^2 acc/dy^2, rounding magnitude of acc, hit);
    the soft terms are None without soft contact, hit is None without hard contact."""
    dt, g = c["dt"], c["gravity"]
    eps, k = c["softness"], c["stiffness"]
    vx, vy = (np.array(a, np.float64) for a in np.broadcast_arrays(np.asarray(vx, np.float64),
                                                                   np.asarray(vy, np.float64)))
    x = np.zeros_like(vx)
    y = np.zeros_like(vx)
    tape = []
    for _ in range(steps):
        state = (x, y, vx, vy)
        acc, dacc, d2acc, racc = g, None, None, None      # None: the term is absent (0)
        if contact == "soft":
            z = -y / eps
            e = np.exp(-np.abs(z))
            lg = np.log(1.0 + e)
            sp = np.maximum(z, 0.0) + lg
            acc = g + k * eps * sp
            sig = _sigmoid_of(z, e)
            dacc = -k * sig                           # d acc / d y
            d2acc = k * sig * (1.0 - sig) / eps       # d^2 acc / d y^2
            # rounding of acc, operation by operation (z, exp, log1p, sum, eps*, k*, g+)
            racc = k * eps * (np.abs(z) + 3.0 * e + 2.0 * lg + sp) + 2.0 * k * eps * sp + np.abs(acc)
        vy = vy + acc * dt
        x = x + vx * dt
        y = y + vy * dt
        hit = None                                        # None: no contact rule
        if contact == "hard":
            hit = y < 0.0
            y = np.where(hit, 0.0, y)
            vy = np.where(hit, -c["bounce"] * vy, vy)
            vx = np.where(hit, c["damping"] * vx, vx)
        tape.append((state, (x, y, vx, vy), acc, dacc, d2acc, racc, hit))
    return (x, y, vx, vy), tape


def adjoint(c: dict[str, float], tape, ax, ay, record: bool = False):
    """Reverse sweep of ``rollout``: given d/d(x_N, y_N), return d/d(vx0, vy0).

    With ``record`` it also returns, per step (forward order), the adjoint of vy after the
    velocity update and the magnitudes the sweep rounds, shape (4, ...) (for the error analysis).
    """
    dt = c["dt"]
    ax, ay = (np.array(a, np.float64) for a in np.broadcast_arrays(ax, ay))
    avx = np.zeros_like(ax)
    avy = np.zeros_like(ax)
    trace = []
    for _, _, _, dacc, _, _, hit in reversed(tape):
        r = np.zeros((4,) + ax.shape) if record else None
        if hit is not None:
            ay = np.where(hit, 0.0, ay)
            avy = np.where(hit, -c["bounce"] * avy, avy)
            avx = np.where(hit, c["damping"] * avx, avx)
            if record:
                r[2] += np.where(hit, np.abs(avx), 0.0); r[3] += np.where(hit, np.abs(avy), 0.0)
        avy = avy + ay * dt          # y1 = y + vy1*dt
        avx = avx + ax * dt          # x1 = x + vx*dt
        if record:
            r[2] += np.abs(ax * dt) + np.abs(avx); r[3] += np.abs(ay * dt) + np.abs(avy)
        if dacc is not None:
            live = dacc != 0.0
            ay = np.where(live, ay + avy * dacc * dt, ay)    # vy1 = vy + acc(y)*dt
            if record:
                r[1] += np.where(live, 2.0 * np.abs(avy * dacc * dt) + np.abs(ay), 0.0)
        if record:
            trace.append((avy, r))
    if record:
        return (avx, avy), trace[::-1]
    return avx, avy


def step_jacobian(c: dict[str, float], dacc, hit) -> np.ndarray:
    """d(x1, y1, vx1, vy1)/d(x, y, vx, vy) of one step, shape dacc.shape + (4, 4)."""
    dt = c["dt"]
    dacc = np.asarray(dacc, np.float64)
    a = np.zeros(dacc.shape + (4, 4))
    a[..., 0, 0] = 1.0; a[..., 0, 2] = dt
    a[..., 1, 3] = dt
    a[..., 1, 1] = 1.0 + dt * dt * dacc
    a[..., 2, 2] = 1.0
    a[..., 3, 1] = dt * dacc; a[..., 3, 3] = 1.0
    hit = np.broadcast_to(hit, dacc.shape)
    if np.any(hit):
        a[hit, 1, :] = 0.0
        a[hit, 2, :] *= c["damping"]
        a[hit, 3, :] *= -c["bounce"]
    return a


def _abs_t_dot(m: np.ndarray, v: np.ndarray) -> np.ndarray:
    """|m|^T v for a batch of matrices (..., i, j) and vectors (..., i)."""
    return np.einsum("...ij,...i->...j", np.abs(m), v)


def error_bounds(c: dict[str, float], contact: str, tape, loss, dx, dy, u: float):
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
    Shapes: loss, dx, dy of the batch shape S (() for one trajectory); returns (S, S + (2,)).
    Cost: O(steps) per trajectory, O(steps^2) for soft contact's term (c).
    """
    dt = c["dt"]
    n = len(tape)
    shape = np.shape(loss)
    zero = np.zeros((n,) + shape)
    def stack(j: int) -> np.ndarray:        # tape field j of every step, (n, S); absent: 0
        return np.array([np.broadcast_to(t[j], shape) for t in tape]) if tape[0][j] is not None else zero
    x0, y0, vx0, vy0 = np.moveaxis(np.array([t[0] for t in tape]), 1, 0)
    x1, y1, vx1, vy1 = np.moveaxis(np.array([t[1] for t in tape]), 1, 0)
    acc, dacc, racc = stack(2), stack(3), stack(5)
    hit = stack(6).astype(bool)
    # local rounding of every step at once, (n, S, 4)
    vy_mid = vy0 + acc * dt
    r_vy = dt * u * racc + u * np.abs(acc * dt) + u * np.abs(vy_mid)
    local = np.stack([u * (np.abs(vx0 * dt) + np.abs(x1)),
                      u * (np.abs(vy_mid * dt) + np.abs(y0 + vy_mid * dt)) + dt * r_vy,
                      zero, r_vy], axis=-1)
    local[..., 1] = np.where(hit, 0.0, local[..., 1])
    local[..., 3] = np.where(hit, c["bounce"] * local[..., 3] + u * np.abs(vy1), local[..., 3])
    local[..., 2] = np.where(hit, u * np.abs(vx1), local[..., 2])
    mats = step_jacobian(c, dacc, hit)
    # Phi(N, k) for every k by a backward product; forward tangents Phi(k, 0) by a forward one.
    back = np.broadcast_to(np.eye(4), shape + (4, 4))
    err_final = np.zeros(shape + (4,))
    for i in range(n - 1, -1, -1):
        err_final += np.einsum("...ij,...j->...i", np.abs(back), local[i])
        back = back @ mats[i]
    jac_v = back[..., :2, 2:4]                  # d(x_N, y_N)/d(vx0, vy0)
    ex, ey = err_final[..., 0], err_final[..., 1]
    adx, ady = np.abs(dx), np.abs(dy)
    tol_loss = 2 * adx * (ex + u * adx) + 2 * ady * (ey + u * ady) + 3 * u * np.asarray(loss)
    seeds = 2.0 * np.stack([ex + u * adx, ey + u * ady], axis=-1)
    tol_grad = _abs_t_dot(jac_v, seeds)
    _, trace = adjoint(c, tape, 2.0 * dx, 2.0 * dy, record=True)
    fwd = np.broadcast_to(np.eye(4), shape + (4, 4))
    # Phi(i, j) for j < i (soft only), grown in place: phis[:i] = A_{i-1} phis[:i], phis[i-1] = I
    phis = np.zeros((n,) + shape + (4, 4)) if contact == "soft" else None
    d2acc = stack(4)
    for i in range(n):
        avy, rr = trace[i]
        # (b): error injected into the adjoint at step i reaches the gradient via Phi(i, 0)^T
        tol_grad = tol_grad + _abs_t_dot(fwd[..., 2:4], u * np.moveaxis(rr, 0, -1))
        if phis is not None:
            ey_k = np.einsum("k...j,k...j->...", np.abs(phis[:i, ..., 1, :]), local[:i]) if i else 0.0
            coeff_err = np.abs(d2acc[i]) * ey_k + 4.0 * u * np.abs(dacc[i])
            tol_grad = tol_grad + (np.abs(avy) * dt * coeff_err)[..., None] * np.abs(fwd[..., 1, 2:4])
            if i:
                phis[:i] = mats[i] @ phis[:i]
            phis[i] = np.eye(4)
        fwd = mats[i] @ fwd
    return tol_loss, tol_grad


def _split(v) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(v, np.float64)
    return v[..., 0], v[..., 1]


def _targets(c: dict[str, float]):
    return c["target_x"], c["target_y"]


def loss_and_gradient(c: dict[str, float], contact: str, steps: int, v):
    """Loss and adjoint gradient from one float64 rollout (as ``evaluate``, without the bounds):
    what a host loop needs per evaluation. v: (2,) or (B, 2); returns loss () or (B,), grad v's
    shape."""
    (x, y, _, _), tape = rollout(c, contact, steps, *_split(v))
    tx, ty = _targets(c)
    dx, dy = x - tx, y - ty
    return dx * dx + dy * dy, np.stack(adjoint(c, tape, 2.0 * dx, 2.0 * dy), axis=-1)


def evaluate(c: dict[str, float], contact: str, steps: int, v, u: float):
    """loss, gradient and their rounding-error bounds for the precision with unit roundoff u."""
    (x, y, _, _), tape = rollout(c, contact, steps, *_split(v))
    tx, ty = _targets(c)
    dx, dy = x - tx, y - ty
    loss = dx * dx + dy * dy
    grad = np.stack(adjoint(c, tape, 2.0 * dx, 2.0 * dy), axis=-1)
    tol_loss, tol_grad = error_bounds(c, contact, tape, loss, dx, dy, u)
    return loss, grad, tol_loss, tol_grad


def gradient(c: dict[str, float], contact: str, steps: int, v) -> np.ndarray:
    return loss_and_gradient(c, contact, steps, v)[1]


def loss_of(c: dict[str, float], contact: str, steps: int, v):
    (x, y, _, _), _ = rollout(c, contact, steps, *_split(v))
    tx, ty = _targets(c)
    return (x - tx) ** 2 + (y - ty) ** 2


def finite_difference_gradient(c: dict[str, float], contact: str, steps: int, v,
                               h: float = 1e-4, with_error: bool = False):
    """Float64 central differences with one Richardson step (error O(h^4)), so a stiff soft
    contact needs no tiny h (whose rounding error, eps/h, would dominate). With ``with_error`` also
    an estimate of its own error: the Richardson correction |rich - central(h/2)| plus the loss
    rounding amplified by the differencing, 8 u64 |loss| / h."""
    v = np.asarray(v, np.float64)

    # every displaced point in one batch (leading axis): step (h, h/2) x direction x sign, and v
    pts = np.stack([v + e * step * sign for step in (h, h / 2) for e in np.eye(2) for sign in (1.0, -1.0)] + [v])
    f = loss_of(c, contact, steps, pts)
    full, half = ([(f[j] - f[j + 1]) / (2 * step), (f[j + 2] - f[j + 3]) / (2 * step)]
                  for j, step in ((0, h), (4, h / 2)))
    full, half = np.stack(full, axis=-1), np.stack(half, axis=-1)
    rich = (4.0 * half - full) / 3.0
    if not with_error:
        return rich
    loss = np.abs(f[8])[..., None]
    return rich, np.abs(rich - half) + 8.0 * UNIT_ROUNDOFF["float64"] * loss / h


def hessian(c: dict[str, float], contact: str, steps: int, v, rel_step: float = 1e-6) -> np.ndarray:
    """Loss Hessian by central differences of the float64 adjoint gradient (symmetrised);
    (2, 2) or (B, 2, 2)."""
    v = np.asarray(v, np.float64)
    h = (rel_step * np.maximum(1.0, np.max(np.abs(v), axis=-1)))[..., None]
    # the four displaced points as one batch (leading axis), targets broadcast alongside
    pts = np.stack([v + h * e * sign for e in np.eye(2) for sign in (1.0, -1.0)])
    g = gradient(c, contact, steps, pts)
    m = np.stack([(g[0] - g[1]) / (2 * h), (g[2] - g[3]) / (2 * h)], axis=-1)
    return 0.5 * (m + np.swapaxes(m, -1, -2))


def closed_form(c: dict[str, float], steps: int, v):
    """Exact loss and gradient of the discrete scheme without contact."""
    t = steps * c["dt"]
    vx, vy = _split(v)
    x = vx * t
    y = vy * t + c["gravity"] * c["dt"] ** 2 * steps * (steps + 1) / 2.0
    tx, ty = _targets(c)
    dx, dy = x - tx, y - ty
    return dx * dx + dy * dy, np.stack([2.0 * dx * t, 2.0 * dy * t], axis=-1)


def spectral_norm_sym(m: np.ndarray) -> np.ndarray:
    """2-norm of symmetric matrices (..., 2, 2): the largest |eigenvalue|."""
    return np.max(np.abs(np.linalg.eigvalsh(m)), axis=-1)


def _ratios(err, bound) -> np.ndarray:
    """err/bound elementwise; an exact zero with a zero bound (e.g. a gradient component killed by
    a final hard-contact clamp) is 0, a nonzero error against a zero bound is inf."""
    err, bound = np.broadcast_arrays(np.asarray(err, np.float64), np.asarray(bound, np.float64))
    r = np.divide(err, bound, out=np.zeros(err.shape), where=bound > 0)
    r[(bound <= 0) & (err != 0)] = np.inf
    r[~np.isfinite(err)] = np.inf
    return r


class Projectile(Scenario):
    name = "projectile"
    title = "Differentiable projectile"
    Params = ProjectileParams
    quick = {"iters": 20}
    outputs = ("loss", "grad", "loss_history", "v_final")
    has_gradient = True
    error_metric = "max(rel. error of loss, rel. error of |grad|) at v0 against the reference"
    sweep_labels = {"error_axis": "max rel. error of loss, grad vs converged ref. (log)",
                    "items": "trajectories", "item_rate": "trajectory-gradients", "rate_work": "gradients",
                    "horizon_items": "batch", "horizon_memory": '{"contact": "hard"}'}

    def sweep_points(self, kind, device, quick):
        if kind == "scaling":     # gradient throughput against the batch
            return [{"params": {"batch": b, **BATCH_SWEEP_PARAMS}, "knob": {"name": "batch", "value": b},
                     "save_outputs": False} for b in BATCH_SWEEP[(device, quick)]]
        if kind == "horizon":     # AD memory and gradient quality against the horizon
            batch = HORIZON_BATCH[(device, quick)]
            return [{"params": {"steps": n, "contact": c, "iters": 0, "batch": batch},
                     "knob": {"name": "steps", "value": n}, "save_outputs": False}
                    for c, ns in HORIZON_STEPS[quick].items() for n in ns]
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
        """Shared constants as scalars; ``v0`` and ``target`` per trajectory: shape (2,) for
        batch = 1 (the seed case), (B, 2) for B > 1 (row 0 the seed case, the rest drawn from
        ``BATCH_DRAW`` with ``seed``). Kernels read the targets from ``target``."""
        dt = dtype_of(precision)
        out = {k: np.array(getattr(params, k), dtype=dt) for k in CONSTANTS}
        v0 = np.array([params.vx0, params.vy0], dtype=np.float64)
        target = np.array([params.target_x, params.target_y], dtype=np.float64)
        if params.batch > 1:
            rng = np.random.default_rng(params.seed)
            draw = {k: rng.uniform(lo, hi, params.batch - 1) for k, (lo, hi) in BATCH_DRAW.items()}
            v0 = np.concatenate([v0[None], np.stack([draw["vx0"], draw["vy0"]], axis=-1)])
            target = np.concatenate([target[None], np.stack([draw["target_x"], draw["target_y"]], axis=-1)])
        out["v0"] = v0.astype(dt)
        out["target"] = target.astype(dt)
        return out

    def output_shapes(self, params: ProjectileParams) -> dict[str, tuple[int, ...]]:
        b = () if params.batch == 1 else (params.batch,)
        return {"loss": b, "grad": b + (2,), "loss_history": (params.iters + 1,) + b, "v_final": b + (2,)}

    def state_bytes_per_step(self, precision: str) -> float:
        """x, y, vx, vy: what a tape that stores every step must keep at the least."""
        return 4.0 * np.dtype(dtype_of(precision)).itemsize

    def size_text(self, params: ProjectileParams) -> str:
        return f"steps={params.steps}" + (f", batch={params.batch}" if params.batch > 1 else "")

    def sample(self, params: ProjectileParams, inputs: dict[str, np.ndarray],
               outputs: dict[str, np.ndarray], k: int):
        """k evenly spaced trajectories of a batch (BATCH_CHECKED when k is 0): the oracle's
        cost grows with steps (steps^2 for soft contact) per trajectory and evaluation."""
        k = k or BATCH_CHECKED
        if params.batch <= k:
            return None
        idx = np.unique(np.linspace(0, params.batch - 1, k).round().astype(np.int64))
        ins = {n: (a[idx] if n in ("v0", "target") else a) for n, a in inputs.items()}
        outs = {n: (np.asarray(a)[:, idx] if n == "loss_history" else np.asarray(a)[idx])
                for n, a in outputs.items()}
        return ins, outs, int(idx.size), params.batch, "trajectories"

    @staticmethod
    def constants(inputs: dict[str, np.ndarray]) -> dict[str, Any]:
        """Float64 constants of the (rounded) inputs; the targets per trajectory."""
        c: dict[str, Any] = {k: float(inputs[k]) for k in CONSTANTS}
        target = np.asarray(inputs["target"], np.float64)
        c["target_x"], c["target_y"] = target[..., 0], target[..., 1]
        return c

    def oracle(self, params: ProjectileParams, inputs) -> dict[str, np.ndarray]:
        """Vectorised over the trajectories of ``inputs`` (one, or a batch)."""
        # the port's rounding (u) plus the float64 oracle's own (u64): the bounds are linear in u
        u = UNIT_ROUNDOFF[precision_of(inputs["v0"])] + UNIT_ROUNDOFF["float64"]
        c = self.constants(inputs)
        lr = c["lr"]
        v = inputs["v0"].astype(np.float64)
        hist, grads, tol_l, tol_g, tol_h, hs, dvs, vs = [], [], [], [], [], [], [], []
        dv = np.zeros(v.shape[:-1])     # bound on |v_k - v_ref_k| (2-norm), per trajectory
        for k in range(params.iters + 1):   # (an unstable descent's bound overflows to inf: unbounded)
            loss, grad, tl, tg = evaluate(c, params.contact, params.steps, v, u)
            if params.contact == "none":       # the closed form is the oracle; the rollout gives bounds
                loss, grad = closed_form(c, params.steps, v)
            hess = hessian(c, params.contact, params.steps, v) if params.iters else np.zeros(v.shape + (2,))
            gnorm = np.linalg.norm(grad, axis=-1)
            with np.errstate(over="ignore", invalid="ignore"):
                tol_h.append(tl + gnorm * dv + 0.5 * spectral_norm_sym(hess) * dv * dv)
            hist.append(loss); grads.append(grad); tol_l.append(tl); tol_g.append(tg)
            hs.append(hess); dvs.append(dv); vs.append(v)
            if k < params.iters:
                v_new = v - lr * grad
                gain = spectral_norm_sym(np.eye(2) - lr * hess)
                with np.errstate(over="ignore", invalid="ignore"):
                    dv = gain * dv + lr * np.linalg.norm(tg, axis=-1) + u * (np.linalg.norm(v_new, axis=-1) + lr * gnorm)
                v = v_new
        fd, fd_err = finite_difference_gradient(c, params.contact, params.steps, inputs["v0"], with_error=True)
        # Where the first-order history bound holds: it multiplies the error bound by the gain
        # |I - lr H_k|, so it needs H nearly constant over the error ball: the gain's uncertainty
        # lr * L_k * dv_k at most LINEAR_MARGIN of max(gain, 1), with L_k the Hessian's rate of
        # change along the oracle's path (from consecutive iterates). Past the first iteration
        # that breaks it, a trajectory's history is outside the analysis (a rounding difference
        # may send the descent to another attractor) and is not checked.
        hs, dvs, vs = np.array(hs), np.array(dvs), np.array(vs)
        if params.iters:
            dh = spectral_norm_sym(hs[1:] - hs[:-1])
            step = np.linalg.norm(vs[1:] - vs[:-1], axis=-1)
            rate = np.divide(dh, step, out=np.full(dh.shape, np.inf), where=step > 0)
            rate = np.where((dh == 0), 0.0, rate)
            rate = np.concatenate([rate, rate[-1:]])
            with np.errstate(invalid="ignore"):
                gain = np.maximum(spectral_norm_sym(np.eye(2) - lr * hs), 1.0)
                linear = np.logical_and.accumulate(lr * rate * dvs <= LINEAR_MARGIN * gain, axis=0)
        else:
            linear = np.ones(dvs.shape, bool)
        return {"loss": np.asarray(hist[0], np.float64), "grad": grads[0], "grad_fd": fd, "grad_fd_error": fd_err,
                "loss_history": np.array(hist), "v_final": v, "grad_history": np.array(grads),
                "tol_loss": np.array(tol_l), "tol_grad": np.array(tol_g), "tol_history": np.array(tol_h),
                "history_checked": linear,
                "gradient_reference": np.array("closed-form" if params.contact == "none" else "adjoint64")}

    def check(self, params, inputs, outputs, reference, precision) -> Check:
        """Loss, gradient and history within their derived bounds, per trajectory.

        History: an error dv_k in v_k evolves through the descent map v -> v - lr*grad(v), whose
        Jacobian is I - lr*H_k (H_k the loss Hessian at v_k, from central differences of the
        float64 adjoint), so dv_{k+1} <= |I - lr H_k|_2 dv_k + lr |tol_grad_k| + u(|v_{k+1}| + lr|grad_k|)
        and |h_k - h_ref_k| <= tol_loss_k + |grad_k| dv_k + |H_k| dv_k^2 / 2. Where descent is
        unstable (|I - lr H| > 1, e.g. the seed's lr = 0.08) the bound grows with the amplification,
        as the error itself does. The reported error is the worst ratio error/bound over loss,
        gradient and history and over the checked trajectories (ok when <= 1).

        Gradient quality (``gradient_fd_agreement``): the share of checked trajectories whose
        gradient agrees with float64 central differences (Richardson, h = 1e-4) to
        FD_AGREEMENT relative (2-norm): whether the gradient is the slope the loss shows at that
        scale, the same question in either precision. The discrete adjoint is the exact
        derivative of the program; where the loss is not smooth in v0 at that scale (a hard bounce
        that comes or goes, a stiff or chaotic rollout) it is not, and long horizons make that
        common. ``gradient_fd_resolved``: the share whose differences are themselves resolved
        (their error estimate below FD_AGREEMENT / 10 of their size).
        """
        shape = np.shape(reference["loss"])
        try:
            loss = np.asarray(outputs["loss"], np.float64).reshape(shape)
            grad = np.asarray(outputs["grad"], np.float64).reshape(shape + (2,))
        except ValueError:
            return Check(math.inf, 1.0, False, {"reason": "loss/grad shapes do not match the inputs"})
        hist = np.asarray(outputs["loss_history"], np.float64)
        ref_hist = reference["loss_history"]
        if hist.size != ref_hist.size:
            return Check(math.inf, 1.0, False, {"reason": f"loss_history shape {hist.shape} != {ref_hist.shape}"})
        hist = hist.reshape(ref_hist.shape)
        e_loss = np.abs(loss - reference["loss"])
        e_grad_vec = np.abs(grad - reference["grad"])
        e_hist = np.abs(hist - ref_hist)
        tol_grad_vec = reference["tol_grad"][0]
        per = np.maximum.reduce([_ratios(e_loss, reference["tol_loss"][0]),
                                 np.max(_ratios(e_grad_vec, tol_grad_vec), axis=-1),
                                 np.max(np.where(reference["history_checked"],
                                                 _ratios(e_hist, reference["tol_history"]), 0.0), axis=0)])
        per = np.where(np.all(np.isfinite(hist), axis=0), per, np.inf)
        worst = float(np.max(per))
        finite = math.isfinite(worst)
        at = int(np.argmax(per)) if np.ndim(per) else 0
        g_ref, fd = reference["grad"], reference["grad_fd"]
        fd_size = np.maximum(np.linalg.norm(fd, axis=-1), 1e-300)
        agree = np.linalg.norm(grad - fd, axis=-1) <= FD_AGREEMENT * fd_size
        resolved = np.linalg.norm(reference["grad_fd_error"], axis=-1) <= 0.1 * FD_AGREEMENT * fd_size
        pick = (lambda a: a) if not shape else (lambda a: np.asarray(a)[at])   # noqa: E731
        details = {
            "metric": "max(error/bound) over loss, gradient, history" + (" and trajectories" if shape else ""),
            "loss_rel_error": float(np.max(e_loss / np.maximum(np.abs(reference["loss"]), 1e-300))),
            "gradient_error": float(np.max(e_grad_vec)),
            "gradient_rel_error": float(np.max(np.max(e_grad_vec, axis=-1)
                                               / np.maximum(np.max(np.abs(g_ref), axis=-1), 1e-300))),
            "gradient_vs_fd64_rel": float(np.max(np.max(np.abs(grad - fd), axis=-1)
                                                 / np.maximum(np.max(np.abs(fd), axis=-1), 1e-300))),
            "gradient_tolerance": [float(t) for t in pick(tol_grad_vec)],
            "gradient_value": [float(g) for g in pick(grad)],
            "gradient_reference_value": [float(g) for g in pick(g_ref)],
            "gradient_fd_agreement": float(np.mean(agree)),
            "gradient_fd_resolved": float(np.mean(resolved)),
            "gradient_reference": str(reference["gradient_reference"]),
            "history_max_abs_error": float(np.max(e_hist)),
            "history_checked_share": float(np.mean(reference["history_checked"])),
        }
        if shape:
            details["worst_trajectory"] = at
        return Check(worst, 1.0, bool(finite and worst <= 1.0), details)

    def distance(self, params, inputs, outputs, other) -> float:
        """Largest relative difference of the loss and of the gradient at v0, per trajectory: the
        gradient's against that trajectory's gradient size (its largest component), since a
        near-zero component would magnify one ulp of libm difference in exp.

        The descent history is left out: where descent is unstable (soft contact, large lr) it
        amplifies one-ulp differences (an FMA, an operation order) by orders of magnitude, which
        says nothing about whether two ports compute the same thing; ``check`` bounds it instead.
        """
        a_l, b_l = (np.asarray(o["loss"], np.float64).reshape(-1) for o in (outputs, other))
        a_g, b_g = (np.asarray(o["grad"], np.float64).reshape(-1, 2) for o in (outputs, other))
        if a_l.shape != b_l.shape or a_g.shape != b_g.shape:
            return math.inf
        d_loss = np.abs(a_l - b_l) / np.maximum(np.abs(b_l), 1e-300)
        d_grad = np.max(np.abs(a_g - b_g), axis=-1) / np.maximum(np.max(np.abs(b_g), axis=-1), 1e-300)
        d = float(max(np.max(d_loss), np.max(d_grad)))
        return d if math.isfinite(d) else math.inf

    def figure(self, runs):
        """Left: loss against descent iteration for every run over the float64 oracle's descent.
        Right: each run's relative distance to the oracle's history (the oracle run from the same
        rounded inputs) and the derived bound for its precision."""
        import matplotlib.pyplot as plt
        rec0 = runs[0][0]
        p = self.params(rec0["params"])
        if p.batch > 1:        # draw row 0 of every batch: the seed case
            p = dataclasses.replace(p, batch=1)
            runs = [(r, {k: np.asarray(v)[:, 0] if k == "loss_history" else np.asarray(v)[0]
                         for k, v in o.items()}) for r, o in runs]
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
        """items: trajectory-steps; gradients: trajectory-gradients (B x evaluations), whose rate is
        the gradient throughput; flops: FLOPS_PER_STEP per trajectory-step, forward and reverse."""
        evals = float(params.batch) * (params.iters + 1)
        return {"items": evals * params.steps, "gradients": evals,
                "flops": evals * params.steps * FLOPS_PER_STEP[params.contact]}

    def footprint(self, params: ProjectileParams, precision: str, device: str = "cpu") -> float:
        # per checked trajectory, the per-step states of the float64 oracle's rollout + adjoint +
        # bounds (soft: also its steps x 4 x 4 transition stack); per trajectory, the inputs and
        # outputs and, on the CPU, the port's tape (at most ~900 B/step measured for a single
        # trajectory; on a GPU the tape is device memory); plus a fixed part (JAX's ~22 MiB)
        checked = min(params.batch, BATCH_CHECKED)
        oracle = params.steps * (1400.0 + (128.0 * params.steps if params.contact == "soft" else 0.0))
        tape = params.steps * 900.0 if device == "cpu" else 0.0
        per_traj = tape + (params.iters + 8) * 8.0 * 3
        return 32.0 * 2**20 + checked * oracle + params.batch * per_traj + params.iters * 64.0

    def floor(self, params: ProjectileParams, precision: str, hardware: dict) -> dict | None:
        """A trajectory is a serial chain: each step's forward pass needs vy <- vy + acc dt, then
        y <- y + vy dt (two dependent FMAs), and the reverse sweep two more, so an evaluation is at
        least 4 x steps dependent operations; at 4 cycles each (the FMA latency of recent NVIDIA
        GPUs) and the GPU's maximum SM clock, iters + 1 evaluations take at least
        16 x steps x (iters + 1) / clock, however many trajectories run side by side. A batch
        also needs its FLOPs (``work``) at the stated peak: the floor is the larger. GPU only."""
        clock = hardware.get("sm_clock_max_hz")
        if not clock:
            return None
        n = 16.0 * params.steps * (params.iters + 1)
        serial = {"kind": "serial latency", "seconds": n / clock,
                  "derivation": f"4 dependent FMAs x 4 cycles x {params.steps} steps x {params.iters + 1} "
                                f"evaluations at {clock / 1e9:.3g} GHz"}
        flops = super().floor(params, precision, hardware) if params.batch > 1 else None
        return max((f for f in (serial, flops) if f), key=lambda f: f["seconds"])
