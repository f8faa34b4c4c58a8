"""The projectile stress experiments' verdict rules and predictions (docs/stress.md): how a loss
history is classified, where the observed learning-rate boundary lies, when a gradient mispredicts
the loss along a scan, and the float64 predictions they are held against.

Loss, gradient and Hessian come from the scenario's float64 model (scenarios/projectile_adjoint.py);
the optimisers from the host-loop tasks (compare/stress/projectile_tasks.py).
"""
from __future__ import annotations

import math
from typing import Iterable

import numpy as np

from compare.stress import projectile_tasks as T
from scenarios.projectile import CONSTANTS, Projectile
from scenarios.projectile_adjoint import hessian, loss_of

SC = Projectile()
CONTACTS = ("none", "hard", "soft")
CONVERGED_REL = 1e-6              # loss reduced a million-fold = miss distance reduced 1000-fold
DIVERGED_REL = 1e-3               # ended more than 0.1 % above its start
FD_AGREE = 0.01                   # a gradient 'agrees' with finite differences to 1 % (stated)
FD_STEPS = tuple(10.0 ** (e / 2) for e in range(2, -17, -1))     # 10 ... 1e-8, half decades


# ---- verdict rules (unit-tested in tests/stress/test_projectile_rules.py) ------------------------------------------

def classify(history: Iterable[float], rel: float = CONVERGED_REL, worse: float = DIVERGED_REL) -> str:
    """converged / stalled / diverged from a loss history h[0..K].

    diverged: a non-finite value, or h[K] > (1 + worse) h[0] (descent ended worse than it started;
    ``worse`` = 1e-3 is far above float32 rounding of the loss and far below any real growth);
    converged: h[K] <= rel h[0]; stalled: anything else (finite, not worse, not converged).
    """
    h = np.asarray(list(history), np.float64)
    if h.size == 0 or not np.all(np.isfinite(h)):
        return "diverged"
    if h[-1] > (1.0 + worse) * h[0]:
        return "diverged"
    return "converged" if h[-1] <= rel * h[0] else "stalled"


def observed_boundary(lrs: list[float], classes: list[str]) -> tuple[float | None, float | None]:
    """(largest lr below which nothing diverged, smallest lr that diverged)."""
    pairs = sorted(zip(lrs, classes))
    first_div = next((lr for lr, c in pairs if c == "diverged"), None)
    stable = [lr for lr, c in pairs if first_div is None or lr < first_div]
    return (max(stable) if stable else None), first_div


def loss_mispredictions(vys: list[float], losses: list[float], grads: list[list[float]],
                        noise_rel: float = 0.0) -> tuple[int, int]:
    """(mispredicted, unresolved) scan intervals. Mispredicted: the gradient's trapezoid prediction
    of the loss change is off by more than a factor 2 or in sign, |dL - pred| > max(|dL|, |pred|)/2,
    and by more than the loss's own rounding, noise_rel (|L_i| + |L_i+1|); unresolved: off by a
    factor 2 but within that rounding (the precision cannot tell)."""
    vy, loss = np.asarray(vys, np.float64), np.asarray(losses, np.float64)
    g = np.asarray(grads, np.float64)[:, 1]
    dl, pred = np.diff(loss), np.diff(vy) * 0.5 * (g[1:] + g[:-1])
    noise = noise_rel * (np.abs(loss[1:]) + np.abs(loss[:-1]))
    with np.errstate(invalid="ignore"):
        off = np.abs(dl - pred)
        factor2 = (off > 0.5 * np.maximum(np.abs(dl), np.abs(pred))) | ~np.isfinite(off)
        resolved = ~(off <= noise)
    return int(np.sum(factor2 & resolved)), int(np.sum(factor2 & ~resolved))


def predicted_lr(contact: str, iters: int) -> tuple[float, dict[str, float]]:
    """2/lambda_max of the float64 loss Hessian where descent at the seed's lr = 0.01 ends (local
    stability of gradient descent), and at v0; for 'none' also the closed form 1/(N dt)^2."""
    p = SC.params({"contact": contact, "iters": 0})
    inp = SC.inputs(p, "float64")
    c = {k: float(inp[k]) for k in CONSTANTS}
    hist, v_end = T.optimise(T.oracle_evaluator({"contact": contact}), inp["v0"], 0.01, iters, "gd")
    lam = {}
    for where, v in (("v0", inp["v0"].astype(np.float64)), ("v_end", v_end)):
        lam[where] = float(np.max(np.linalg.eigvalsh(hessian(c, contact, p.steps, v)))) if np.all(np.isfinite(v)) else math.nan
    info = {f"lambda_max({k})": val for k, val in lam.items()}
    if contact == "none":
        info["closed form 1/(N dt)^2"] = 1.0 / (p.steps * c["dt"]) ** 2
    lam_end = lam["v_end"] if math.isfinite(lam["v_end"]) else lam["v0"]
    return (2.0 / lam_end if lam_end > 0 else math.inf), info


def fd_gradient(c: dict[str, float], contact: str, steps: int, v: np.ndarray, h: float) -> np.ndarray:
    """Float64 central differences of the scenario's loss with step h."""
    return np.array([(loss_of(c, contact, steps, v + h * e) - loss_of(c, contact, steps, v - h * e)) / (2 * h)
                     for e in np.eye(2)])
