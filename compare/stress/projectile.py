"""The projectile scenario's stress experiments (docs/stress.md): projectile-lr (learning rate x
contact x optimiser), projectile-gradient (gradient quality against finite differences and along
vy0) and projectile-horizon (gradient growth with the number of steps).

Their verdict rules and predictions are in compare/stress/projectile_rules.py, their page hooks
and plots in compare/stress/projectile_plots.py; loss, gradient and Hessian come from the
scenario's float64 model, the optimisers and scans run as host-loop tasks
(compare/stress/projectile_tasks.py).
"""
from __future__ import annotations

import math

import numpy as np

from compare.stress import projectile_tasks as T
from compare.stress.numerics import ORACLE, Experiment, Result, Series, StressContext, check_of
from compare.stress.projectile_plots import (LOOK, lr_matrix, lr_table_rows, plot_projectile_gradient,
                                             plot_projectile_horizon, plot_projectile_lr)
from compare.stress.projectile_rules import (CONTACTS, FD_AGREE, FD_STEPS, SC, classify, fd_gradient,
                                             loss_mispredictions, observed_boundary, predicted_lr)
from scenarios.base import Precision
from scenarios.projectile import CONSTANTS
from scenarios.projectile_adjoint import gradient

SEED_LRS = (0.01, 0.08, 0.2)      # the seeds' learning rates: their histories are plotted


def lr_grid(quick: bool) -> tuple[float, ...]:
    return (0.01, 0.045, 0.055, 0.08, 0.2) if quick else \
        (0.001, 0.005, 0.01, 0.02, 0.04, 0.045, 0.055, 0.08, 0.2, 1.0)


def host_rows(ctx: StressContext, tasks: list[T.Task]) -> list[tuple[T.Task, T.Outcome]]:
    """Run the backends' host-loop tasks in worker processes and the float64 oracle's (the last
    task) here; (task, outcome) pairs."""
    results = ctx.run_tasks(tasks[:-1])
    results.append(T.execute(tasks[-1]))
    return list(zip(tasks, results))


# ---- experiments --------------------------------------------------------------------------------

