"""The particles scenario's stress experiments (docs/stress.md): particles-dt, particles-long,
particles-inf, particles-divergence, and the contact-timing analysis they share (their plots:
compare/stress/particles_plots.py).

Every rollout comes from the scenario itself: the backends through cells, the float64 oracle
(``Particles.oracle``) and the one NumPy stepper (``simulate``) here; energy and its derived bound
are the scenario's (``energy``, ``energy_bound``).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from backends.base import DEFAULT_VARIANT
from compare.stress.numerics import (Experiment, Outputs, Overrides, Result, StressContext,
                                     bitwise_differences, check_of)
from scenarios.base import UNIT_ROUNDOFF, Precision, dtype_of
from scenarios.particles import Particles, ParticlesParams, energy, energy_bound, simulate
from compare.stress.particles_plots import LOOK, plot_particles_divergence, plot_particles_dt, plot_particles_long

SC = Particles()
STATE = ("x", "y", "vx", "vy")


def particle_inputs(params: Overrides, precision: str) -> tuple[ParticlesParams, Outputs]:
    p = SC.params(params)
    return p, SC.inputs(p, precision)


def state_error(out: dict[str, np.ndarray], ref: dict[str, np.ndarray]) -> np.ndarray:
    with np.errstate(invalid="ignore", over="ignore"):
        return np.max([np.abs(np.asarray(out[k], np.float64) - ref[k]) for k in STATE], axis=0)


def finite_state(out: dict[str, np.ndarray]) -> bool:
    return all(bool(np.all(np.isfinite(out[k]))) for k in STATE)


def first_nonfinite_step(params: Overrides, precision: Precision, max_steps: int) -> int | None:
    """The first step after which some particle's state is non-finite, by the scenario's NumPy
    stepper at ``precision`` (operation by operation, no FMA); None within ``max_steps``."""
    _, inp = particle_inputs(params, precision)
    state, steps = simulate(inp, max_steps, dtype_of(precision), until_nonfinite=True)
    return None if all(np.all(np.isfinite(a)) for a in state) else steps


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


# ---- experiments --------------------------------------------------------------------------------

def exp_particles_dt(ctx: StressContext) -> Result:
    """dt sweep at fixed simulated time T = 3 s: float32 rounding against the time discretisation."""
    name, T, n = "particles-dt", 3.0, 256
    dts = (0.02, 0.005, 0.001) if ctx.quick else (0.02, 0.01, 0.005, 0.002, 0.001, 0.0005)
    precisions = ("float32",) if ctx.quick else ("float32", "float64")   # float64: exact vs the oracle
    steps = {dt: int(round(T / dt)) for dt in dts}
    # discretisation error: float64 oracle at dt against one at dt_min/4 (median over particles)
    pf, inf = particle_inputs({"n": n, "steps": 4 * steps[dts[-1]], "dt": dts[-1] / 4}, Precision.FLOAT64)
    fine = SC.oracle(pf, inf, Precision.FLOAT64)
    disc, ref32 = {}, {}
    for dt in dts:
        p, i64 = particle_inputs({"n": n, "steps": steps[dt], "dt": dt}, Precision.FLOAT64)
        disc[dt] = float(np.median(state_error(SC.oracle(p, i64, Precision.FLOAT64), fine)))
        p, i32 = particle_inputs({"n": n, "steps": steps[dt], "dt": dt}, Precision.FLOAT32)
        ref32[dt] = SC.oracle(p, i32, Precision.FLOAT32)
    planned = [(dt, ctx.spec(SC.name, b, d, prec, {"n": n, "steps": steps[dt], "dt": dt}))
               for b, d, _ in ctx.targets() for prec in ctx.precisions(b, d, precisions) for dt in dts]
    rows = ctx.skip_rows(name, precisions=precisions)
    lines: dict[str, dict[str, list[float]]] = {}
    for (dt, s), (rec, out) in zip(planned, ctx.run_cells([s for _, s in planned])):
        setting = f"dt={dt:g}, steps={steps[dt]}, T={T:g} s"
        if rec.status == "error" or out is None:
            rows.append(ctx.error_row(name, s, setting, rec)); continue
        e = check_of(rec)
        ok = rec.status == "ok"
        rows.append(ctx.row(name, s.backend, s.device, s.precision, setting,
                            "max error / derived bound (well-conditioned particles)",
                            e.get("worst_error_over_bound"), "within derived bound" if ok else "EXCEEDS derived bound",
                            f"max |state - float64| {ctx.fmt(e['vs_oracle'])} vs bound {ctx.fmt(e['tolerance'])}; "
                            f"{e.get('ill_conditioned')} ill-conditioned particles not checked"))
        line = lines.setdefault(f"{ctx.label(s)}/{s.precision}", {"dt": [], "median": []})
        line["dt"].append(dt)
        if s.precision == "float32":
            med = float(np.median(state_error(out, ref32[dt])))
            line["median"].append(med)
            ratio = med / disc[dt] if disc[dt] > 0 else math.inf
            rows.append(ctx.row(name, s.backend, s.device, s.precision, setting,
                                "median rounding error / median discretisation error", ratio,
                                "rounding below discretisation" if ratio < 1 else
                                "ROUNDING DOMINATES: a smaller dt no longer helps in float32",
                                f"rounding {med:.3g} (vs float64 oracle, same inputs), discretisation "
                                f"{disc[dt]:.3g} (float64 at dt vs at dt = {dts[-1] / 4:g})"))
        else:
            line["median"].append(e["vs_oracle"])
    return rows, {"dt": list(dts), "discretisation": [disc[dt] for dt in dts], "lines": lines}


def exp_particles_long(ctx: StressContext) -> Result:
    """Long rollouts: energy against its derived bound (bounce < 1) or its growth (bounce > 1)."""
    name, n = "particles-long", 256
    lengths = (10_000,) if ctx.quick else (1000, 10_000, 100_000)
    bounces = (0.82, 1.05) if ctx.quick else (0.82, 0.99, 1.05)
    precisions = ("float32",) if ctx.quick else ("float32", "float64")
    planned = [((bo, st), ctx.spec(SC.name, b, d, prec, {"n": n, "steps": st, "bounce": bo}))
               for b, d, _ in ctx.targets() for prec in ctx.precisions(b, d, precisions)
               for bo in bounces for st in lengths]
    rows = ctx.skip_rows(name, precisions=precisions)
    series: dict[str, dict[str, list[Any]]] = {}
    for ((bounce, st), s), (rec, out) in zip(planned, ctx.run_cells([s for _, s in planned])):
        setting = f"bounce={bounce}, steps={st}"
        if rec.status == "error" or out is None:
            rows.append(ctx.row(name, s.backend, s.device, s.precision, setting, "cell", None,
                                "CRASHED" if bounce > 1 else "error", rec.reason))
            continue
        _, inp = particle_inputs({"n": n, "steps": st, "bounce": bounce}, s.precision)
        g, r = float(inp["gravity"]), float(inp["radius"])
        e0 = energy(inp["x0"], inp["y0"], inp["vx0"], inp["vy0"], g, r)
        et = energy(out["x"], out["y"], out["vx"], out["vy"], g, r)
        total = float(np.sum(et) / np.sum(e0))
        fin = finite_state(out)
        key = f"{ctx.label(s)}/{s.precision}/bounce={bounce}"
        series.setdefault(key, {"steps": [], "ratio": []})
        series[key]["steps"].append(st); series[key]["ratio"].append(total if fin else None)
        if bounce < 1:
            slack = 16 * UNIT_ROUNDOFF[s.precision]
            worst = float(np.max(et / energy_bound(inp))) if fin else math.inf
            verdict = ("NON-FINITE state" if not fin else "no energy gain (within derived bound)"
                       if worst <= 1 + slack else "GAINS ENERGY beyond the derived bound")
            rows.append(ctx.row(name, s.backend, s.device, s.precision, setting,
                                "max over particles of E(T) / derived bound", worst, verdict,
                                f"total E(T)/E(0) = {total:.3g}; bound E <= u0^2/2 + max(Ev0, E_floor), slack 16u"))
        else:
            verdict = ("unstable, reported: non-finite state, no crash" if not fin else
                       f"unstable, reported: energy x{total:.3g} (bounce > 1 adds energy)" if total > 1 else
                       "no energy growth observed")
            rows.append(ctx.row(name, s.backend, s.device, s.precision, setting,
                                "total E(T) / E(0)", total, verdict,
                                f"max height {float(np.max(np.asarray(out['y'], np.float64))):.3g} m"))
    return rows, series


def exp_particles_inf(ctx: StressContext) -> Result:
    """bounce = 1.05: the walls return 5 % more speed at every hit and are hit ever more often, so
    the horizontal speed overflows in finite time; find the first step with a non-finite state."""
    name, n, smax = "particles-inf", 256, 30_000
    base = {"n": n, "bounce": 1.05}
    predicted = {prec: first_nonfinite_step(base, prec, smax) for prec in (Precision.FLOAT32, Precision.FLOAT64)}

    def search(item: tuple[str, str, str, Precision]) -> tuple[tuple[str, str, str, Precision], int | None,
                                                              list[int], str | None]:
        b, d, var, prec = item
        calls: list[int] = []

        def nonfinite(steps: int) -> bool | None:
            if steps == 0:
                return False
            (rec, out), = ctx.run_cells([ctx.spec(SC.name, b, d, prec, {**base, "steps": steps}, var)])
            calls.append(steps)
            if rec.status == "error" or out is None:
                raise RuntimeError(rec.reason)
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

    both = ("float32", "float64")
    items = [(b, d, v, Precision(prec)) for b, d, v in ctx.targets(variants=True)
             for prec in ctx.precisions(b, d, both)]
    rows = ctx.skip_rows(name, variants=True, precisions=both)
    for (b, d, var, prec), first, calls, err in ctx.map(search, items):
        setting = f"bounce=1.05, n={n}" + ("" if var == DEFAULT_VARIANT else f", variant={var}")
        pred = predicted[prec]
        if err:
            rows.append(ctx.row(name, b, d, prec, setting, "first step with a non-finite state", None, "CRASHED", err))
        elif first is None:
            rows.append(ctx.row(name, b, d, prec, setting, "first step with a non-finite state", None,
                                f"no Inf/NaN within {smax} steps", f"NumPy {prec} emulation: step {pred}"))
        else:
            same = "= NumPy emulation" if first == pred else f"NumPy emulation says {pred}"
            rows.append(ctx.row(name, b, d, prec, setting, "first step with a non-finite state", first,
                                f"unstable, reported: Inf/NaN from step {first} ({same}), no crash",
                                f"located with {len(calls)} cells at steps {calls}"))
    return rows, {}


def exp_particles_divergence(ctx: StressContext) -> Result:
    """float32 vs float64 along whole trajectories; collision-timing flips between precisions and
    between backends. bounce 0.82 (the seed) settles within ~10 s; 0.99 keeps bouncing."""
    name, n = "particles-divergence", 256
    steps = 1000 if ctx.quick else 5000
    bounces = (0.99,) if ctx.quick else (0.82, 0.99)
    rows, series = ctx.skip_rows(name, precisions=("float32", "float64")), {}
    for bounce in bounces:
        r, s = divergence_for(ctx, name, n, steps, bounce)
        rows += r
        series.update({f"{k}/bounce={bounce:g}": v for k, v in s.items()})
    return rows, series


def divergence_for(ctx: StressContext, name: str, n: int, steps: int, bounce: float) -> Result:
    prm = {"n": n, "steps": steps, "record_every": 1, "bounce": bounce}
    refs = {}
    for prec in ("float32", "float64"):
        p, inp = particle_inputs(prm, Precision(prec))
        ref = SC.oracle(p, inp, Precision(prec))
        refs[prec] = (ref, contacts(ref["traj_x"][1:], ref["traj_y"][1:], float(inp["radius"]), np.float64),
                      float(inp["radius"]))
    specs = [ctx.spec(SC.name, b, d, prec, prm) for b, d, _ in ctx.targets()
             for prec in ctx.precisions(b, d, ("float32", "float64"))]
    res = dict(zip([(s.backend, str(s.device), str(s.precision)) for s in specs], ctx.run_cells(specs)))
    rows, series = [], {}
    setting = f"bounce={bounce:g}, n={n}, steps={steps}"
    flags: dict[tuple[str, str, str], np.ndarray] = {}
    outs: dict[tuple[str, str, str], Outputs] = {}     # the outputs flags were drawn from
    for (b, d, prec), (rec, out) in res.items():
        if rec.status == "error" or out is None or "traj_x" not in out:
            rows.append(ctx.row(name, b, d, prec, setting, "cell", None, "error", rec.reason))
            continue
        ref, cref, radius = refs[prec]
        flags[(b, d, prec)] = c = contacts(out["traj_x"][1:], out["traj_y"][1:], radius, dtype_of(prec))
        outs[(b, d, prec)] = out
        flips = first_flips(c, cref)
        ill = ref["ill_conditioned"]
        bad = int(np.sum((flips >= 0) & ~ill))
        nflip = int(np.sum(flips >= 0))
        rows.append(ctx.row(name, b, d, prec, setting, "particles whose contact timing flips vs float64 oracle (same inputs)",
                            nflip, "no flips" if nflip == 0 else
                            "all flips in derived ill-conditioned particles" if bad == 0 else
                            f"{bad} FLIPS IN WELL-CONDITIONED particles (rounding beyond the bound)",
                            f"{int(ill.sum())} particles ill-conditioned; first flip at step "
                            f"{int(flips[flips >= 0].min()) + 1 if nflip else '-'}"))
    for b, d, _ in ctx.targets():
        if (b, d, "float32") not in flags or (b, d, "float64") not in flags:
            continue
        o32, o64 = outs[(b, d, "float32")], outs[(b, d, "float64")]
        with np.errstate(invalid="ignore"):
            dpos = np.maximum(np.abs(o32["traj_x"].astype(np.float64) - o64["traj_x"]),
                              np.abs(o32["traj_y"].astype(np.float64) - o64["traj_y"]))
        med, mx = np.median(dpos, axis=1), np.max(dpos, axis=1)
        radius = refs["float64"][2]
        over = np.nonzero(med > radius)[0]
        flips = first_flips(flags[(b, d, "float32")], flags[(b, d, "float64")])
        nflip = int(np.sum(flips >= 0))
        rows.append(ctx.row(name, b, d, "float32 vs float64", setting, "max |pos32 - pos64| at the last step",
                            float(mx[-1]), f"DECORRELATED: median particle off by > radius from step {int(over[0])}"
                            if over.size else "median particle stays within one radius",
                            f"median {float(med[-1]):.3g} m; {nflip} of {n} particles' contact timing flips "
                            f"(first at step {int(flips[flips >= 0].min()) + 1 if nflip else '-'})"))
        idx = np.unique(np.geomspace(1, steps, 300).astype(int))
        series[f"{b}/{d}"] = {"step": idx.tolist(), "median": med[idx].tolist(), "max": mx[idx].tolist()}
    ref_name = ctx.reference
    for (b, d, prec), c in flags.items():
        if b == ref_name or (ref_name, d, prec) not in flags:
            continue
        flips = first_flips(c, flags[(ref_name, d, prec)])
        ill = refs[prec][0]["ill_conditioned"]
        nflip, bad = int(np.sum(flips >= 0)), int(np.sum((flips >= 0) & ~ill))
        same = bitwise_differences({k: outs[(b, d, prec)][k] for k in ("traj_x", "traj_y")},
                                   {k: outs[(ref_name, d, prec)][k] for k in ("traj_x", "traj_y")})
        verdict = ("bitwise identical trajectory" if same == 0 else
                   "same contact timing, trajectories differ in rounding" if nflip == 0 else
                   "flips only in derived ill-conditioned particles" if bad == 0 else
                   f"{bad} FLIPS IN WELL-CONDITIONED particles")
        rows.append(ctx.row(name, b, d, prec, setting, f"particles whose contact timing flips vs {ref_name}", nflip,
                            verdict, f"{same} trajectory values differ bitwise from {ref_name}"))
    return rows, series


# ---- plots (from the series kept in stress.json) -------------------------------------------------

EXPERIMENTS: dict[str, Experiment] = {e.name: e for e in (
    Experiment("particles-dt", "dt sweep at fixed simulated time", exp_particles_dt, plot_particles_dt,
               look=LOOK["particles-dt"]),
    Experiment("particles-long", "long rollouts: energy bound (bounce < 1), growth (bounce > 1)",
               exp_particles_long, plot_particles_long, look=LOOK["particles-long"]),
    Experiment("particles-inf", "first non-finite step (bounce = 1.05)", exp_particles_inf),
    Experiment("particles-divergence", "float32 vs float64 over time, collision-timing flips",
               exp_particles_divergence, plot_particles_divergence, look=LOOK["particles-divergence"]),
)}
