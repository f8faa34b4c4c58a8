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
'hard' and 'soft' a float64 rollout with its hand-written discrete adjoint (both in
scenarios/projectile_adjoint.py; checked against central finite differences in the tests). The oracle also carries first-order running bounds on
the rounding error of the state (as in the particles scenario), from which the tolerances for
loss, gradient and history are derived (see ``check``).
"""
from __future__ import annotations

import dataclasses
import math
from typing import Any, Literal

import numpy as np

from .base import (Check, Precision, Sample, Scenario, UNIT_ROUNDOFF, dtype_of, require, sample_rows,
                   sample_seed)
from .projectile_adjoint import closed_form, evaluate, finite_difference_gradient, hessian, spectral_norm_sym

CONSTANTS = ("dt", "gravity", "target_x", "target_y", "bounce", "damping", "stiffness",
             "softness", "lr")
MAX_BATCH = 1 << 24
BIG_BATCH = 1 << 16    # from here a cell is first timed in miniature (compare.planning.calibrate)
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

# Host bytes a CPU port's tape takes per step: (one trajectory, per trajectory of a batch). The
# first bounds a single trajectory's per-operation overheads, the second the slope between
# horizons where fixed costs cancel (docs/measurement.md, "Memory": where both come from).
TAPE_STEP_BYTES = (900.0, 400.0)


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
    # on a GPU its ranked timings are the gradient rows', at the scaling sweep's largest batch (2^20
    # on the H100), never its defaults' one trajectory; the CPU-only and busy rows rank those
    timings_ranked_on = ("cpu",)

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

    def size_text(self, params: ProjectileParams) -> str:
        return f"steps={params.steps}" + (f", batch={params.batch}" if params.batch > 1 else "")

    def scaled(self, params: ProjectileParams, factor: int) -> ProjectileParams | None:
        return (dataclasses.replace(params, batch=max(1, params.batch // factor))
                if params.batch >= BIG_BATCH else None)

    def sample(self, params: ProjectileParams, inputs: dict[str, np.ndarray],
               outputs: dict[str, np.ndarray], k: int) -> Sample | None:
        """k trajectories of a batch (BATCH_CHECKED when k is 0), the rows of ``sample_rows``
        (extremes of v0, target and of every output, so a NaN or a wild value a port writes into
        one trajectory is always looked at): the oracle's cost grows with steps (steps^2 for soft
        contact) per trajectory and evaluation."""
        k = k or BATCH_CHECKED
        if params.batch <= k:
            return None
        seed = sample_seed(params)
        per_row = [inputs["v0"], inputs["target"]] + [np.asarray(a).T if n == "loss_history" else a
                                                      for n, a in outputs.items()]
        idx = sample_rows(params.batch, k, seed, per_row)
        ins = {n: (a[idx] if n in ("v0", "target") else a) for n, a in inputs.items()}
        outs = {n: (np.asarray(a)[:, idx] if n == "loss_history" else np.asarray(a)[idx])
                for n, a in outputs.items()}
        return Sample(ins, outs, int(idx.size), params.batch, "trajectories", seed, idx)

    @staticmethod
    def constants(inputs: dict[str, np.ndarray]) -> dict[str, Any]:
        """Float64 constants of the (rounded) inputs; the targets per trajectory."""
        c: dict[str, Any] = {k: float(inputs[k]) for k in CONSTANTS}
        target = np.asarray(inputs["target"], np.float64)
        c["target_x"], c["target_y"] = target[..., 0], target[..., 1]
        return c

    def oracle(self, params: ProjectileParams, inputs, precision: Precision) -> dict[str, np.ndarray]:
        """Vectorised over the trajectories of ``inputs`` (one, or a batch)."""
        # the port's rounding (u) plus the float64 oracle's own (u64): the bounds are linear in u
        u = UNIT_ROUNDOFF[precision] + UNIT_ROUNDOFF[Precision.FLOAT64]
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
        hs_arr, dvs_arr, vs_arr = np.array(hs), np.array(dvs), np.array(vs)
        if params.iters:
            dh = spectral_norm_sym(hs_arr[1:] - hs_arr[:-1])
            step = np.linalg.norm(vs_arr[1:] - vs_arr[:-1], axis=-1)
            rate = np.divide(dh, step, out=np.full(dh.shape, np.inf), where=step > 0)
            rate = np.where((dh == 0), 0.0, rate)
            rate = np.concatenate([rate, rate[-1:]])
            with np.errstate(invalid="ignore"):
                gain = np.maximum(spectral_norm_sym(np.eye(2) - lr * hs_arr), 1.0)
                linear = np.logical_and.accumulate(lr * rate * dvs_arr <= LINEAR_MARGIN * gain, axis=0)
        else:
            linear = np.ones(dvs_arr.shape, bool)
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

    def work(self, params: ProjectileParams, precision: str) -> dict[str, float]:
        """items: trajectory-steps; gradients: trajectory-gradients (B x evaluations), whose rate is
        the gradient throughput; flops: FLOPS_PER_STEP per trajectory-step, forward and reverse."""
        evals = float(params.batch) * (params.iters + 1)
        return {"items": evals * params.steps, "gradients": evals,
                "flops": evals * params.steps * FLOPS_PER_STEP[params.contact]}

    def footprint(self, params: ProjectileParams, precision: str, device: str = "cpu") -> float:
        # per checked trajectory, the per-step states of the float64 oracle's rollout + adjoint +
        # bounds (soft: also its steps x 4 x 4 transition stack); per trajectory, the inputs and
        # outputs; on the CPU the port's tape per step, the larger of a single trajectory's step
        # and the batch times the largest per-trajectory-step slope of the horizon sweeps
        # (TAPE_STEP_BYTES; on a GPU the tape is device memory); plus a fixed part for JAX
        checked = min(params.batch, BATCH_CHECKED)
        oracle = params.steps * (1400.0 + (128.0 * params.steps if params.contact == "soft" else 0.0))
        one, per_traj_step = TAPE_STEP_BYTES
        tape = params.steps * max(one, per_traj_step * params.batch) if device == "cpu" else 0.0
        per_traj = (params.iters + 8) * 8.0 * 3
        return 32.0 * 2**20 + checked * oracle + tape + params.batch * per_traj + params.iters * 64.0

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
