"""``python -m compare stress``: the numerical stability stress suite.

Measures, per backend and device, what the seeds only warn about: float32 in long rollouts, hard
contacts and noisy gradients, gradient explosion at large learning rates, fast-math, races. Every
finding is a row (experiment, backend, device, precision, setting, figure, value, verdict, detail)
whose verdict is decided from the value beside it by a rule stated in docs/stress.md; nothing is
tuned per backend. Backend runs go through compare.cells.run (one worker process per cell); the
optimiser study and the gradient scans use compare.stress_tasks (host loop, see there).

    python -m compare stress [--backends ...] [--devices cpu,cuda] [--quick] [--out DIR]
                             [--only EXP,...] [--jobs N] [--timeout S]

Writes DIR/stress.json, DIR/stress.md and DIR/*.png. With --only, rows of the experiments not run
this time are kept from an existing DIR/stress.json, so a long suite can be run in parts.
Exit status: 0 when the suite ran (unstable settings are findings, not failures), 1 when a cell
failed unexpectedly or the racy control kernel went unflagged on a GPU, 2 for bad usage.
"""
from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import json
import math
import os
import re
import sys
import time
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np

import backends
import scenarios
from compare import cells, environment, stress_tasks
from compare.report import atomic_write, fmt_num
from scenarios import projectile as P
from scenarios.base import UNIT_ROUNDOFF, ParamError

EXIT_OK, EXIT_FAIL, EXIT_USAGE = 0, 1, 2
COLUMNS = ("experiment", "backend", "device", "precision", "setting", "figure", "value", "verdict", "detail")
RACY = "racy-one-launch"          # the Warp particles variant that reproduces the seed's race
CONVERGED_REL = 1e-6              # loss reduced a million-fold = miss distance reduced 1000-fold
DIVERGED_REL = 1e-3               # ended more than 0.1 % above its start
FD_AGREE = 0.01                   # a gradient 'agrees' with finite differences to 1 % (stated)
SEED_LRS = (0.01, 0.08, 0.2)


# ---------------------------------------------------------------------------------------------
# Pure analysis (unit-tested in tests/test_stress.py)

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


