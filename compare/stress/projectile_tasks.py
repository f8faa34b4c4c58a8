"""Host-loop tasks of the projectile stress experiments (run by ``compare.stress.host_loop``).

Two experiments need more than one cell gives: optimisers the backends do not implement (gradient
clipping, Adam) and loss/gradient along a line of launch velocities. A task builds the backend's
projectile kernel with ``iters=0`` (one run = loss and gradient at ``v0``) once per contact model
and, per evaluation, overwrites its ``v0`` in place with the point asked for, rounded to the cell's
precision (``ScenarioKernel.set_input``: no rebuild, no recompile). **The optimiser runs on the
host** in float64: only the loss and gradient come from the backend. A kernel without
``set_input`` is rebuilt per evaluation, which costs whatever its constructor costs (JAX compiles
per instance), so a task times its second evaluation and declines, with the measured figures,
when the whole task would exceed its time budget.
"""
from __future__ import annotations

import math
import time
from typing import Any, Callable

import numpy as np

import backends
from backends.base import Device
from compare.stress.numerics import ORACLE
from scenarios.base import Precision
from scenarios.projectile import CONSTANTS, Projectile
from scenarios.projectile_adjoint import loss_and_gradient

CLIP_NORM = 100.0                       # gradient clipping threshold (|grad| at v0 is ~636 for 'none')
ADAM = {"beta1": 0.9, "beta2": 0.999, "eps": 1e-8}
OPTIMISERS = ("gd", "clip", "adam")

Evaluate = Callable[[np.ndarray], tuple[float, np.ndarray]]


def task(kind: str, **fields: Any) -> dict[str, Any]:
    """A host-loop task dict (JSON-able) that ``compare.stress.host_loop`` runs with ``run_task``."""
    return {"call": f"{__name__}:run_task", "kind": kind, **fields}


def optimise(evaluate: Evaluate, v0: np.ndarray, lr: float, iters: int, method: str,
             clip: float = CLIP_NORM) -> tuple[list[float], np.ndarray]:
    """history[k] = loss(v_k), k = 0..iters, like the scenario's own descent; stops at a non-finite loss.

    gd: v -= lr g;  clip: v -= lr g min(1, clip/|g|);  adam: Kingma & Ba with bias correction.
    """
    v = np.asarray(v0, np.float64).copy()
    m = np.zeros(2); s = np.zeros(2)
    hist: list[float] = []
    for k in range(iters + 1):
        loss, g = evaluate(v)
        hist.append(float(loss))
        if not (math.isfinite(loss) and np.all(np.isfinite(g))):
            hist += [math.nan] * (iters - k)
            break
        if k == iters:
            break
        if method == "gd":
            step = g
        elif method == "clip":
            norm = float(np.linalg.norm(g))
            step = g * min(1.0, clip / norm) if norm > 0 else g
        elif method == "adam":
            b1, b2, eps = ADAM["beta1"], ADAM["beta2"], ADAM["eps"]
            m = b1 * m + (1 - b1) * g
            s = b2 * s + (1 - b2) * g * g
            step = (m / (1 - b1 ** (k + 1))) / (np.sqrt(s / (1 - b2 ** (k + 1))) + eps)
        else:
            raise ValueError(f"unknown optimiser {method!r}")
        v = v - lr * step
    return hist, v


def backend_evaluator(backend: str, device: str, precision: Precision, params: dict[str, Any]) -> Evaluate:
    """loss and gradient at v from the backend's projectile kernel (iters = 0): one kernel, its v0
    replaced in place per call (``set_input``), else one kernel per call. Runs in a host-loop
    worker process."""
    be, sc = backends.get(backend), Projectile()
    p = sc.params({**params, "iters": 0})
    base = sc.inputs(p, precision)
    be.setup(device, precision, "default")
    kernel_cls = be.kernel(sc.name)
    dtype = base["v0"].dtype
    kernel, reusable = None, True

    def evaluate(v: np.ndarray) -> tuple[float, np.ndarray]:
        nonlocal kernel, reusable
        if not np.all(np.isfinite(v)):
            return math.nan, np.full(2, math.nan)
        with np.errstate(over="ignore"):
            v0 = np.asarray(v, np.float64).astype(dtype)
        if kernel is not None and reusable:
            try:
                kernel.set_input("v0", v0)
            except NotImplementedError:
                reusable = False
        if kernel is None or not reusable:
            kernel = kernel_cls(p, {**base, "v0": v0}, Device(device), Precision(precision), "default")
        k = kernel
        be.synchronize(device, k.run())
        out = k.outputs()
        return float(np.asarray(out["loss"]).reshape(())), np.asarray(out["grad"], np.float64).reshape(2)
    return evaluate