def exp_projectile_lr(ctx: StressContext) -> Result:
    """Learning-rate sweep x contact x optimiser, classified; observed boundary vs 2/lambda_max."""
    name = "projectile-lr"
    lrs = lr_grid(ctx.quick)
    iters = SC.params({}, quick=ctx.quick).iters
    budget = 60.0 if ctx.quick else 300.0
    rows = ctx.skip_rows(name)
    series: Series = {"lrs": list(lrs), "histories": {}}
    pred = {c: predicted_lr(c, iters) for c in CONTACTS}
    for c, (lr_star, info) in pred.items():
        rows.append(ctx.row(name, "physics", "host", "float64", f"contact={c}", "predicted GD boundary lr* = 2/lambda_max(H)",
                            lr_star, f"GD locally stable iff lr < {lr_star:.3g}",
                            "; ".join(f"{k} = {v:.4g}" for k, v in info.items()) + " (H: float64 Hessian)"))
    # gradient descent: the backends' own device-side loop (one cell each, float32)
    planned = [((c, lr), ctx.spec(SC.name, b, d, "float32", {"contact": c, "lr": lr, "iters": iters}))
               for b, d, _ in ctx.targets() for c in CONTACTS for lr in lrs]
    runs: list[tuple[str, str, str, str, str, float, list[float] | None, str]] = []
    for ((c, lr), s), (rec, out) in zip(planned, ctx.run_cells([s for _, s in planned])):
        h = None if out is None else np.asarray(out["loss_history"], np.float64).tolist()
        runs.append((s.backend, str(s.device), "float32", "gd", c, lr, h, "" if h is not None else rec.reason))
    # clipping and Adam: host loop; the float64 oracle runs all three
    tasks = [T.Task("optimise", b, d, "float32", CONTACTS, budget, lrs=lrs, methods=("clip", "adam"), iters=iters)
             for b, d, _ in ctx.targets()]
    tasks.append(T.Task("optimise", ORACLE, "host", "float64", CONTACTS, math.inf, lrs=lrs, methods=T.OPTIMISERS,
                        iters=iters))
    for t, res in host_rows(ctx, tasks):
        if res.why_not is not None:
            rows.append(ctx.row(name, t.backend, t.device, t.precision, "clip, adam (host loop)", "-", None,
                                "skipped" if res.skipped else "error", res.why_not))
            continue
        for r in res.descents:
            runs.append((t.backend, t.device, t.precision, r.method, r.contact, r.lr, r.history, ""))
    groups: dict[tuple, list] = {}
    for b, d, prec, m, c, lr, h, why in runs:
        setting = f"{m}, contact={c}, lr={lr:g}, iters={iters}"
        if h is None:
            rows.append(ctx.row(name, b, d, prec, setting, "loss[end]/loss[0]", None, "error", why)); continue
        cls = classify(h)
        ratio = h[-1] / h[0] if math.isfinite(h[-1]) and h[0] > 0 else math.inf
        rows.append(ctx.row(name, b, d, prec, setting, "loss[end]/loss[0]", ratio, cls,
                            f"loss[0] = {h[0]:.4g}" + ("" if m != "clip" else f"; clip |g| <= {T.CLIP_NORM:g}")
                            + ("" if m != "adam" else "; Adam b1 0.9, b2 0.999")))
        groups.setdefault((b, d, prec, m, c), []).append((lr, cls))
        if b in (ctx.reference, ORACLE) and lr in SEED_LRS:
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
        rows.append(ctx.row(name, b, d, prec, f"{m}, contact={c}", "observed boundary: first diverging lr", first_div,
                            verdict, f"largest lr below it: {stable}; " + ("" if monotone else "NON-MONOTONE in lr; ")
                            + " ".join(f"{lr:g}:{cl[0].upper()}" for lr, cl in sorted(pts))))
    return rows, series