def bitwise_differences(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> int:
    """Number of elements whose bit patterns differ (NaN == NaN when the bits match); -1 when the
    two sets of outputs do not even have the same names, shapes or dtypes."""
    n = 0
    for k in sorted(set(a) | set(b)):
        if k not in a or k not in b:
            return -1
        x, y = np.ascontiguousarray(a[k]), np.ascontiguousarray(b[k])
        if x.shape != y.shape or x.dtype != y.dtype:
            return -1
        if x.size:
            bx, by = x.view(np.uint8).reshape(x.size, -1), y.view(np.uint8).reshape(y.size, -1)
            n += int(np.sum(np.any(bx != by, axis=1)))
    return n


def race_verdict(device: str, differing: int, oracle_ok: tuple[bool, bool]) -> str:
    """Verdict of the racy control: flagged if two runs differ or a run misses the oracle's bound."""
    if differing != 0 or not all(oracle_ok):
        why = []
        if differing != 0:
            why.append("runs differ" if differing > 0 else "runs differ in shape")
        if not all(oracle_ok):
            why.append("outside the oracle's bound")
        return "RACE DETECTED (" + ", ".join(why) + ")"
    return "race not observable on CPU" if device == "cpu" else "MISSED: race not flagged"


def energy(x: np.ndarray, y: np.ndarray, u: np.ndarray, v: np.ndarray, gravity: float,
           radius: float) -> np.ndarray:
    """Per-particle mechanical energy per unit mass, 0 at rest on the floor (float64)."""
    f = lambda a: np.asarray(a, np.float64)  # noqa: E731
    with np.errstate(over="ignore", invalid="ignore"):
        return 0.5 * (f(u) ** 2 + f(v) ** 2) + abs(gravity) * (f(y) - radius)


def energy_bound(inputs: dict[str, np.ndarray]) -> np.ndarray:
    """Per-particle energy bound of the exact scheme for bounce < 1, damping <= 1 (docs/stress.md):
    horizontal energy never grows; free flight loses g^2 dt^2/2 per step; a floor contact leaves
    vertical energy <= max(before, E_floor), E_floor = (b |g| dt/(1-b))^2 / 2."""
    c = {k: float(inputs[k]) for k in ("dt", "gravity", "bounce", "radius")}
    b = c["bounce"]
    e_floor = 0.5 * (b * abs(c["gravity"]) * c["dt"] / (1.0 - b)) ** 2
    u0 = inputs["vx0"].astype(np.float64)
    ev0 = 0.5 * inputs["vy0"].astype(np.float64) ** 2 + abs(c["gravity"]) * (inputs["y0"] - c["radius"])
    return 0.5 * u0 ** 2 + np.maximum(ev0, e_floor)


def contacts(tx: np.ndarray, ty: np.ndarray, radius: float, dtype: Any) -> np.ndarray:
    """Per frame and particle: was it clamped (on the floor or a wall) in the step that ended there?

    A clamp sets the coordinate to the threshold exactly; 4 ulps of slack absorbs a port computing
    -1 + radius in another order. A free flight that ends within 4 ulps of a wall is negligible.
    """
    tol = 4.0 * float(np.finfo(dtype).eps)
    lo, hi = float(dtype(-1.0) + dtype(radius)), float(dtype(1.0) - dtype(radius))
    tx, ty = np.asarray(tx, np.float64), np.asarray(ty, np.float64)
    return (ty <= radius + tol) | (tx <= lo + tol) | (tx >= hi - tol)


def first_flips(ca: np.ndarray, cb: np.ndarray) -> np.ndarray:
    """Per particle, the first frame where two contact sequences differ (-1: never)."""
    diff = ca != cb
    first = np.argmax(diff, axis=0)
    return np.where(diff.any(axis=0), first, -1)


def ulps(out: np.ndarray, ref: np.ndarray, dtype: Any = np.float32) -> np.ndarray:
    """|out - ref| in units of the spacing of ``dtype`` at ref (ulps of the correctly rounded result)."""
    ref = np.asarray(ref, np.float64)
    spacing = np.spacing(np.abs(ref).astype(dtype)).astype(np.float64)
    return np.abs(np.asarray(out, np.float64) - ref) / spacing


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


# ---------------------------------------------------------------------------------------------
# Running cells

@dataclasses.dataclass
class Ctx:
    backends: list[str]
    devices: list[str]
    quick: bool
    jobs: int
    timeout: float
    probes: dict[str, dict[str, Any]]

    def why_not(self, backend: str, device: str) -> str | None:
        return self.probes[backend]["available"].get(device)

    def targets(self, variants: bool = False) -> list[tuple[str, str, str]]:
        """(backend, device, variant) that can run, reference first."""
        out = []
        for d in self.devices:
            for b in self.backends:
                if self.why_not(b, d):
                    continue
                for v in (backends.get(b).variants if variants else ("default",)):
                    out.append((b, d, v))
        return out

    def skip_rows(self, experiment: str) -> list[dict[str, Any]]:
        return [row(experiment, b, d, "-", "-", "-", None, "skipped", self.why_not(b, d))
                for d in self.devices for b in self.backends if self.why_not(b, d)]


def row(experiment: str, backend: str, device: str, precision: str, setting: str, figure: str,
        value: Any, verdict: str, detail: str | None = "") -> dict[str, Any]:
    if isinstance(value, (np.floating, np.integer)):
        value = value.item()
    return dict(zip(COLUMNS, (experiment, backend, device, precision, setting, figure, value, verdict,
                              detail or "")))


def spec(scenario: str, backend: str, device: str, precision: str, params: dict[str, Any],
         variant: str = "default") -> dict[str, Any]:
    # Timing is not measured here: one timed call (the worker adds its first call and warm-ups),
    # and the frameworks' kernel caches stay warm so cells do not recompile the same kernels.
    return {"scenario": scenario, "backend": backend, "device": device, "precision": precision,
            "variant": variant, "params": params, "quick": False, "repeat": 1, "min_time": 0.0,
            "cache": "warm", "timer": "wall"}


def gpu_lane(item: Any) -> Any:
    """Items that must not overlap: work of one backend on one GPU (None: no constraint).

    Frameworks reserve device memory per process: Taichi sizes each kernel's autodiff-stack local
    memory for every thread the GPU can hold resident, so eight Taichi processes on one H100 ran out
    of memory at launch. One process per backend per GPU still lets different backends overlap.
    """
    # items are cell specs / task dicts, or (backend, device, ...) tuples
    backend, device = ((item.get("backend"), item.get("device")) if isinstance(item, dict) else item[:2])
    return None if device in ("cpu", "host") else (backend, device)


def pool_map(ctx: Ctx, fn: Callable[[Any], Any], items: list[Any],
             lane: Callable[[Any], Any] = gpu_lane) -> list[Any]:
    """Stress figures are not timings, so cells may share the machine: ``--jobs`` at a time, except
    that items in the same ``lane`` (not None) run one after another."""
    groups: dict[Any, list[int]] = {}
    for i, it in enumerate(items):
        key = lane(it)
        groups.setdefault(("solo", i) if key is None else key, []).append(i)
    results: list[Any] = [None] * len(items)

    def run_group(idx: list[int]) -> None:
        for i in idx:
            results[i] = fn(items[i])

    if ctx.jobs <= 1 or len(groups) <= 1:
        for idx in groups.values():
            run_group(idx)
    else:
        with concurrent.futures.ThreadPoolExecutor(max_workers=ctx.jobs) as pool:
            list(pool.map(run_group, groups.values()))
    return results


def run_cells(ctx: Ctx, specs: list[dict[str, Any]]) -> list[tuple[dict[str, Any], dict[str, np.ndarray] | None]]:
    return pool_map(ctx, lambda s: cells.run(s, timeout=ctx.timeout), specs)


def label(spec_or_rec: dict[str, Any]) -> str:
    s = spec_or_rec
    v = s.get("variant", "default")
    return f"{s['backend']}/{s['device']}" + ("" if v == "default" else f"/{v}")


def error_row(experiment: str, s: dict[str, Any], setting: str, rec: dict[str, Any]) -> dict[str, Any]:
    return row(experiment, label(s).split("/", 1)[0], s["device"], s["precision"], setting, "cell",
               None, "error", rec.get("reason", "?"))


def finite_state(out: dict[str, np.ndarray]) -> bool:
    return all(bool(np.all(np.isfinite(out[k]))) for k in ("x", "y", "vx", "vy"))


# ---------------------------------------------------------------------------------------------
# Experiments: each returns (rows, series); series are what its plot needs (kept in stress.json)

Result = tuple[list[dict[str, Any]], dict[str, Any]]


def particle_inputs(params: dict[str, Any], precision: str):
    sc = scenarios.get("particles")
    p = sc.params(params)
    return sc, p, sc.inputs(p, precision)


def state_error(out: dict[str, np.ndarray], ref: dict[str, np.ndarray]) -> np.ndarray:
    with np.errstate(invalid="ignore", over="ignore"):
        return np.max([np.abs(np.asarray(out[k], np.float64) - ref[k]) for k in ("x", "y", "vx", "vy")], axis=0)


def exp_particles_dt(ctx: Ctx) -> Result:
    """dt sweep at fixed simulated time T = 3 s: float32 rounding against the time discretisation."""
    name, T, n = "particles-dt", 3.0, 256
    dts = (0.02, 0.005, 0.001) if ctx.quick else (0.02, 0.01, 0.005, 0.002, 0.001, 0.0005)
    precisions = ("float32",) if ctx.quick else ("float32", "float64")   # float64: exact vs the oracle
    steps = {dt: int(round(T / dt)) for dt in dts}
    # discretisation error: float64 oracle at dt against one at dt_min/4 (median over particles)
    sc, pf, inf = particle_inputs({"n": n, "steps": 4 * steps[dts[-1]], "dt": dts[-1] / 4}, "float64")
    fine = sc.oracle(pf, inf)
    disc, ref32 = {}, {}
    for dt in dts:
        _, p, i64 = particle_inputs({"n": n, "steps": steps[dt], "dt": dt}, "float64")
        disc[dt] = float(np.median(state_error(sc.oracle(p, i64), fine)))
        _, p, i32 = particle_inputs({"n": n, "steps": steps[dt], "dt": dt}, "float32")
        ref32[dt] = sc.oracle(p, i32)
    specs = [spec("particles", b, d, prec, {"n": n, "steps": steps[dt], "dt": dt})
             for b, d, _ in ctx.targets() for prec in precisions for dt in dts]
    rows, lines = ctx.skip_rows(name), {}
    for s, (rec, out) in zip(specs, run_cells(ctx, specs)):
        dt = s["params"]["dt"]
        setting = f"dt={dt:g}, steps={steps[dt]}, T={T:g} s"
        if rec["status"] == "error" or out is None:
            rows.append(error_row(name, s, setting, rec)); continue
        e = rec["error"]
        ok = rec["status"] == "ok"
        rows.append(row(name, s["backend"], s["device"], s["precision"], setting,
                        "max error / derived bound (well-conditioned particles)",
                        e.get("worst_error_over_bound"), "within derived bound" if ok else "EXCEEDS derived bound",
                        f"max |state - float64| {fmt_num(e['vs_oracle'])} vs bound {fmt_num(e['tolerance'])}; "
                        f"{e.get('ill_conditioned')} ill-conditioned particles not checked"))
        line = lines.setdefault(f"{label(s)}/{s['precision']}", {"dt": [], "median": []})
        line["dt"].append(dt)
        if s["precision"] == "float32":
            med = float(np.median(state_error(out, ref32[dt])))
            line["median"].append(med)
            ratio = med / disc[dt] if disc[dt] > 0 else math.inf
            rows.append(row(name, s["backend"], s["device"], s["precision"], setting,
                            "median rounding error / median discretisation error", ratio,
                            "rounding below discretisation" if ratio < 1 else
                            "ROUNDING DOMINATES: a smaller dt no longer helps in float32",
                            f"rounding {med:.3g} (vs float64 oracle, same inputs), discretisation "
                            f"{disc[dt]:.3g} (float64 at dt vs at dt = {dts[-1] / 4:g})"))
        else:
            line["median"].append(e["vs_oracle"])
    return rows, {"dt": list(dts), "discretisation": [disc[dt] for dt in dts], "lines": lines}


def exp_particles_long(ctx: Ctx) -> Result:
    """Long rollouts: energy against its derived bound (bounce < 1) or its growth (bounce > 1)."""
    name, n = "particles-long", 256
    lengths = (10_000,) if ctx.quick else (1000, 10_000, 100_000)
    bounces = (0.82, 1.05) if ctx.quick else (0.82, 0.99, 1.05)
    precisions = ("float32",) if ctx.quick else ("float32", "float64")
    specs = [spec("particles", b, d, prec, {"n": n, "steps": st, "bounce": bo})
             for b, d, _ in ctx.targets() for prec in precisions for bo in bounces for st in lengths]
    rows, series = ctx.skip_rows(name), {}
    for s, (rec, out) in zip(specs, run_cells(ctx, specs)):
        prm = s["params"]
        setting = f"bounce={prm['bounce']}, steps={prm['steps']}"
        if rec["status"] == "error" or out is None:
            rows.append(row(name, s["backend"], s["device"], s["precision"], setting, "cell", None,
                            "CRASHED" if prm["bounce"] > 1 else "error", rec.get("reason")))
            continue
        _, _, inp = particle_inputs(prm, s["precision"])
        g, r = float(inp["gravity"]), float(inp["radius"])
        e0 = energy(inp["x0"], inp["y0"], inp["vx0"], inp["vy0"], g, r)
        et = energy(out["x"], out["y"], out["vx"], out["vy"], g, r)
        total = float(np.sum(et) / np.sum(e0))
        fin = finite_state(out)
        key = f"{label(s)}/{s['precision']}/bounce={prm['bounce']}"
        series.setdefault(key, {"steps": [], "ratio": []})
        series[key]["steps"].append(prm["steps"]); series[key]["ratio"].append(total if fin else None)
        if prm["bounce"] < 1:
            slack = 16 * UNIT_ROUNDOFF[s["precision"]]
            worst = float(np.max(et / energy_bound(inp))) if fin else math.inf
            verdict = ("NON-FINITE state" if not fin else "no energy gain (within derived bound)"
                       if worst <= 1 + slack else "GAINS ENERGY beyond the derived bound")
            rows.append(row(name, s["backend"], s["device"], s["precision"], setting,
                            "max over particles of E(T) / derived bound", worst, verdict,
                            f"total E(T)/E(0) = {total:.3g}; bound E <= u0^2/2 + max(Ev0, E_floor), slack 16u"))
        else:
            verdict = ("unstable, reported: non-finite state, no crash" if not fin else
                       f"unstable, reported: energy x{total:.3g} (bounce > 1 adds energy)" if total > 1 else
                       "no energy growth observed")
            rows.append(row(name, s["backend"], s["device"], s["precision"], setting,
                            "total E(T) / E(0)", total, verdict,
                            f"max height {float(np.max(np.asarray(out['y'], np.float64))):.3g} m"))
    return rows, series


def emulate_first_nonfinite(params: dict[str, Any], precision: str, max_steps: int) -> int | None:
    """The scenario's step in NumPy at ``precision`` (operation by operation, no FMA): the first
    step after which some particle's state is non-finite."""
    _, _, inp = particle_inputs(params, precision)
    c = {k: inp[k][()] for k in ("dt", "gravity", "damping", "bounce", "radius")}
    one = np.ones((), inp["x0"].dtype)
    lo, hi, gdt = -one + c["radius"], one - c["radius"], c["gravity"] * c["dt"]
    x, y, u, v = (inp[k].copy() for k in ("x0", "y0", "vx0", "vy0"))
    with np.errstate(all="ignore"):
        for s in range(1, max_steps + 1):
            v = v + gdt; x = x + u * c["dt"]; y = y + v * c["dt"]
            h = y < c["radius"]
            y = np.where(h, c["radius"], y); v = np.where(h, -c["bounce"] * v, v); u = np.where(h, c["damping"] * u, u)
            h = x < lo
            x = np.where(h, lo, x); u = np.where(h, -c["bounce"] * u, u)
            h = x > hi
            x = np.where(h, hi, x); u = np.where(h, -c["bounce"] * u, u)
            if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y)) and np.all(np.isfinite(u))
                    and np.all(np.isfinite(v))):
                return s
    return None


