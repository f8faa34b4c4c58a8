"""The projectile's float64 model: rollout, its discrete adjoint, and what the oracle and the
stress experiments derive from them (loss and gradient, finite differences, the Hessian, the
closed form without contact) with first-order bounds on their rounding error.

The step and the loss are defined in scenarios/projectile.py's docstring; ``c`` holds its
constants as float64 (``Projectile.constants``).
"""
from __future__ import annotations

import numpy as np

from .base import UNIT_ROUNDOFF, Precision

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
            if r is not None:      # (r is set exactly when record is)
                r[2] += np.where(hit, np.abs(avx), 0.0); r[3] += np.where(hit, np.abs(avy), 0.0)
        avy = avy + ay * dt          # y1 = y + vy1*dt
        avx = avx + ax * dt          # x1 = x + vx*dt
        if r is not None:
            r[2] += np.abs(ax * dt) + np.abs(avx); r[3] += np.abs(ay * dt) + np.abs(avy)
        if dacc is not None:
            live = dacc != 0.0
            ay = np.where(live, ay + avy * dacc * dt, ay)    # vy1 = vy + acc(y)*dt
            if r is not None:
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
    full_cols, half_cols = ([(f[j] - f[j + 1]) / (2 * step), (f[j + 2] - f[j + 3]) / (2 * step)]
                            for j, step in ((0, h), (4, h / 2)))
    full, half = np.stack(full_cols, axis=-1), np.stack(half_cols, axis=-1)
    rich = (4.0 * half - full) / 3.0
    if not with_error:
        return rich
    loss = np.abs(f[8])[..., None]
    return rich, np.abs(rich - half) + 8.0 * UNIT_ROUNDOFF[Precision.FLOAT64] * loss / h


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
