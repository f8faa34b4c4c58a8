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

import dataclasses
import math
import time
from typing import Callable, Literal, NamedTuple

import numpy as np

import backends
from backends.base import Device
from compare.stress.numerics import ORACLE, Overrides, Payload
from scenarios.base import Precision
from scenarios.projectile import CONSTANTS, Projectile
from scenarios.projectile_adjoint import loss_and_gradient

CLIP_NORM = 100.0                       # gradient clipping threshold (|grad| at v0 is ~636 for 'none')
ADAM = {"beta1": 0.9, "beta2": 0.999, "eps": 1e-8}
OPTIMISERS = ("gd", "clip", "adam")

Evaluate = Callable[[np.ndarray], tuple[float, np.ndarray]]


@dataclasses.dataclass(frozen=True)
class Descent:
    """One optimiser run: the loss history (as ``optimise`` gives it) and where it ended."""
    contact: str
    method: str
    lr: float
    history: list[float]
    v_final: list[float]


@dataclasses.dataclass(frozen=True)
class Scan:
    """Loss and gradient at each vy0 of one scan."""
    contact: str
    scan: str
    vy: list[float]
    loss: list[float]
    grad: list[list[float]]


@dataclasses.dataclass(frozen=True)
class Outcome:
    """A task's answer: its runs (``descents`` of an 'optimise' task, ``scans`` of a 'scan'
    task), or why there are none (``skipped``: over its time budget; ``error``: it failed)."""
    descents: tuple[Descent, ...] = ()
    scans: tuple[Scan, ...] = ()
    skipped: str | None = None
    error: str | None = None
    per_eval_s: float | None = None
    wall_s: float | None = None

    @property
    def why_not(self) -> str | None:
        """Why the task has no runs (None: it ran)."""
        return self.skipped or self.error

    def to_json(self) -> Payload:
        """What the worker writes back (the process boundary)."""
        if self.skipped:
            return {"skipped": self.skipped, "per_eval_s": self.per_eval_s}
        if self.error:
            return {"error": self.error}
        return {"results": [*map(dataclasses.asdict, self.descents), *map(dataclasses.asdict, self.scans)],
                "per_eval_s": self.per_eval_s, "wall_s": self.wall_s}


@dataclasses.dataclass(frozen=True)
class Task:
    """A host-loop task (``compare.stress.host_loop.HostTask``): 'optimise' runs ``methods`` at
    ``lrs`` for ``iters`` steps, 'scan' evaluates along ``scans`` (name -> vy0 values), per contact."""
    kind: Literal["optimise", "scan"]
    backend: str
    device: str
    precision: str
    contacts: tuple[str, ...]
    budget_s: float
    lrs: tuple[float, ...] = ()
    methods: tuple[str, ...] = ()
    iters: int = 0
    scans: dict[str, list[float]] = dataclasses.field(default_factory=dict)
    params: dict[str, float] = dataclasses.field(default_factory=dict)    # projectile overrides

    def to_json(self) -> Payload:
        """What the worker reads (the process boundary): the fields, and the function that runs them."""
        return {"call": f"{__name__}:run_task", **dataclasses.asdict(self)}

    @classmethod
    def from_json(cls, d: Payload) -> "Task":
        fields = {f.name for f in dataclasses.fields(cls)}
        d = {k: tuple(v) if k in ("contacts", "lrs", "methods") else v for k, v in d.items() if k in fields}
        return cls(**d)

    def outcome(self, result: Payload) -> Outcome:
        """The decode of the worker's answer (``Outcome.to_json``, or only an error)."""
        if "results" not in result:
            return Outcome(skipped=result.get("skipped"), error=None if "skipped" in result else result.get("error"),
                           per_eval_s=result.get("per_eval_s"))
        runs = result["results"]
        return Outcome(descents=tuple(Descent(**r) for r in runs) if self.kind == "optimise" else (),
                       scans=tuple(Scan(**r) for r in runs) if self.kind == "scan" else (),
                       per_eval_s=result.get("per_eval_s"), wall_s=result.get("wall_s"))


class Item(NamedTuple):
    """One unit of a task's work: (contact, optimiser, lr) or (contact, scan); ``evals`` is its
    evaluation count."""
    contact: str
    evals: int
    method: str = ""
    lr: float = 0.0
    scan: str = ""
    vy: tuple[float, ...] = ()


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


def backend_evaluator(backend: str, device: str, precision: str, params: Overrides) -> Evaluate:
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


def oracle_evaluator(params: Overrides, precision: Precision = Precision.FLOAT64) -> Evaluate:
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


def scan(evaluate: Evaluate, vx: float, vys: list[float], contact: str = "", name: str = "") -> Scan:
    losses: list[float] = []
    grads: list[list[float]] = []
    for vy in vys:
        loss, g = evaluate(np.array([vx, vy]))
        losses.append(loss); grads.append([float(g[0]), float(g[1])])
    return Scan(contact, name, list(vys), losses, grads)


def work_items(task: Task) -> list[Item]:
    """One item per (contact, optimiser, lr) or (contact, scan); each knows its evaluation count."""
    items = []
    for contact in task.contacts:
        if task.kind == "optimise":
            items += [Item(contact, task.iters + 1, method=m, lr=lr) for m in task.methods for lr in task.lrs]
        else:
            items += [Item(contact, len(vys), scan=name, vy=tuple(vys)) for name, vys in task.scans.items()]
    return items


def run_task(payload: Payload) -> Payload:
    """The worker's entry (``Task.to_json`` names it): the task from its JSON, the outcome as JSON."""
    return execute(Task.from_json(payload)).to_json()


def execute(task: Task) -> Outcome:
    """Run ``task`` in this process: its runs, or skipped when it would exceed its budget."""
    params = dict(task.params)
    v0 = np.array([params.get("vx0", 2.0), params.get("vy0", 6.5)])
    items = work_items(task)
    total = sum(it.evals for it in items)
    evaluators: dict[str, Evaluate] = {}

    def evaluator(contact: str) -> Evaluate:
        if contact not in evaluators:
            p: dict[str, float | str] = {**params, "contact": contact}
            evaluators[contact] = (oracle_evaluator(p) if task.backend == ORACLE else
                                   backend_evaluator(task.backend, task.device, task.precision, p))
        return evaluators[contact]

    # cost probe: the first evaluation compiles; the second is what every later one costs
    ev = evaluator(items[0].contact)
    t0 = time.perf_counter(); ev(v0); first = time.perf_counter() - t0
    t0 = time.perf_counter(); ev(v0); per_eval = time.perf_counter() - t0
    projected = per_eval * total
    if projected > task.budget_s:
        return Outcome(skipped=f"{total} host-loop evaluations at {per_eval * 1e3:.3g} ms each "
                               f"(first {first:.3g} s) would take "
                               f"~{projected:.0f} s, over this task's budget of {task.budget_s:g} s",
                       per_eval_s=per_eval)
    descents, scans = [], []
    t_start = time.perf_counter()
    for it in items:
        ev = evaluator(it.contact)
        if task.kind == "optimise":
            hist, v = optimise(ev, v0, it.lr, task.iters, it.method)
            descents.append(Descent(it.contact, it.method, it.lr, hist, [float(x) for x in v]))
        else:
            scans.append(scan(ev, float(v0[0]), list(it.vy), it.contact, it.scan))
    return Outcome(tuple(descents), tuple(scans), per_eval_s=per_eval, wall_s=time.perf_counter() - t_start)