def exp_particles_inf(ctx: Ctx) -> Result:
    """bounce = 1.05: the walls return 5 % more speed at every hit and are hit ever more often, so
    the horizontal speed overflows in finite time; find the first step with a non-finite state."""
    name, n, smax = "particles-inf", 256, 30_000
    base = {"n": n, "bounce": 1.05}
    predicted = {prec: emulate_first_nonfinite(base, prec, smax) for prec in ("float32", "float64")}

    def search(item):
        b, d, var, prec = item
        calls = []

        def nonfinite(steps: int) -> bool | None:
            if steps == 0:
                return False
            rec, out = cells.run(spec("particles", b, d, prec, {**base, "steps": steps}, var), timeout=ctx.timeout)
            calls.append(steps)
            if rec["status"] == "error" or out is None:
                raise RuntimeError(rec.get("reason", "?"))
            return not finite_state(out)
        try:
            s_star = predicted[prec] or smax
            lo_, hi_ = None, None
            if nonfinite(s_star - 1):
                lo_, hi_ = 0, s_star - 1
            elif nonfinite(s_star):
                lo_, hi_ = s_star - 1, s_star
            elif not nonfinite(smax):
                return item, None, calls, None
            else:
                lo_, hi_ = s_star, smax
            while hi_ - lo_ > 1:          # bisection: non-finite stays non-finite (see docs)
                mid = (lo_ + hi_) // 2
                lo_, hi_ = (lo_, mid) if nonfinite(mid) else (mid, hi_)
            return item, hi_, calls, None
        except RuntimeError as exc:
            return item, None, calls, str(exc)

    items = [(b, d, v, prec) for b, d, v in ctx.targets(variants=True) for prec in ("float32", "float64")]
    rows = ctx.skip_rows(name)
    for (b, d, var, prec), first, calls, err in pool_map(ctx, search, items):
        setting = f"bounce=1.05, n={n}" + ("" if var == "default" else f", variant={var}")
        pred = predicted[prec]
        if err:
            rows.append(row(name, b, d, prec, setting, "first step with a non-finite state", None, "CRASHED", err))
        elif first is None:
            rows.append(row(name, b, d, prec, setting, "first step with a non-finite state", None,
                            f"no Inf/NaN within {smax} steps", f"NumPy {prec} emulation: step {pred}"))
        else:
            same = "= NumPy emulation" if first == pred else f"NumPy emulation says {pred}"
            rows.append(row(name, b, d, prec, setting, "first step with a non-finite state", first,
                            f"unstable, reported: Inf/NaN from step {first} ({same}), no crash",
                            f"located with {len(calls)} cells at steps {calls}"))
    return rows, {}


def exp_particles_divergence(ctx: Ctx) -> Result:
    """float32 vs float64 along whole trajectories; collision-timing flips between precisions and
    between backends. bounce 0.82 (the seed) settles within ~10 s; 0.99 keeps bouncing."""
    name, n = "particles-divergence", 256
    steps = 1000 if ctx.quick else 5000
    bounces = (0.99,) if ctx.quick else (0.82, 0.99)
    rows, series = ctx.skip_rows(name), {}
    for bounce in bounces:
        r, s = divergence_for(ctx, name, {"n": n, "steps": steps, "record_every": 1, "bounce": bounce})
        rows += r
        series.update({f"{k}/bounce={bounce:g}": v for k, v in s.items()})
    return rows, series


def divergence_for(ctx: Ctx, name: str, prm: dict[str, Any]) -> Result:
    n, steps = prm["n"], prm["steps"]
    refs = {}
    for prec in ("float32", "float64"):
        sc, p, inp = particle_inputs(prm, prec)
        ref = sc.oracle(p, inp)
        refs[prec] = (ref, contacts(ref["traj_x"][1:], ref["traj_y"][1:], float(inp["radius"]), np.float64),
                      float(inp["radius"]))
    specs = [spec("particles", b, d, prec, prm) for b, d, _ in ctx.targets() for prec in ("float32", "float64")]
    res = dict(zip([(s["backend"], s["device"], s["precision"]) for s in specs], run_cells(ctx, specs)))
    rows, series = [], {}
    setting = f"bounce={prm['bounce']:g}, n={n}, steps={steps}"
    flags: dict[tuple[str, str, str], np.ndarray] = {}
    for (b, d, prec), (rec, out) in res.items():
        if rec["status"] == "error" or out is None or "traj_x" not in out:
            rows.append(row(name, b, d, prec, setting, "cell", None, "error", rec.get("reason", "no trajectory")))
            continue
        ref, cref, radius = refs[prec]
        dtype = np.float32 if prec == "float32" else np.float64
        flags[(b, d, prec)] = c = contacts(out["traj_x"][1:], out["traj_y"][1:], radius, dtype)
        flips = first_flips(c, cref)
        ill = ref["ill_conditioned"]
        bad = int(np.sum((flips >= 0) & ~ill))
        nflip = int(np.sum(flips >= 0))
        rows.append(row(name, b, d, prec, setting, "particles whose contact timing flips vs float64 oracle (same inputs)",
                        nflip, "no flips" if nflip == 0 else
                        "all flips in derived ill-conditioned particles" if bad == 0 else
                        f"{bad} FLIPS IN WELL-CONDITIONED particles (rounding beyond the bound)",
                        f"{int(ill.sum())} particles ill-conditioned; first flip at step "
                        f"{int(flips[flips >= 0].min()) + 1 if nflip else '-'}"))
    for b, d, _ in ctx.targets():
        r32, r64 = res.get((b, d, "float32")), res.get((b, d, "float64"))
        if (b, d, "float32") not in flags or (b, d, "float64") not in flags:
            continue
        o32, o64 = r32[1], r64[1]
        with np.errstate(invalid="ignore"):
            dpos = np.maximum(np.abs(o32["traj_x"].astype(np.float64) - o64["traj_x"]),
                              np.abs(o32["traj_y"].astype(np.float64) - o64["traj_y"]))
        med, mx = np.median(dpos, axis=1), np.max(dpos, axis=1)
        radius = refs["float64"][2]
        over = np.nonzero(med > radius)[0]
        flips = first_flips(flags[(b, d, "float32")], flags[(b, d, "float64")])
        nflip = int(np.sum(flips >= 0))
        rows.append(row(name, b, d, "float32 vs float64", setting, "max |pos32 - pos64| at the last step",
                        float(mx[-1]), f"DECORRELATED: median particle off by > radius from step {int(over[0])}"
                        if over.size else "median particle stays within one radius",
                        f"median {float(med[-1]):.3g} m; {nflip} of {n} particles' contact timing flips "
                        f"(first at step {int(flips[flips >= 0].min()) + 1 if nflip else '-'})"))
        idx = np.unique(np.geomspace(1, steps, 300).astype(int))
        series[f"{b}/{d}"] = {"step": idx.tolist(), "median": med[idx].tolist(), "max": mx[idx].tolist()}
    ref_name = backends.reference()
    for (b, d, prec), c in flags.items():
        if b == ref_name or (ref_name, d, prec) not in flags:
            continue
        flips = first_flips(c, flags[(ref_name, d, prec)])
        ill = refs[prec][0]["ill_conditioned"]
        nflip, bad = int(np.sum(flips >= 0)), int(np.sum((flips >= 0) & ~ill))
        same = bitwise_differences({k: res[(b, d, prec)][1][k] for k in ("traj_x", "traj_y")},
                                   {k: res[(ref_name, d, prec)][1][k] for k in ("traj_x", "traj_y")})
        verdict = ("bitwise identical trajectory" if same == 0 else
                   "same contact timing, trajectories differ in rounding" if nflip == 0 else
                   "flips only in derived ill-conditioned particles" if bad == 0 else
                   f"{bad} FLIPS IN WELL-CONDITIONED particles")
        rows.append(row(name, b, d, prec, setting, f"particles whose contact timing flips vs {ref_name}", nflip,
                        verdict, f"{same} trajectory values differ bitwise from {ref_name}"))
    return rows, series


def lr_grid(ctx: Ctx) -> tuple[float, ...]:
    return (0.01, 0.045, 0.055, 0.08, 0.2) if ctx.quick else \
        (0.001, 0.005, 0.01, 0.02, 0.04, 0.045, 0.055, 0.08, 0.2, 1.0)


