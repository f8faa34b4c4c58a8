"""Converged float64 references of the time-against-error sweep, and the errors measured
against them (compare/sweep/points/ says which scenario uses which).

Each reference comes from the scenario's own physics (its field, its NumPy stepper, its rollout
and adjoint), computed at a finer resolution than any swept point; a reference that depends on
the sweep point is memoised in a cache the suite keeps for a whole run (``dt_reference``).
"""
from __future__ import annotations

import dataclasses
import json
from typing import Any, Callable, Mapping

import numpy as np

from compare.results.record_parts import Converged, ReferenceInfo
from scenarios.base import Scenario
from scenarios.particles import simulate
from scenarios.projectile import CONSTANTS
from scenarios.projectile_adjoint import loss_and_gradient
from scenarios.sdf import sdf_field

REF_FACTOR = 16          # converged dt references: smallest swept dt / REF_FACTOR
SDF_EVAL = 2001          # points per axis of the grid the sdf reconstruction is measured on

Param = int | float | str      # a scenario parameter's value (every field of a scenario's Params is one)
Solution = tuple[np.ndarray | float, ...]       # what a reference solve returns (positions; loss, gradient)
Cache = dict[Any, Any]         # memoised references, kept by the suite for a whole run (keys: what they depend on)


@dataclasses.dataclass(frozen=True)
class Reference:
    """What a sweep point's converged error is measured against: a float64 rollout at ``dt``
    (None: the scenario's default). A property of the sweep, not of the cell: the suite hands it
    back to ``converged_error`` and never stores it in the cell's identity."""
    dt: float | None = None


def dt_reference(cache: Cache, sc: Scenario, params: Mapping[str, Param], reference: Reference | None,
                 default_dt: float, solve: Callable[[Scenario, Mapping[str, Param], float, int], Solution],
                 distance: Callable[[Solution, Solution], float],
                 simulated_time: float) -> tuple[Solution, ReferenceInfo]:
    """A converged float64 reference over ``simulated_time`` at the sweep point's reference time
    step (``reference.dt``, else ``default_dt``) for ``params`` without their dt and steps,
    memoised in ``cache``, and what it is: ``solve(sc, base_params, dt, steps)`` computes it; its
    ``self_difference`` is ``distance(coarse, reference)`` to the same at 2 dt (its own error
    scale, which must be far below the errors it measures)."""
    dt = (reference.dt if reference is not None else None) or default_dt
    base = {k: v for k, v in params.items() if k not in ("dt", "steps")}
    key = (sc.name, json.dumps(base, sort_keys=True), dt)
    if key not in cache:
        steps = round(simulated_time / dt)
        ref = solve(sc, base, dt, steps)
        coarse = solve(sc, base, 2 * dt, round(simulated_time / (2 * dt)))
        cache[key] = (ref, ReferenceInfo(dt=dt, steps=steps, simulated_time_s=simulated_time,
                                         self_difference=distance(coarse, ref),
                                         note="float64 NumPy rollout; self_difference: same metric "
                                              "against a reference at 2 dt (its own error scale)"))
    return cache[key]


# ---- sdf: the analytic field ------------------------------------------------------------------
def reconstruction_error(image: np.ndarray, cache: Cache | None = None) -> dict[str, float]:
    """Bilinear reconstruction of the image against the analytic field on a fixed fine grid
    (SDF_EVAL points per axis over [-1, 1]^2): max and RMS of the difference."""
    img = np.asarray(image, np.float64)
    h, w = img.shape
    t = np.linspace(-1.0, 1.0, SDF_EVAL)
    cache = {} if cache is None else cache
    if ("sdf-field", SDF_EVAL) not in cache:
        cache["sdf-field", SDF_EVAL] = sdf_field(t[None, :], t[:, None])
    exact = cache["sdf-field", SDF_EVAL]

    def axis(n):
        pos = (t + 1.0) * 0.5 * (n - 1)
        i0 = np.clip(np.floor(pos).astype(np.int64), 0, n - 2)
        return i0, pos - i0
    i0, fx = axis(w)
    j0, fy = axis(h)
    rows0, rows1 = img[j0], img[j0 + 1]
    top = rows0[:, i0] * (1 - fx) + rows0[:, i0 + 1] * fx
    bot = rows1[:, i0] * (1 - fx) + rows1[:, i0 + 1] * fx
    d = np.abs(top * (1 - fy)[:, None] + bot * fy[:, None] - exact)
    return {"error": float(d.max()), "rms": float(np.sqrt(np.mean(d * d)))}


# ---- particles: positions at the same simulated time -------------------------------------------
def converged_positions(sc: Scenario, params: Mapping[str, Param], dt: float,
                        steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Float64 positions after ``steps`` steps of ``dt`` (the particle scenario ``sc``'s one NumPy
    stepper, ``simulate``) from the float64 initial state of ``params``."""
    p = sc.params({**params, "dt": dt, "steps": steps})
    (x, y, _, _), _ = simulate(sc.inputs(p, "float64"), steps, np.float64)
    return x, y


def position_error(px: np.ndarray, py: np.ndarray, rx: np.ndarray, ry: np.ndarray) -> dict[str, float]:
    """RMS (``error``) and max over particles of the position distance to (rx, ry)."""
    d = np.hypot(np.asarray(px, np.float64) - rx, np.asarray(py, np.float64) - ry)
    return {"error": float(np.sqrt(np.mean(d * d))), "max": float(d.max())}


# ---- projectile: loss and gradient at v0 -------------------------------------------------------
def converged_loss_grad(sc: Scenario, params: Mapping[str, Param], dt: float, steps: int) -> tuple[float, np.ndarray]:
    """Float64 loss and discrete-adjoint gradient at v0 (``loss_and_gradient``: ``rollout`` +
    ``adjoint``) after ``steps`` steps of ``dt`` of the projectile scenario ``sc``, the other
    parameters from ``params``."""
    p = sc.params({**params, "dt": dt, "steps": steps})
    c = {k: float(getattr(p, k)) for k in CONSTANTS}
    return loss_and_gradient(c, p.contact, steps, (p.vx0, p.vy0))


def loss_grad_error(loss: np.ndarray, grad: np.ndarray, rloss: float, rgrad: np.ndarray) -> dict[str, float]:
    """max(relative error of the loss, relative 2-norm error of the gradient) (``error``)."""
    el = abs(float(np.asarray(loss).reshape(())) - rloss) / abs(rloss)
    eg = float(np.linalg.norm(np.asarray(grad, np.float64).reshape(2) - rgrad) / np.linalg.norm(rgrad))
    return {"error": max(el, eg), "loss_rel": el, "grad_rel": eg}