def exp_projectile_gradient(ctx: StressContext) -> Result:
    """Gradient quality (none / hard / soft) against float64 central differences over FD steps, and
    along a line of launch velocities at two spacings (loss jumps vs stiff curvature)."""
    name = "projectile-gradient"
    fd, gsize = {}, {}
    for prec in ("float32", "float64"):
        for c in CONTACTS:
            p = SC.params({"contact": c, "iters": 0})
            inp = SC.inputs(p, prec)
            cc = {k: float(inp[k]) for k in CONSTANTS}
            v = inp["v0"].astype(np.float64)
            fd[(prec, c)] = [fd_gradient(cc, c, p.steps, v, h) for h in FD_STEPS]
            gsize[c] = float(np.linalg.norm(gradient(cc, c, p.steps, v)))
    precisions = ("float32",) if ctx.quick else ("float32", "float64")
    planned = [((c, prec), ctx.spec(SC.name, b, d, prec, {"contact": c, "iters": 0})) for b, d, _ in ctx.targets()
               for prec in ctx.precisions(b, d, precisions) for c in CONTACTS]
    rows = ctx.skip_rows(name, precisions=precisions)
    series: Series = {"h": list(FD_STEPS), "lines": {}, "scans": {}}
    step_len = {c: 0.01 * gsize[c] for c in CONTACTS}       # one GD step at the seed's lr = 0.01
    for ((c, prec), s), (rec, out) in zip(planned, ctx.run_cells([s for _, s in planned])):
        setting = f"contact={c}, v0=(2, 6.5)"
        if rec.status == "error" or out is None:
            rows.append(ctx.error_row(name, s, setting, rec)); continue
        g = np.asarray(out["grad"], np.float64)
        gr = rec.gradient        # a block without keys reads as none
        rows.append(ctx.row(name, s.backend, s.device, prec, setting,
                            f"gradient rel. error vs {gr.get('reference', 'oracle') if gr else 'oracle'}",
                            gr.get("vs_oracle_rel") if gr else None,
                            "within derived bound" if rec.status == "ok" else "EXCEEDS derived bound",
                            f"gradient {np.array2string(g, precision=5)}"))
        rel = [float(np.max(np.abs(g - f)) / max(float(np.max(np.abs(g))), 1e-300)) for f in fd[(prec, c)]]
        series["lines"][f"{ctx.label(s)}/{prec}/{c}"] = rel
        h_star = None                 # largest h such that every h' <= h agrees within FD_AGREE
        for h, r in sorted(zip(FD_STEPS, rel)):
            if r > FD_AGREE:
                break
            h_star = h
        step = step_len[c]
        verdict = ("agrees with FD at no step" if h_star is None else
                   f"valid over a GD step (h* >= lr|g| = {step:.3g})" if h_star >= step else
                   f"VALID ONLY FOR h <= {h_star:.2g}, one GD step at lr 0.01 is {step:.3g}")
        rows.append(ctx.row(name, s.backend, s.device, prec, setting,
                            "largest FD step h* with |g - g_FD(h)| <= 1% |g| (all smaller h too)", h_star, verdict,
                            "rel. discrepancy at h = 1e-1, 1e-2, 1e-3: " +
                            ", ".join(f"{rel[FD_STEPS.index(h)]:.2g}" for h in (10.0 ** -1, 10.0 ** -2, 10.0 ** -3)
                                      if h in FD_STEPS)))
    # scans along vy0 at two spacings: mispredictions that persist at the finer one are jumps;
    # differences below the derived loss rounding bound (relative, at v0) cannot be told apart
    loss_noise = {}
    for prec in ("float32", "float64"):
        for c in ("hard", "soft"):
            p = SC.params({"contact": c, "iters": 0})
            ref = SC.oracle(p, SC.inputs(p, prec), Precision(prec))
            loss_noise[(prec, c)] = float(ref["tol_loss"][0] / abs(ref["loss"]))
    npts = 41 if ctx.quick else 81
    scans = {"coarse": np.linspace(6.3, 6.7, npts).tolist(), "fine": np.linspace(6.48, 6.52, npts).tolist()}
    budget = 60.0 if ctx.quick else 300.0
    tasks = [T.Task("scan", b, d, "float32", ("hard", "soft"), budget, scans=scans) for b, d, _ in ctx.targets()]
    tasks.append(T.Task("scan", ORACLE, "host", "float64", ("hard", "soft"), math.inf, scans=scans))
    for t, res in host_rows(ctx, tasks):
        if res.why_not is not None:
            rows.append(ctx.row(name, t.backend, t.device, t.precision, "vy0 scans (host loop)", "-", None,
                                "skipped" if res.skipped else "error", res.why_not))
            continue
        per = {(r.contact, r.scan): r for r in res.scans}
        for c in ("hard", "soft"):
            k = {sc_: loss_mispredictions(per[(c, sc_)].vy, per[(c, sc_)].loss, per[(c, sc_)].grad,
                                          loss_noise[(t.precision, c)]) for sc_ in scans}
            spacing = {sc_: scans[sc_][1] - scans[sc_][0] for sc_ in scans}
            verdict = ("gradient predicts the loss along the scan" if k["coarse"][0] == 0 else
                       "smooth but stiff: mispredictions vanish at 10x finer spacing" if k["fine"][0] == 0 else
                       "LOSS JUMPS: mispredictions persist at 10x finer spacing")
            rows.append(ctx.row(name, t.backend, t.device, t.precision, f"contact={c}, vy0 scan",
                                "intervals where the gradient mispredicts the loss change (coarse)", k["coarse"][0],
                                verdict, "; ".join(
                                    f"{sc_}: {k[sc_][0]}/{npts - 1} at dvy = {spacing[sc_]:.3g} "
                                    f"(+{k[sc_][1]} below the loss rounding {loss_noise[(t.precision, c)]:.2g}|L|)"
                                    for sc_ in scans)))
            if t.backend in (ctx.reference, ORACLE):
                coarse = per[(c, "coarse")]
                series["scans"][f"{t.backend}/{t.device}/{c}"] = {
                    "vy": coarse.vy, "loss": coarse.loss, "dvy": [g[1] for g in coarse.grad]}
    series["gd_step"] = step_len
    return rows, series