def predicted_lr(contact: str, iters: int) -> tuple[float, dict[str, float]]:
    """2/lambda_max of the float64 loss Hessian where descent at the seed's lr = 0.01 ends (local
    stability of gradient descent), and at v0; for 'none' also the closed form 1/(N dt)^2."""
    sc = scenarios.get("projectile")
    p = sc.params({"contact": contact, "iters": 0})
    inp = sc.inputs(p, "float64")
    c = {k: float(inp[k]) for k in P.CONSTANTS}
    hist, v_end = stress_tasks.optimise(stress_tasks.oracle_evaluator({"contact": contact}),
                                        inp["v0"], 0.01, iters, "gd")
    lam = {}
    for where, v in (("v0", inp["v0"].astype(np.float64)), ("v_end", v_end)):
        lam[where] = float(np.max(np.linalg.eigvalsh(P.hessian(c, contact, p.steps, v)))) if np.all(np.isfinite(v)) else math.nan
    info = {f"lambda_max({k})": val for k, val in lam.items()}
    if contact == "none":
        info["closed form 1/(N dt)^2"] = 1.0 / (p.steps * c["dt"]) ** 2
    lam_end = lam["v_end"] if math.isfinite(lam["v_end"]) else lam["v0"]
    return (2.0 / lam_end if lam_end > 0 else math.inf), info


def exp_projectile_lr(ctx: Ctx) -> Result:
    """Learning-rate sweep x contact x optimiser, classified; observed boundary vs 2/lambda_max."""
    name = "projectile-lr"
    lrs, contacts_ = lr_grid(ctx), ("none", "hard", "soft")
    iters = scenarios.get("projectile").params({}, quick=ctx.quick).iters
    budget = 60.0 if ctx.quick else 300.0
    rows, series = ctx.skip_rows(name), {"lrs": list(lrs), "histories": {}}
    pred = {c: predicted_lr(c, iters) for c in contacts_}
    for c, (lr_star, info) in pred.items():
        rows.append(row(name, "physics", "host", "float64", f"contact={c}", "predicted GD boundary lr* = 2/lambda_max(H)",
                        lr_star, f"GD locally stable iff lr < {lr_star:.3g}",
                        "; ".join(f"{k} = {v:.4g}" for k, v in info.items()) + " (H: float64 Hessian)"))
    # gradient descent: the backends' own device-side loop (one cell each, float32)
    specs = [spec("projectile", b, d, "float32", {"contact": c, "lr": lr, "iters": iters})
             for b, d, _ in ctx.targets() for c in contacts_ for lr in lrs]
    runs: list[tuple[str, str, str, str, str, float, list[float] | None, str]] = []
    for s, (rec, out) in zip(specs, run_cells(ctx, specs)):
        h = None if out is None else np.asarray(out["loss_history"], np.float64).tolist()
        runs.append((s["backend"], s["device"], "float32", "gd", s["params"]["contact"], s["params"]["lr"], h,
                     "" if h is not None else rec.get("reason", "?")))
    # clipping and Adam: host loop (compare.stress_tasks); the float64 oracle runs all three
    tasks = [({"kind": "optimise", "backend": b, "device": d, "precision": "float32", "contacts": list(contacts_),
               "lrs": list(lrs), "methods": ["clip", "adam"], "iters": iters, "budget_s": budget})
             for b, d, _ in ctx.targets()]
    results = pool_map(ctx, lambda t: stress_tasks.run(t, timeout=ctx.timeout), tasks)
    results.append(stress_tasks.run_task({"kind": "optimise", "backend": "oracle64", "device": "host",
                                          "precision": "float64", "contacts": list(contacts_), "lrs": list(lrs),
                                          "methods": list(stress_tasks.OPTIMISERS), "iters": iters,
                                          "budget_s": math.inf}))
    tasks.append({"backend": "oracle64", "device": "host", "precision": "float64"})
    for t, res in zip(tasks, results):
        if "results" not in res:
            why = res.get("skipped") or res.get("error")
            rows.append(row(name, t["backend"], t["device"], t["precision"], "clip, adam (host loop)", "-", None,
                            "skipped" if "skipped" in res else "error", why))
            continue
        for r in res["results"]:
            runs.append((t["backend"], t["device"], t["precision"], r["method"], r["contact"], r["lr"], r["history"], ""))
    groups: dict[tuple, list] = {}
    for b, d, prec, m, c, lr, h, why in runs:
        setting = f"{m}, contact={c}, lr={lr:g}, iters={iters}"
        if h is None:
            rows.append(row(name, b, d, prec, setting, "loss[end]/loss[0]", None, "error", why)); continue
        cls = classify(h)
        ratio = h[-1] / h[0] if math.isfinite(h[-1]) and h[0] > 0 else math.inf
        rows.append(row(name, b, d, prec, setting, "loss[end]/loss[0]", ratio, cls,
                        f"loss[0] = {h[0]:.4g}" + ("" if m != "clip" else f"; clip |g| <= {stress_tasks.CLIP_NORM:g}")
                        + ("" if m != "adam" else "; Adam b1 0.9, b2 0.999")))
        groups.setdefault((b, d, prec, m, c), []).append((lr, cls))
        if b in (backends.reference(), "oracle64") and lr in SEED_LRS:
            series["histories"][f"{b}/{d}/{m}/{c}/{lr:g}"] = h
    for (b, d, prec, m, c), pts in groups.items():
        lrs_, cls_ = [p[0] for p in pts], [p[1] for p in pts]
        stable, first_div = observed_boundary(lrs_, cls_)
        lr_star = pred[c][0]
        if first_div is None:
            verdict = f"no divergence up to lr = {max(lrs_):g}" + (" (bounded steps)" if m != "gd" else "")
        elif m != "gd":
            verdict = f"diverges from lr = {first_div:g}"
        elif (stable is None or stable < lr_star) and lr_star <= first_div:
            verdict = f"agrees with predicted lr* = {lr_star:.3g}"
        else:
            verdict = f"DISAGREES with predicted lr* = {lr_star:.3g}"
        monotone = all(not (c1 == "diverged" and c2 != "diverged") for (_, c1), (_, c2) in
                       zip(sorted(pts), sorted(pts)[1:]))
        rows.append(row(name, b, d, prec, f"{m}, contact={c}", "observed boundary: first diverging lr", first_div,
                        verdict, f"largest lr below it: {stable}; " + ("" if monotone else "NON-MONOTONE in lr; ")
                        + " ".join(f"{lr:g}:{cl[0].upper()}" for lr, cl in sorted(pts))))
    return rows, series


FD_STEPS = tuple(10.0 ** (e / 2) for e in range(2, -17, -1))     # 10 ... 1e-8, half decades


def fd_gradient(c: dict[str, float], contact: str, steps: int, v: np.ndarray, h: float) -> np.ndarray:
    def loss(w):
        (x, y, _, _), _ = P.rollout(c, contact, steps, float(w[0]), float(w[1]))
        return (x - c["target_x"]) ** 2 + (y - c["target_y"]) ** 2
    return np.array([(loss(v + h * e) - loss(v - h * e)) / (2 * h) for e in np.eye(2)])