def oracle_evaluator(params: dict[str, Any], precision: Precision = Precision.FLOAT64) -> Evaluate:
    """The same from the scenario's float64 rollout and adjoint (constants rounded to
    ``precision`` as the backends receive them)."""
    sc = Projectile()
    p = sc.params({**params, "iters": 0})
    inputs = sc.inputs(p, precision)
    c = {k: float(inputs[k]) for k in CONSTANTS}

    def evaluate(v: np.ndarray) -> tuple[float, np.ndarray]:
        if not np.all(np.isfinite(v)):
            return math.nan, np.full(2, math.nan)
        return loss_and_gradient(c, p.contact, p.steps, v)
    return evaluate


def scan(evaluate: Evaluate, vx: float, vys: list[float]) -> dict[str, list[float] | list[list[float]]]:
    losses: list[float] = []
    grads: list[list[float]] = []
    for vy in vys:
        loss, g = evaluate(np.array([vx, vy]))
        losses.append(loss); grads.append([float(g[0]), float(g[1])])
    return {"vy": list(vys), "loss": losses, "grad": grads}


def work_items(task: dict[str, Any]) -> list[dict[str, Any]]:
    """One item per (contact, optimiser, lr) or (contact, scan); each knows its evaluation count."""
    items = []
    for contact in task["contacts"]:
        if task["kind"] == "optimise":
            items += [{"contact": contact, "method": m, "lr": lr, "evals": task["iters"] + 1}
                      for m in task["methods"] for lr in task["lrs"]]
        else:
            items += [{"contact": contact, "scan": name, "vy": vys, "evals": len(vys)}
                      for name, vys in task["scans"].items()]
    return items


def run_task(task: dict[str, Any]) -> dict[str, Any]:
    """Execute in this process. Returns {"results": [...]} or {"skipped": reason}."""
    params = dict(task.get("params", {}))
    v0 = np.array([params.get("vx0", 2.0), params.get("vy0", 6.5)])
    items = work_items(task)
    total = sum(it["evals"] for it in items)
    evaluators: dict[str, Evaluate] = {}

    def evaluator(contact: str) -> Evaluate:
        if contact not in evaluators:
            p = {**params, "contact": contact}
            evaluators[contact] = (oracle_evaluator(p) if task["backend"] == ORACLE else
                                   backend_evaluator(task["backend"], task["device"], task["precision"], p))
        return evaluators[contact]

    # cost probe: the first evaluation compiles; the second is what every later one costs
    ev = evaluator(items[0]["contact"])
    t0 = time.perf_counter(); ev(v0); first = time.perf_counter() - t0
    t0 = time.perf_counter(); ev(v0); per_eval = time.perf_counter() - t0
    projected = per_eval * total
    if projected > task["budget_s"]:
        return {"skipped": f"{total} host-loop evaluations at {per_eval * 1e3:.3g} ms each "
                           f"(first {first:.3g} s) would take "
                           f"~{projected:.0f} s, over this task's budget of {task['budget_s']:g} s",
                "per_eval_s": per_eval}
    results = []
    t_start = time.perf_counter()
    for it in items:
        ev = evaluator(it["contact"])
        if task["kind"] == "optimise":
            hist, v = optimise(ev, v0, it["lr"], task["iters"], it["method"])
            results.append({**{k: it[k] for k in ("contact", "method", "lr")}, "history": hist,
                            "v_final": [float(x) for x in v]})
        else:
            results.append({"contact": it["contact"], "scan": it["scan"], **scan(ev, float(v0[0]), it["vy"])})
    return {"results": results, "per_eval_s": per_eval, "wall_s": time.perf_counter() - t_start}