def exp_projectile_horizon(ctx: StressContext) -> Result:
    """Horizon (steps) sweep: gradient size and float32 gradient error as the rollout lengthens."""
    name = "projectile-horizon"
    horizons = (90, 180, 720) if ctx.quick else (45, 90, 180, 360, 720, 1440)
    planned = [((c, n), ctx.spec(SC.name, b, d, "float32", {"contact": c, "steps": n, "iters": 0}))
               for b, d, _ in ctx.targets() for c in CONTACTS for n in horizons]
    rows, series = ctx.skip_rows(name), {}
    acc: dict[tuple[str, str, str], list] = {}
    for ((c, n), s), (rec, out) in zip(planned, ctx.run_cells([s for _, s in planned])):
        setting = f"contact={c}, steps={n}"
        if rec.status == "error" or out is None:
            rows.append(ctx.error_row(name, s, setting, rec)); continue
        rel = rec.gradient.vs_oracle_rel if rec.gradient else None
        g = float(np.linalg.norm(np.asarray(out["grad"], np.float64)))
        ok = rec.status == "ok"
        rows.append(ctx.row(name, s.backend, s.device, "float32", setting, "gradient rel. error vs float64",
                            rel, "within derived bound" if ok else "EXCEEDS derived bound",
                            f"|grad| = {g:.4g}; error/bound = {ctx.fmt(check_of(rec).vs_oracle)}"))
        acc.setdefault((s.backend, str(s.device), c), []).append((n, g, rel, ok))
    for (b, d, c), pts in acc.items():
        pts.sort()
        ns = np.array([p[0] for p in pts], float); gs = np.array([p[1] for p in pts], float)
        good = (gs > 0) & np.isfinite(gs)
        slope = float(np.polyfit(np.log(ns[good]), np.log(gs[good]), 1)[0]) if good.sum() >= 2 else math.nan
        all_ok = all(p[3] for p in pts)
        rels = [p[2] for p in pts]
        worst = max(((float(r), n_) for n_, r in zip(ns, rels) if isinstance(r, (int, float))),
                    default=(math.nan, 0))
        rows.append(ctx.row(name, b, d, "float32", f"contact={c}, steps {int(ns[0])}..{int(ns[-1])}",
                            "|grad| growth exponent p (|grad| ~ steps^p, least squares)", slope,
                            ("within derived bound at every horizon" if all_ok else "EXCEEDS derived bound at some horizon")
                            + (f"; float32 gradient OFF BY {worst[0]:.0%} at steps={int(worst[1])} (ill-conditioned)"
                               if worst[0] > FD_AGREE else ""),
                            f"|grad| x{gs[-1] / gs[0]:.3g} from {int(ns[0])} to {int(ns[-1])} steps; rel. error: "
                            + ", ".join(f"{int(n_)}:{ctx.fmt(r)}" for n_, r in zip(ns, rels))))
        series[f"{b}/{d}/{c}"] = {"steps": ns.tolist(), "grad": gs.tolist(), "rel": rels}
    return rows, series


EXPERIMENTS: dict[str, Experiment] = {e.name: e for e in (
    Experiment("projectile-lr", "learning-rate sweep x contact x optimiser", exp_projectile_lr,
               plot_projectile_lr, extra_markdown=lr_matrix, table_rows=lr_table_rows, look=LOOK["projectile-lr"]),
    Experiment("projectile-gradient", "gradient quality: hard vs soft vs finite differences",
               exp_projectile_gradient, plot_projectile_gradient, look=LOOK["projectile-gradient"]),
    Experiment("projectile-horizon", "horizon sweep: gradient growth", exp_projectile_horizon,
               plot_projectile_horizon, look=LOOK["projectile-horizon"]),
)}