def exp_projectile_gradient(ctx: Ctx) -> Result:
    """Gradient quality (none / hard / soft) against float64 central differences over FD steps, and
    along a line of launch velocities at two spacings (loss jumps vs stiff curvature)."""
    name = "projectile-gradient"
    contacts_ = ("none", "hard", "soft")
    sc = scenarios.get("projectile")
    fd, gsize = {}, {}
    for prec in ("float32", "float64"):
        for c in contacts_:
            p = sc.params({"contact": c, "iters": 0})
            inp = sc.inputs(p, prec)
            cc = {k: float(inp[k]) for k in P.CONSTANTS}
            v = inp["v0"].astype(np.float64)
            fd[(prec, c)] = [fd_gradient(cc, c, p.steps, v, h) for h in FD_STEPS]
            gsize[c] = float(np.linalg.norm(P.gradient(cc, c, p.steps, v)))
    specs = [spec("projectile", b, d, prec, {"contact": c, "iters": 0}) for b, d, _ in ctx.targets()
             for prec in (("float32",) if ctx.quick else ("float32", "float64")) for c in contacts_]
    rows, series = ctx.skip_rows(name), {"h": list(FD_STEPS), "lines": {}, "scans": {}}
    step_len = {c: 0.01 * gsize[c] for c in contacts_}       # one GD step at the seed's lr = 0.01
    for s, (rec, out) in zip(specs, run_cells(ctx, specs)):
        c, prec = s["params"]["contact"], s["precision"]
        setting = f"contact={c}, v0=(2, 6.5)"
        if rec["status"] == "error" or out is None:
            rows.append(error_row(name, s, setting, rec)); continue
        g = np.asarray(out["grad"], np.float64)
        gr = rec.get("gradient") or {}
        rows.append(row(name, s["backend"], s["device"], prec, setting,
                        f"gradient rel. error vs {gr.get('reference', 'oracle')}", gr.get("vs_oracle_rel"),
                        "within derived bound" if rec["status"] == "ok" else "EXCEEDS derived bound",
                        f"gradient {np.array2string(g, precision=5)}"))
        rel = [float(np.max(np.abs(g - f)) / max(float(np.max(np.abs(g))), 1e-300)) for f in fd[(prec, c)]]
        series["lines"][f"{label(s)}/{prec}/{c}"] = rel
        h_star = None                 # largest h such that every h' <= h agrees within FD_AGREE
        for h, r in sorted(zip(FD_STEPS, rel)):
            if r > FD_AGREE:
                break
            h_star = h
        step = step_len[c]
        verdict = ("agrees with FD at no step" if h_star is None else
                   f"valid over a GD step (h* >= lr|g| = {step:.3g})" if h_star >= step else
                   f"VALID ONLY FOR h <= {h_star:.2g}, one GD step at lr 0.01 is {step:.3g}")
        rows.append(row(name, s["backend"], s["device"], prec, setting,
                        "largest FD step h* with |g - g_FD(h)| <= 1% |g| (all smaller h too)", h_star, verdict,
                        "rel. discrepancy at h = 1e-1, 1e-2, 1e-3: " +
                        ", ".join(f"{rel[FD_STEPS.index(h)]:.2g}" for h in (10.0 ** -1, 10.0 ** -2, 10.0 ** -3)
                                  if h in FD_STEPS)))
    # scans along vy0 at two spacings: mispredictions that persist at the finer one are jumps;
    # differences below the derived loss rounding bound (relative, at v0) cannot be told apart
    loss_noise = {}
    for prec in ("float32", "float64"):
        for c in ("hard", "soft"):
            p = sc.params({"contact": c, "iters": 0})
            ref = sc.oracle(p, sc.inputs(p, prec))
            loss_noise[(prec, c)] = float(ref["tol_loss"][0] / abs(ref["loss"]))
    npts = 41 if ctx.quick else 81
    scans = {"coarse": np.linspace(6.3, 6.7, npts).tolist(), "fine": np.linspace(6.48, 6.52, npts).tolist()}
    budget = 60.0 if ctx.quick else 300.0
    tasks = [{"kind": "scan", "backend": b, "device": d, "precision": "float32", "contacts": ["hard", "soft"],
              "scans": scans, "budget_s": budget} for b, d, _ in ctx.targets()]
    results = pool_map(ctx, lambda t: stress_tasks.run(t, timeout=ctx.timeout), tasks)
    tasks.append({"kind": "scan", "backend": "oracle64", "device": "host", "precision": "float64",
                  "contacts": ["hard", "soft"], "scans": scans, "budget_s": math.inf})
    results.append(stress_tasks.run_task(tasks[-1]))
    for t, res in zip(tasks, results):
        if "results" not in res:
            rows.append(row(name, t["backend"], t["device"], t["precision"], "vy0 scans (host loop)", "-", None,
                            "skipped" if "skipped" in res else "error", res.get("skipped") or res.get("error")))
            continue
        per = {(r["contact"], r["scan"]): r for r in res["results"]}
        for c in ("hard", "soft"):
            k = {sc_: loss_mispredictions(per[(c, sc_)]["vy"], per[(c, sc_)]["loss"], per[(c, sc_)]["grad"],
                                          loss_noise[(t["precision"], c)]) for sc_ in scans}
            spacing = {sc_: scans[sc_][1] - scans[sc_][0] for sc_ in scans}
            verdict = ("gradient predicts the loss along the scan" if k["coarse"][0] == 0 else
                       "smooth but stiff: mispredictions vanish at 10x finer spacing" if k["fine"][0] == 0 else
                       "LOSS JUMPS: mispredictions persist at 10x finer spacing")
            rows.append(row(name, t["backend"], t["device"], t["precision"], f"contact={c}, vy0 scan",
                            "intervals where the gradient mispredicts the loss change (coarse)", k["coarse"][0],
                            verdict, "; ".join(
                                f"{sc_}: {k[sc_][0]}/{npts - 1} at dvy = {spacing[sc_]:.3g} "
                                f"(+{k[sc_][1]} below the loss rounding {loss_noise[(t['precision'], c)]:.2g}|L|)"
                                for sc_ in scans)))
            if t["backend"] in (backends.reference(), "oracle64"):
                series["scans"][f"{t['backend']}/{t['device']}/{c}"] = {
                    "vy": per[(c, "coarse")]["vy"], "loss": per[(c, "coarse")]["loss"],
                    "dvy": [g[1] for g in per[(c, "coarse")]["grad"]]}
    series["gd_step"] = step_len
    return rows, series


def exp_projectile_horizon(ctx: Ctx) -> Result:
    """Horizon (steps) sweep: gradient size and float32 gradient error as the rollout lengthens."""
    name = "projectile-horizon"
    horizons = (90, 180, 720) if ctx.quick else (45, 90, 180, 360, 720, 1440)
    contacts_ = ("none", "hard", "soft")
    specs = [spec("projectile", b, d, "float32", {"contact": c, "steps": n, "iters": 0})
             for b, d, _ in ctx.targets() for c in contacts_ for n in horizons]
    rows, series = ctx.skip_rows(name), {}
    acc: dict[tuple[str, str, str], list] = {}
    for s, (rec, out) in zip(specs, run_cells(ctx, specs)):
        c, n = s["params"]["contact"], s["params"]["steps"]
        setting = f"contact={c}, steps={n}"
        if rec["status"] == "error" or out is None:
            rows.append(error_row(name, s, setting, rec)); continue
        gr = rec.get("gradient") or {}
        g = float(np.linalg.norm(np.asarray(out["grad"], np.float64)))
        ok = rec["status"] == "ok"
        rows.append(row(name, s["backend"], s["device"], "float32", setting, "gradient rel. error vs float64",
                        gr.get("vs_oracle_rel"), "within derived bound" if ok else "EXCEEDS derived bound",
                        f"|grad| = {g:.4g}; error/bound = {fmt_num(rec['error']['vs_oracle'])}"))
        acc.setdefault((s["backend"], s["device"], c), []).append((n, g, gr.get("vs_oracle_rel"), ok))
    for (b, d, c), pts in acc.items():
        pts.sort()
        ns = np.array([p[0] for p in pts], float); gs = np.array([p[1] for p in pts], float)
        good = (gs > 0) & np.isfinite(gs)
        slope = float(np.polyfit(np.log(ns[good]), np.log(gs[good]), 1)[0]) if good.sum() >= 2 else math.nan
        all_ok = all(p[3] for p in pts)
        rel = [p[2] for p in pts]
        worst = max(((r, n_) for n_, r in zip(ns, rel) if isinstance(r, (int, float))), default=(math.nan, 0))
        rows.append(row(name, b, d, "float32", f"contact={c}, steps {int(ns[0])}..{int(ns[-1])}",
                        "|grad| growth exponent p (|grad| ~ steps^p, least squares)", slope,
                        ("within derived bound at every horizon" if all_ok else "EXCEEDS derived bound at some horizon")
                        + (f"; float32 gradient OFF BY {worst[0]:.0%} at steps={int(worst[1])} (ill-conditioned)"
                           if worst[0] > FD_AGREE else ""),
                        f"|grad| x{gs[-1] / gs[0]:.3g} from {int(ns[0])} to {int(ns[-1])} steps; rel. error: "
                        + ", ".join(f"{int(n_)}:{fmt_num(r)}" for n_, r in zip(ns, rel))))
        series[f"{b}/{d}/{c}"] = {"steps": ns.tolist(), "grad": gs.tolist(), "rel": rel}
    return rows, series


def exp_ulps(ctx: Ctx) -> Result:
    """float32 error distributions in ulps (saxpy, sdf), every variant (fast-math)."""
    name = "ulps"
    n = 100_003 if ctx.quick else 1_000_000
    cases = [("sdf", {"width": 512, "height": 512}, "image"),
             ("saxpy", {"n": n, "inputs": "linspace"}, "out"),
             ("saxpy", {"n": n, "inputs": "random", "seed": 3}, "out")]
    specs = [spec(scn, b, d, "float32", prm, v) for b, d, v in ctx.targets(variants=True) for scn, prm, _ in cases]
    refs = {}
    for scn, prm, key in cases:
        sc = scenarios.get(scn)
        p = sc.params(prm)
        refs[(scn, json.dumps(prm))] = sc.oracle(p, sc.inputs(p, "float32"))[key]
    results = run_cells(ctx, specs)
    rows, series = ctx.skip_rows(name), {}
    defaults = {}
    for s, (rec, out) in zip(specs, results):
        if s["variant"] == "default" and out is not None:
            defaults[(s["backend"], s["device"], s["scenario"], json.dumps(s["params"]))] = out
    for s, (rec, out) in zip(specs, results):
        scn, prm = s["scenario"], s["params"]
        key = next(k for sc_, p_, k in cases if sc_ == scn and p_ == prm)
        setting = scn + ("" if scn == "sdf" else f" ({prm['inputs']})") + (f", variant={s['variant']}")
        if rec["status"] == "error" or out is None:
            rows.append(error_row(name, s, setting, rec)); continue
        e = ulps(out[key], refs[(scn, json.dumps(prm))]).ravel()
        finite = np.isfinite(e)
        ok = rec["status"] == "ok"
        q = np.percentile(e[finite], [50, 99]) if finite.any() else [math.nan, math.nan]
        rows.append(row(name, s["backend"], s["device"], "float32", setting, "max error [ulps of the result]",
                        float(np.max(e)) if finite.all() else math.inf,
                        "within derived bound" if ok else "EXCEEDS derived bound",
                        f"median {q[0]:.3g}, p99 {q[1]:.3g} ulps; {100 * np.mean(e > 0.5):.3g}% not correctly "
                        f"rounded; scenario metric {fmt_num(rec['error']['vs_oracle'])} (bound {fmt_num(rec['error']['tolerance'])})"))
        if scn == "sdf":
            srt = np.sort(e[finite])
            idx = np.unique(np.geomspace(1, srt.size, 200).astype(int)) - 1
            series[f"{label(s)}"] = {"ulps": srt[idx].tolist(), "frac": ((idx + 1) / srt.size).tolist()}
        if s["variant"] != "default":
            base = defaults.get((s["backend"], s["device"], scn, json.dumps(prm)))
            if base is None:
                continue
            diff = bitwise_differences({key: out[key]}, {key: base[key]})
            change = ulps(out[key], base[key].astype(np.float64))
            rows.append(row(name, s["backend"], s["device"], "float32", setting, "elements changed by the variant",
                            diff, "bitwise identical to default" if diff == 0 else
                            f"changes results (max {float(np.max(change)):.3g} ulps); "
                            + ("still within derived bound" if ok else "EXCEEDS derived bound"),
                            f"of {out[key].size}"))
    return rows, series


def exp_races(ctx: Ctx) -> Result:
    """Every cell twice (bitwise), CPU against GPU, and the racy one-launch control kernel."""
    name = "races"
    precisions = ("float32",) if ctx.quick else ("float32", "float64")
    cases = [(scn, scenarios.get(scn).params({}, quick=True)) for scn in ("saxpy", "sdf", "particles", "projectile")]
    specs = []
    for b, d, _ in ctx.targets():
        for scn, p in cases:
            for prec in precisions:
                prm = {k: getattr(p, k) for k in scenarios.get(scn).quick}
                specs += [spec(scn, b, d, prec, prm)] * 2
    ref_name = backends.reference()
    control = []
    if ref_name in ctx.backends:
        prm = {k: getattr(cases[2][1], k) for k in scenarios.get("particles").quick}
        control = [spec("particles", ref_name, d, "float32", prm, RACY) for d in ctx.devices
                   if not ctx.why_not(ref_name, d)]
        specs += [s for s in control for _ in range(2)]
    results = run_cells(ctx, specs)
    rows, first_run = ctx.skip_rows(name), {}
    for i in range(0, len(specs), 2):
        s = specs[i]
        (ra, oa), (rb, ob) = results[i], results[i + 1]
        setting = f"{s['scenario']} (quick sizes)" + ("" if s["variant"] == "default" else f", variant={s['variant']}")
        if oa is None or ob is None:
            rows.append(error_row(name, s, setting, ra if oa is None else rb)); continue
        diff = bitwise_differences(oa, ob)
        if s["variant"] == RACY:
            verdict = race_verdict(s["device"], diff, (ra["status"] == "ok", rb["status"] == "ok"))
            rows.append(row(name, s["backend"], s["device"], s["precision"], setting,
                            "elements differing between two runs", diff, verdict,
                            f"error vs oracle {fmt_num(ra['error']['vs_oracle'])} and {fmt_num(rb['error']['vs_oracle'])} "
                            f"(bound {fmt_num(ra['error']['tolerance'])}); control: one launch over steps x n"))
            continue
        first_run[(s["scenario"], s["backend"], s["device"], s["precision"])] = (ra, oa)
        rows.append(row(name, s["backend"], s["device"], s["precision"], setting,
                        "elements differing between two runs", diff,
                        "bitwise reproducible" if diff == 0 else "NONDETERMINISTIC between runs",
                        f"of {sum(int(np.size(v)) for v in oa.values())} output values"))
    if {"cpu", "cuda"} <= set(ctx.devices):
        for (scn, b, d, prec), (ra, oa) in first_run.items():
            if d != "cpu" or (scn, b, "cuda", prec) not in first_run:
                continue
            rg, og = first_run[(scn, b, "cuda", prec)]
            diff = bitwise_differences(oa, og)
            sc = scenarios.get(scn)
            p = sc.params(ra["params"])
            dist = sc.distance(p, sc.inputs(p, prec), og, oa)
            both = ra["status"] == "ok" and rg["status"] == "ok"
            rows.append(row(name, b, "cpu vs cuda", prec, f"{scn} (quick sizes)", "scenario distance cpu vs cuda",
                            dist, "bitwise identical" if diff == 0 else
                            ("differ, both within derived bound" if both else "DIFFER, one outside its bound"),
                            f"{diff} values differ bitwise"))
    return rows, {}


EXPERIMENTS: dict[str, tuple[Callable[[Ctx], Result], str]] = {
    "particles-dt": (exp_particles_dt, "dt sweep at fixed simulated time"),
    "particles-long": (exp_particles_long, "long rollouts: energy bound (bounce < 1), growth (bounce > 1)"),
    "particles-inf": (exp_particles_inf, "first non-finite step (bounce = 1.05)"),
    "particles-divergence": (exp_particles_divergence, "float32 vs float64 over time, collision-timing flips"),
    "projectile-lr": (exp_projectile_lr, "learning-rate sweep x contact x optimiser"),
    "projectile-gradient": (exp_projectile_gradient, "gradient quality: hard vs soft vs finite differences"),
    "projectile-horizon": (exp_projectile_horizon, "horizon sweep: gradient growth"),
    "ulps": (exp_ulps, "float32 error distributions in ulps, fast-math"),
    "races": (exp_races, "run-to-run, CPU vs GPU, racy control kernel"),
}


# ---------------------------------------------------------------------------------------------
# Plots (from the series kept in stress.json, so merged runs redraw them)

def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _style(lbl: str) -> dict[str, Any]:
    """One colour per backend and one marker per device, in every plot."""
    b = lbl.split("/", 1)[0]
    order = list(backends.ORDER) + ["oracle64"]
    color = f"C{order.index(b)}" if b in order else "k"
    return {"color": color, "marker": "^" if "/cuda" in lbl else "o", "markersize": 4}


def _floor(xs: Iterable[Any], eps: float = 1e-18) -> list[float]:
    return [max(float(x), eps) if isinstance(x, (int, float)) and math.isfinite(x) else math.nan for x in xs]


def plot_particles_dt(series: dict[str, Any], path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for lbl, line in sorted(series["lines"].items()):
        ax.plot(line["dt"], _floor(line["median"]), ls="-" if "float32" in lbl else ":", label=lbl, lw=1, **_style(lbl))
    ax.plot(series["dt"], _floor(series["discretisation"]), "k-", lw=2.5, label="discretisation (float64)")
    ax.set_xscale("log"); ax.set_yscale("log"); ax.invert_xaxis()
    ax.set_xlabel("dt [s] (T = 3 s fixed)"); ax.set_ylabel("median |state error| over particles")
    ax.set_title("float32 rounding vs time discretisation (float64: max error, 0 drawn at 1e-18)", fontsize=8)
    ax.legend(fontsize=6); ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout(); fig.savefig(path, dpi=110); plt.close(fig)


def plot_particles_long(series: dict[str, Any], path: Path) -> None:
    plt = _plt()
    bounces = sorted({float(k.rsplit("bounce=", 1)[1]) for k in series})
    fig, axes = plt.subplots(1, len(bounces), figsize=(5.2 * len(bounces), 4.2), squeeze=False)
    for key, s in sorted(series.items()):
        ax = axes[0][bounces.index(float(key.rsplit("bounce=", 1)[1]))]
        ax.plot(s["steps"], _floor(s["ratio"]), ls="-" if "float32" in key else ":",
                label=key.rsplit("/bounce", 1)[0], lw=1, **_style(key))
    for ax, b in zip(axes[0], bounces):
        ax.set_title(f"bounce {b:g}: " + ("must not gain energy" if b < 1 else "unstable (gaps: non-finite)"))
        finite = any(np.isfinite(y).any() for line in ax.lines for y in [np.asarray(line.get_ydata(), float)])
        if not finite:
            ax.text(0.5, 0.5, "non-finite energy at every length", ha="center", transform=ax.transAxes)
        ax.set_xscale("log"); ax.set_yscale("log" if finite else "linear"); ax.grid(True, which="both", alpha=0.3)
        ax.set_xlabel("steps (dt = 0.01)"); ax.set_ylabel("total E(T) / E(0)"); ax.legend(fontsize=6)
    fig.tight_layout(); fig.savefig(path, dpi=110); plt.close(fig)


def plot_particles_divergence(series: dict[str, Any], path: Path) -> None:
    plt = _plt()
    bounces = sorted({k.rsplit("bounce=", 1)[1] for k in series}, key=float)
    fig, axes = plt.subplots(1, len(bounces), figsize=(6 * len(bounces), 4.5), squeeze=False)
    for lbl, s in sorted(series.items()):
        ax = axes[0][bounces.index(lbl.rsplit("bounce=", 1)[1])]
        name = lbl.rsplit("/bounce", 1)[0]
        st = {**_style(lbl), "marker": None}
        ax.plot(s["step"], _floor(s["median"]), label=f"{name} median", **st)
        ax.plot(s["step"], _floor(s["max"]), ls=":", label=f"{name} max", **st)
    for ax, b in zip(axes[0], bounces):
        ax.axhline(0.03, color="k", lw=0.8, ls="--", label="radius")
        ax.set_xscale("log"); ax.set_yscale("log"); ax.grid(True, which="both", alpha=0.3)
        ax.set_title(f"bounce {b}: float32 vs float64 port (0 drawn at 1e-18)", fontsize=9)
        ax.set_xlabel("step"); ax.set_ylabel("|pos float32 - pos float64| over particles [m]")
        ax.legend(fontsize=6)
    fig.tight_layout(); fig.savefig(path, dpi=110); plt.close(fig)


def plot_projectile_lr(series: dict[str, Any], path: Path) -> None:
    plt = _plt()
    hist = series.get("histories", {})
    methods, contacts_ = ("gd", "clip", "adam"), ("none", "hard", "soft")
    fig, axes = plt.subplots(3, 3, figsize=(12, 9), sharex=True)
    for key, h in sorted(hist.items()):
        b, d, m, c, lr = key.split("/")
        ax = axes[methods.index(m)][contacts_.index(c)]
        ax.plot(range(len(h)), _floor(h, 1e-30), ls="-" if b != "oracle64" else ":", lw=1, label=f"{b} lr={lr}")
    for i, m in enumerate(methods):
        for j, c in enumerate(contacts_):
            ax = axes[i][j]
            ax.set_yscale("log"); ax.set_title(f"{m}, contact={c}", fontsize=9); ax.grid(True, alpha=0.3)
            if ax.lines:
                ax.legend(fontsize=5)
    for ax in axes[-1]:
        ax.set_xlabel("iteration")
    fig.tight_layout(); fig.savefig(path, dpi=100); plt.close(fig)


def plot_projectile_gradient(series: dict[str, Any], path: Path) -> None:
    plt = _plt()
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5))
    for j, c in enumerate(("none", "hard", "soft")):
        ax = axes[0][j]
        for lbl, rel in sorted(series["lines"].items()):
            if lbl.endswith("/" + c):
                ax.plot(series["h"], _floor(rel), lw=1, ls="-" if "float32" in lbl else ":",
                        label=lbl.rsplit("/", 1)[0], **_style(lbl))
        ax.axhline(FD_AGREE, color="k", ls="--", lw=0.8)
        if c in series.get("gd_step", {}):
            ax.axvline(series["gd_step"][c], color="r", lw=0.8, label="one GD step at lr 0.01")
        ax.set_xscale("log"); ax.set_yscale("log"); ax.set_title(f"contact={c}: |g - g_FD(h)|/|g|", fontsize=9)
        ax.set_xlabel("FD step h"); ax.grid(True, which="both", alpha=0.3); ax.legend(fontsize=5)
    for j, c in enumerate(("hard", "soft")):
        ax = axes[1][j]
        for lbl, s in sorted(series["scans"].items()):
            if lbl.endswith("/" + c):
                ax.plot(s["vy"], s["loss"], lw=1, label=lbl.rsplit("/", 1)[0])
        ax.set_title(f"contact={c}: loss along vy0 (vx0 = 2)", fontsize=9); ax.set_xlabel("vy0"); ax.legend(fontsize=6)
        ax2 = axes[1][2]
        for lbl, s in sorted(series["scans"].items()):
            if lbl.endswith("/" + c):
                ax2.plot(s["vy"], s["dvy"], lw=1, ls="-" if c == "soft" else "--", label=f"{c} {lbl.rsplit('/', 1)[0]}")
        ax2.set_title("d loss / d vy0 along the scan (AD)", fontsize=9); ax2.set_xlabel("vy0"); ax2.legend(fontsize=6)
    fig.tight_layout(); fig.savefig(path, dpi=100); plt.close(fig)


def plot_projectile_horizon(series: dict[str, Any], path: Path) -> None:
    plt = _plt()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for lbl, s in sorted(series.items()):
        ls = {"none": "-", "hard": "--", "soft": ":"}[lbl.rsplit("/", 1)[1]]
        axes[0].plot(s["steps"], _floor(s["grad"]), ls=ls, lw=1, label=lbl, **_style(lbl))
        axes[1].plot(s["steps"], _floor(s["rel"]), ls=ls, lw=1, label=lbl, **_style(lbl))
    axes[0].set_ylabel("|grad| (float32)"); axes[1].set_ylabel("float32 gradient rel. error vs float64")
    for ax in axes:
        ax.set_xscale("log"); ax.set_yscale("log"); ax.set_xlabel("steps (dt = 0.025)")
        ax.grid(True, which="both", alpha=0.3); ax.legend(fontsize=5)
    fig.tight_layout(); fig.savefig(path, dpi=110); plt.close(fig)


def plot_ulps(series: dict[str, Any], path: Path) -> None:
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for lbl, s in sorted(series.items()):
        ax.plot(_floor(s["ulps"], 1e-3), s["frac"], lw=1, label=lbl, ls="--" if "fastmath" in lbl else "-",
                **{**_style(lbl), "marker": None})
    ax.set_xscale("log"); ax.set_xlabel("error [ulps of the correctly rounded pixel] (0 drawn at 1e-3)")
    ax.set_ylabel("fraction of pixels with error <= x"); ax.set_title("sdf 512x512, float32", fontsize=9)
    ax.grid(True, which="both", alpha=0.3); ax.legend(fontsize=6)
    fig.tight_layout(); fig.savefig(path, dpi=110); plt.close(fig)


PLOTS: dict[str, Callable[[dict[str, Any], Path], None]] = {
    "particles-dt": plot_particles_dt, "particles-long": plot_particles_long,
    "particles-divergence": plot_particles_divergence, "projectile-lr": plot_projectile_lr,
    "projectile-gradient": plot_projectile_gradient, "projectile-horizon": plot_projectile_horizon,
    "ulps": plot_ulps,
}


# ---------------------------------------------------------------------------------------------
# Reports

def fmt_value(v: Any) -> str:
    if isinstance(v, int) and not isinstance(v, bool):
        return str(v)
    if isinstance(v, float) and math.isfinite(v) and v != 0:
        return f"{v:.4g}"
    return fmt_num(v) if not isinstance(v, bool) else str(v)


def lr_matrix(rows: list[dict[str, Any]]) -> str:
    """projectile-lr as one line per (backend, device, optimiser, contact): C/S/D per lr."""
    from tabulate import tabulate
    cells_: dict[tuple, dict[float, str]] = {}
    lrs: set[float] = set()
    for r in rows:
        if r["experiment"] != "projectile-lr" or not r["setting"].count("lr="):
            continue
        parts = dict(p.split("=", 1) for p in r["setting"].split(", ")[1:])
        m = r["setting"].split(",", 1)[0]
        lr = float(parts["lr"]); lrs.add(lr)
        cells_.setdefault((r["backend"], r["device"], r["precision"], m, parts["contact"]), {})[lr] = \
            {"converged": "C", "stalled": "S", "diverged": "**D**"}.get(r["verdict"], "E")
    if not cells_:
        return ""
    cols = sorted(lrs)
    table = [[*k, *(v.get(lr, "") for lr in cols)] for k, v in cells_.items()]
    return tabulate(table, headers=["backend", "device", "precision", "optimiser", "contact",
                                    *[f"lr {lr:g}" for lr in cols]], tablefmt="github", disable_numparse=True)


def produced_by(data: dict[str, Any]) -> list[str]:
    """One line per run that produced rows: its command, when, and which experiments."""
    runs: dict[tuple, list[str]] = {}
    for e, r in provenance(data).items():
        runs.setdefault((r.get("command") or "?", r.get("created") or "?", r.get("git_commit") or "?"), []).append(e)
    lines = ["- produced by:" if len(runs) > 1 else "- produced by"]
    for (cmd, when, commit), exps in runs.items():
        lines.append(f"  - `{cmd}` ({when}, commit {commit or '?'}): {', '.join(exps)}")
    return lines


def markdown(data: dict[str, Any]) -> str:
    from tabulate import tabulate
    env = data.get("environment", {})
    lines = ["# Stress suite results", "",
             *produced_by(data), f"- host: {env.get('hostname', '?')}, "
             f"CPU {env.get('cpu', '?')}, GPUs: {', '.join(g.get('name', '?') for g in env.get('gpus', [])) or 'none'}",
             f"- Python {env.get('python', '?')}; " + ", ".join(f"{k} {v}" for k, v in env.get("packages", {}).items()),
             "- How each verdict is decided: docs/stress.md. Verdicts in CAPITALS flag a problem or a "
             "limit found; 'skipped' rows say why.", "", "## Verdicts per experiment", ""]
    counts: dict[str, dict[str, int]] = {}
    for r in data["rows"]:
        v = re.sub(r"(?<![\w.])\d[\d.e+-]*%?", "#", r["verdict"].split(" (")[0])    # numbers apart: one class
        counts.setdefault(r["experiment"], {}).setdefault(v, 0)
        counts[r["experiment"]][v] += 1
    lines += [f"- **{e}**: " + "; ".join(f"{v} x{k}" for v, k in c.items()) for e, c in counts.items()] + [""]
    for name, (_, title) in EXPERIMENTS.items():
        rows = [r for r in data["rows"] if r["experiment"] == name]
        if not rows:
            continue
        lines += [f"## {name}: {title}", ""]
        if (Path(data["_out"]) / f"{name}.png").exists():
            lines += [f"![{name}]({name}.png)", ""]
        if name == "projectile-lr":
            lines += ["C converged, S stalled, **D** diverged (GD: the backend's own device loop; "
                      "clip, adam: host loop with the backend's gradient; oracle64: float64 Python).", "",
                      lr_matrix(rows), ""]
            rows = [r for r in rows if "lr=" not in r["setting"]]
        table = [[r["backend"], r["device"], r["precision"], r["setting"], r["figure"], fmt_value(r["value"]),
                  r["verdict"], r["detail"]] for r in rows]
        lines += [tabulate(table, headers=COLUMNS[1:], tablefmt="github", disable_numparse=True), ""]
    return "\n".join(lines) + "\n"


def provenance(data: dict[str, Any]) -> dict[str, dict[str, Any]]:
    """experiment -> the run that produced its rows (command, time, commit): a results file
    assembled from several runs says which run each experiment came from."""
    if "provenance" in data:
        return data["provenance"]
    env = data.get("environment", {})
    run = {k: env.get(k) for k in ("command", "created", "git_commit")}
    if "merged_from" in env:      # an old merged file: its parts' commands were not kept
        run["command"] = f"merge of {len(env['merged_from'])} parts (commands not recorded)"
    return {r["experiment"]: run for r in data.get("rows", [])}


def write_outputs(out: Path, env: dict[str, Any], rows: list[dict[str, Any]], series: dict[str, Any],
                  ran: list[str], plots: bool = True,
                  prov: dict[str, dict[str, Any]] | None = None) -> dict[str, Any]:
    """Merge with an existing stress.json (experiments not run now are kept), write json, md, png."""
    from compare.worker import jsonable
    path = out / "stress.json"
    old_rows, old_series, old_prov = [], {}, {}
    if path.exists():
        try:
            old = json.loads(path.read_text())
            old_rows = [r for r in old.get("rows", []) if r["experiment"] not in ran]
            old_series = {k: v for k, v in old.get("series", {}).items() if k not in ran}
            old_prov = {k: v for k, v in provenance(old).items() if k not in ran}
        except (OSError, ValueError, KeyError):
            pass
    order = list(EXPERIMENTS)
    all_rows = sorted(old_rows + rows, key=lambda r: order.index(r["experiment"]) if r["experiment"] in order else 99)
    new_prov = prov if prov is not None else provenance({"environment": env, "rows": rows})
    prov = {**old_prov, **{e: v for e, v in new_prov.items() if e in ran}}
    data = {"environment": env, "provenance": prov, "rows": jsonable(all_rows),
            "series": jsonable({**old_series, **series})}
    atomic_write(path, json.dumps(data, indent=1))
    if plots:
        for name, s in data["series"].items():
            if name in PLOTS and s:
                try:
                    PLOTS[name](s, out / f"{name}.png")
                except Exception as exc:  # a plot must not lose the table
                    print(f"warning: plot {name} failed: {type(exc).__name__}: {exc}", file=sys.stderr)
    atomic_write(out / "stress.md", markdown({**data, "_out": str(out)}))
    return data


# ---------------------------------------------------------------------------------------------
# CLI

class UsageError(Exception):
    pass


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:
        raise UsageError(message)


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="python -m compare stress", description="numerical stability stress suite")
    p.add_argument("--backends", default=",".join(backends.BACKENDS))
    p.add_argument("--devices", default=",".join(backends.DEVICES))
    p.add_argument("--quick", action="store_true", help="smaller sweeps (a few minutes on 2 cores)")
    p.add_argument("--out", default="results/stress")
    p.add_argument("--only", default="", help="comma-separated: " + ",".join(EXPERIMENTS))
    p.add_argument("--jobs", type=int, default=min(8, os.cpu_count() or 1),
                   help="cells run at once (stress figures are not timings)")
    p.add_argument("--timeout", type=float, default=900.0, help="seconds before a cell is killed")
    p.add_argument("--no-plots", action="store_true")
    p.add_argument("--merge", nargs="+", metavar="STRESS_JSON", default=None,
                   help="run nothing: merge saved stress.json files (later ones win per experiment) into --out")
    return p


def merge(files: list[str], out: Path, plots: bool) -> int:
    """Rebuild DIR/stress.{json,md} and plots from parts run separately (e.g. one GPU call each)."""
    rows: list[dict[str, Any]] = []
    series: dict[str, Any] = {}
    envs = []
    prov: dict[str, dict[str, Any]] = {}
    for f in files:
        try:
            data = json.loads(Path(f).read_text())
            part_rows, part_series, env = data["rows"], data.get("series", {}), data["environment"]
        except (OSError, ValueError, KeyError) as exc:
            raise UsageError(f"cannot read stress results {f}: {exc}") from None
        ran = {r["experiment"] for r in part_rows}
        rows = [r for r in rows if r["experiment"] not in ran] + part_rows
        prov.update({e: v for e, v in provenance(data).items() if e in ran})
        series = {**{k: v for k, v in series.items() if k not in ran}, **part_series}
        envs.append(env)
    env = {**envs[-1], "merged_from": files}
    out.mkdir(parents=True, exist_ok=True)
    write_outputs(out, env, rows, series, sorted({r["experiment"] for r in rows}), plots=plots, prov=prov)
    print(f"merged {len(files)} files into {out / 'stress.json'} ({len(rows)} rows)", file=sys.stderr)
    return EXIT_OK


def split(value: str, allowed: Iterable[str], what: str) -> list[str]:
    allowed = list(allowed)
    items = [v.strip() for v in value.split(",") if v.strip()]
    if not items:
        raise UsageError(f"--{what} is empty (allowed: {', '.join(allowed)})")
    for v in items:
        if v not in allowed:
            raise UsageError(f"unknown {what.rstrip('s')} {v!r} (allowed: {', '.join(allowed)})")
    return items


def failure(r: dict[str, Any]) -> bool:
    """A row that makes the exit status 1: a cell that failed, or the racy control not flagged."""
    return r["verdict"] in ("error", "CRASHED") or r["verdict"].startswith("MISSED")


def main(argv: list[str]) -> int:
    try:
        args = build_parser().parse_args(argv)
        names = split(args.backends, backends.BACKENDS, "backends")
        devices = split(args.devices, backends.DEVICES, "devices")
        only = split(args.only, EXPERIMENTS, "only") if args.only else list(EXPERIMENTS)
        if args.jobs < 1:
            raise UsageError(f"--jobs must be >= 1, got {args.jobs}")
        if not args.timeout > 0:
            raise UsageError(f"--timeout must be > 0, got {args.timeout}")
        if args.merge:
            return merge(args.merge, Path(args.out), plots=not args.no_plots)
    except (UsageError, ParamError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    ref = backends.reference()
    names.sort(key=lambda n: n != ref)
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, len(names))) as pool:
        probes = dict(zip(names, pool.map(cells.probe, names)))
    ctx = Ctx(names, devices, args.quick, args.jobs, args.timeout, probes)
    env = environment.collect(["stress", *argv])
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = []
    series: dict[str, Any] = {}
    try:
        for name in only:
            t0 = time.perf_counter()
            print(f"stress: {name} ...", file=sys.stderr, flush=True)
            try:
                r, s = EXPERIMENTS[name][0](ctx)
            except Exception as exc:  # one broken experiment must not lose the others
                import traceback
                traceback.print_exc()
                r, s = [row(name, "-", "-", "-", "-", "experiment", None, "error",
                            f"{type(exc).__name__}: {exc}")], {}
            rows += r
            series[name] = s
            print(f"stress: {name} done in {time.perf_counter() - t0:.0f} s ({len(r)} rows)", file=sys.stderr, flush=True)
            write_outputs(out, env, rows, series, only[:only.index(name) + 1], plots=False)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    data = write_outputs(out, env, rows, series, only, plots=not args.no_plots)
    failed = [r for r in data["rows"] if r["experiment"] in only and failure(r)]
    print(f"wrote {out / 'stress.json'}, stress.md" + ("" if args.no_plots else ", *.png")
          + f": {len(rows)} rows, {len(failed)} failures", file=sys.stderr)
    for r in failed:
        print(f"  {r['experiment']} {r['backend']}/{r['device']} {r['setting']}: {r['verdict']} {r['detail'][:160]}",
              file=sys.stderr)
    return EXIT_FAIL if failed else EXIT_OK
