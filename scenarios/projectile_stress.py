"""The projectile scenario's stress experiments (docs/stress.md): projectile-lr (learning rate x
contact x optimiser), projectile-gradient (gradient quality against finite differences and along
vy0) and projectile-horizon (gradient growth with the number of steps), their verdict rules,
plots and the lr matrix of the page.

Loss, gradient and Hessian come from the scenario (``scenarios.projectile``); the optimisers and
scans run as host-loop tasks (``scenarios.projectile_tasks``).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from . import projectile as P
from . import projectile_tasks as T
from .numerics import ORACLE, Experiment, Result, Row, StressContext, Style, log_floor

SC = P.Projectile()
CONTACTS = ("none", "hard", "soft")
CONVERGED_REL = 1e-6              # loss reduced a million-fold = miss distance reduced 1000-fold
DIVERGED_REL = 1e-3               # ended more than 0.1 % above its start
FD_AGREE = 0.01                   # a gradient 'agrees' with finite differences to 1 % (stated)
SEED_LRS = (0.01, 0.08, 0.2)
FD_STEPS = tuple(10.0 ** (e / 2) for e in range(2, -17, -1))     # 10 ... 1e-8, half decades


# ---- verdict rules (unit-tested in tests/test_stress.py) ------------------------------------------

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
    c = {k: float(inp[k]) for k in P.CONSTANTS}
    hist, v_end = T.optimise(T.oracle_evaluator({"contact": contact}), inp["v0"], 0.01, iters, "gd")
    lam = {}
    for where, v in (("v0", inp["v0"].astype(np.float64)), ("v_end", v_end)):
        lam[where] = float(np.max(np.linalg.eigvalsh(P.hessian(c, contact, p.steps, v)))) if np.all(np.isfinite(v)) else math.nan
    info = {f"lambda_max({k})": val for k, val in lam.items()}
    if contact == "none":
        info["closed form 1/(N dt)^2"] = 1.0 / (p.steps * c["dt"]) ** 2
    lam_end = lam["v_end"] if math.isfinite(lam["v_end"]) else lam["v0"]
    return (2.0 / lam_end if lam_end > 0 else math.inf), info


def fd_gradient(c: dict[str, float], contact: str, steps: int, v: np.ndarray, h: float) -> np.ndarray:
    """Float64 central differences of the scenario's loss with step h."""
    return np.array([(P.loss_of(c, contact, steps, v + h * e) - P.loss_of(c, contact, steps, v - h * e)) / (2 * h)
                     for e in np.eye(2)])


def lr_grid(quick: bool) -> tuple[float, ...]:
    return (0.01, 0.045, 0.055, 0.08, 0.2) if quick else \
        (0.001, 0.005, 0.01, 0.02, 0.04, 0.045, 0.055, 0.08, 0.2, 1.0)


def host_rows(ctx: StressContext, tasks: list[dict[str, Any]]) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    """Run the backends' host-loop tasks in worker processes and the float64 oracle's (the last
    task) here; (task, result) pairs."""
    results = ctx.run_tasks(tasks[:-1])
    results.append(T.run_task(tasks[-1]))
    return list(zip(tasks, results))


# ---- experiments --------------------------------------------------------------------------------

def exp_projectile_lr(ctx: StressContext) -> Result:
    """Learning-rate sweep x contact x optimiser, classified; observed boundary vs 2/lambda_max."""
    name = "projectile-lr"
    lrs = lr_grid(ctx.quick)
    iters = SC.params({}, quick=ctx.quick).iters
    budget = 60.0 if ctx.quick else 300.0
    rows, series = ctx.skip_rows(name), {"lrs": list(lrs), "histories": {}}
    pred = {c: predicted_lr(c, iters) for c in CONTACTS}
    for c, (lr_star, info) in pred.items():
        rows.append(ctx.row(name, "physics", "host", "float64", f"contact={c}", "predicted GD boundary lr* = 2/lambda_max(H)",
                            lr_star, f"GD locally stable iff lr < {lr_star:.3g}",
                            "; ".join(f"{k} = {v:.4g}" for k, v in info.items()) + " (H: float64 Hessian)"))
    # gradient descent: the backends' own device-side loop (one cell each, float32)
    specs = [ctx.spec(SC.name, b, d, "float32", {"contact": c, "lr": lr, "iters": iters})
             for b, d, _ in ctx.targets() for c in CONTACTS for lr in lrs]
    runs: list[tuple[str, str, str, str, str, float, list[float] | None, str]] = []
    for s, (rec, out) in zip(specs, ctx.run_cells(specs)):
        h = None if out is None else np.asarray(out["loss_history"], np.float64).tolist()
        runs.append((s["backend"], s["device"], "float32", "gd", s["params"]["contact"], s["params"]["lr"], h,
                     "" if h is not None else rec.get("reason", "?")))
    # clipping and Adam: host loop; the float64 oracle runs all three
    tasks = [T.task("optimise", backend=b, device=d, precision="float32", contacts=list(CONTACTS),
                    lrs=list(lrs), methods=["clip", "adam"], iters=iters, budget_s=budget)
             for b, d, _ in ctx.targets()]
    tasks.append(T.task("optimise", backend=ORACLE, device="host", precision="float64", contacts=list(CONTACTS),
                        lrs=list(lrs), methods=list(T.OPTIMISERS), iters=iters, budget_s=math.inf))
    for t, res in host_rows(ctx, tasks):
        if "results" not in res:
            why = res.get("skipped") or res.get("error")
            rows.append(ctx.row(name, t["backend"], t["device"], t["precision"], "clip, adam (host loop)", "-", None,
                                "skipped" if "skipped" in res else "error", why))
            continue
        for r in res["results"]:
            runs.append((t["backend"], t["device"], t["precision"], r["method"], r["contact"], r["lr"], r["history"], ""))
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
            cc = {k: float(inp[k]) for k in P.CONSTANTS}
            v = inp["v0"].astype(np.float64)
            fd[(prec, c)] = [fd_gradient(cc, c, p.steps, v, h) for h in FD_STEPS]
            gsize[c] = float(np.linalg.norm(P.gradient(cc, c, p.steps, v)))
    specs = [ctx.spec(SC.name, b, d, prec, {"contact": c, "iters": 0}) for b, d, _ in ctx.targets()
             for prec in (("float32",) if ctx.quick else ("float32", "float64")) for c in CONTACTS]
    rows, series = ctx.skip_rows(name), {"h": list(FD_STEPS), "lines": {}, "scans": {}}
    step_len = {c: 0.01 * gsize[c] for c in CONTACTS}       # one GD step at the seed's lr = 0.01
    for s, (rec, out) in zip(specs, ctx.run_cells(specs)):
        c, prec = s["params"]["contact"], s["precision"]
        setting = f"contact={c}, v0=(2, 6.5)"
        if rec["status"] == "error" or out is None:
            rows.append(ctx.error_row(name, s, setting, rec)); continue
        g = np.asarray(out["grad"], np.float64)
        gr = rec.get("gradient") or {}
        rows.append(ctx.row(name, s["backend"], s["device"], prec, setting,
                            f"gradient rel. error vs {gr.get('reference', 'oracle')}", gr.get("vs_oracle_rel"),
                            "within derived bound" if rec["status"] == "ok" else "EXCEEDS derived bound",
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
        rows.append(ctx.row(name, s["backend"], s["device"], prec, setting,
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
            ref = SC.oracle(p, SC.inputs(p, prec))
            loss_noise[(prec, c)] = float(ref["tol_loss"][0] / abs(ref["loss"]))
    npts = 41 if ctx.quick else 81
    scans = {"coarse": np.linspace(6.3, 6.7, npts).tolist(), "fine": np.linspace(6.48, 6.52, npts).tolist()}
    budget = 60.0 if ctx.quick else 300.0
    tasks = [T.task("scan", backend=b, device=d, precision="float32", contacts=["hard", "soft"],
                    scans=scans, budget_s=budget) for b, d, _ in ctx.targets()]
    tasks.append(T.task("scan", backend=ORACLE, device="host", precision="float64",
                        contacts=["hard", "soft"], scans=scans, budget_s=math.inf))
    for t, res in host_rows(ctx, tasks):
        if "results" not in res:
            rows.append(ctx.row(name, t["backend"], t["device"], t["precision"], "vy0 scans (host loop)", "-", None,
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
            rows.append(ctx.row(name, t["backend"], t["device"], t["precision"], f"contact={c}, vy0 scan",
                                "intervals where the gradient mispredicts the loss change (coarse)", k["coarse"][0],
                                verdict, "; ".join(
                                    f"{sc_}: {k[sc_][0]}/{npts - 1} at dvy = {spacing[sc_]:.3g} "
                                    f"(+{k[sc_][1]} below the loss rounding {loss_noise[(t['precision'], c)]:.2g}|L|)"
                                    for sc_ in scans)))
            if t["backend"] in (ctx.reference, ORACLE):
                series["scans"][f"{t['backend']}/{t['device']}/{c}"] = {
                    "vy": per[(c, "coarse")]["vy"], "loss": per[(c, "coarse")]["loss"],
                    "dvy": [g[1] for g in per[(c, "coarse")]["grad"]]}
    series["gd_step"] = step_len
    return rows, series


def exp_projectile_horizon(ctx: StressContext) -> Result:
    """Horizon (steps) sweep: gradient size and float32 gradient error as the rollout lengthens."""
    name = "projectile-horizon"
    horizons = (90, 180, 720) if ctx.quick else (45, 90, 180, 360, 720, 1440)
    specs = [ctx.spec(SC.name, b, d, "float32", {"contact": c, "steps": n, "iters": 0})
             for b, d, _ in ctx.targets() for c in CONTACTS for n in horizons]
    rows, series = ctx.skip_rows(name), {}
    acc: dict[tuple[str, str, str], list] = {}
    for s, (rec, out) in zip(specs, ctx.run_cells(specs)):
        c, n = s["params"]["contact"], s["params"]["steps"]
        setting = f"contact={c}, steps={n}"
        if rec["status"] == "error" or out is None:
            rows.append(ctx.error_row(name, s, setting, rec)); continue
        gr = rec.get("gradient") or {}
        g = float(np.linalg.norm(np.asarray(out["grad"], np.float64)))
        ok = rec["status"] == "ok"
        rows.append(ctx.row(name, s["backend"], s["device"], "float32", setting, "gradient rel. error vs float64",
                            gr.get("vs_oracle_rel"), "within derived bound" if ok else "EXCEEDS derived bound",
                            f"|grad| = {g:.4g}; error/bound = {ctx.fmt(rec['error']['vs_oracle'])}"))
        acc.setdefault((s["backend"], s["device"], c), []).append((n, g, gr.get("vs_oracle_rel"), ok))
    for (b, d, c), pts in acc.items():
        pts.sort()
        ns = np.array([p[0] for p in pts], float); gs = np.array([p[1] for p in pts], float)
        good = (gs > 0) & np.isfinite(gs)
        slope = float(np.polyfit(np.log(ns[good]), np.log(gs[good]), 1)[0]) if good.sum() >= 2 else math.nan
        all_ok = all(p[3] for p in pts)
        rel = [p[2] for p in pts]
        worst = max(((r, n_) for n_, r in zip(ns, rel) if isinstance(r, (int, float))), default=(math.nan, 0))
        rows.append(ctx.row(name, b, d, "float32", f"contact={c}, steps {int(ns[0])}..{int(ns[-1])}",
                            "|grad| growth exponent p (|grad| ~ steps^p, least squares)", slope,
                            ("within derived bound at every horizon" if all_ok else "EXCEEDS derived bound at some horizon")
                            + (f"; float32 gradient OFF BY {worst[0]:.0%} at steps={int(worst[1])} (ill-conditioned)"
                               if worst[0] > FD_AGREE else ""),
                            f"|grad| x{gs[-1] / gs[0]:.3g} from {int(ns[0])} to {int(ns[-1])} steps; rel. error: "
                            + ", ".join(f"{int(n_)}:{ctx.fmt(r)}" for n_, r in zip(ns, rel))))
        series[f"{b}/{d}/{c}"] = {"steps": ns.tolist(), "grad": gs.tolist(), "rel": rel}
    return rows, series


# ---- page and plots -----------------------------------------------------------------------------

def lr_matrix(rows: list[Row]) -> str:
    """projectile-lr as one line per (backend, device, optimiser, contact): C/S/D per lr, under
    its legend (goes above the row table on the page)."""
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
    table = "" if not cells_ else tabulate(
        [[*k, *(v.get(lr, "") for lr in sorted(lrs))] for k, v in cells_.items()],
        headers=["backend", "device", "precision", "optimiser", "contact", *[f"lr {lr:g}" for lr in sorted(lrs)]],
        tablefmt="github", disable_numparse=True)
    return ("C converged, S stalled, **D** diverged (GD: the backend's own device loop; "
            f"clip, adam: host loop with the backend's gradient; {ORACLE}: float64 Python).\n\n" + table)


def lr_table_rows(rows: list[Row]) -> list[Row]:
    """The rows the page tables below the matrix: predictions and boundaries (not per-lr rows)."""
    return [r for r in rows if "lr=" not in r["setting"]]


def plot_projectile_lr(series: dict[str, Any], path: Path, style: Style) -> None:
    import matplotlib.pyplot as plt
    hist = series.get("histories", {})
    methods = T.OPTIMISERS
    fig, axes = plt.subplots(3, 3, figsize=(12, 9), sharex=True)
    for key, h in sorted(hist.items()):
        b, d, m, c, lr = key.split("/")
        ax = axes[methods.index(m)][CONTACTS.index(c)]
        ax.plot(range(len(h)), log_floor(h, 1e-30), ls="-" if b != ORACLE else ":", lw=1, label=f"{b} lr={lr}")
    for i, m in enumerate(methods):
        for j, c in enumerate(CONTACTS):
            ax = axes[i][j]
            ax.set_yscale("log"); ax.set_title(f"{m}, contact={c}", fontsize=9); ax.grid(True, alpha=0.3)
            if ax.lines:
                ax.legend(fontsize=5)
    for ax in axes[-1]:
        ax.set_xlabel("iteration")
    fig.tight_layout(); fig.savefig(path, dpi=100); plt.close(fig)


def plot_projectile_gradient(series: dict[str, Any], path: Path, style: Style) -> None:
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5))
    for j, c in enumerate(CONTACTS):
        ax = axes[0][j]
        for lbl, rel in sorted(series["lines"].items()):
            if lbl.endswith("/" + c):
                ax.plot(series["h"], log_floor(rel), lw=1, ls="-" if "float32" in lbl else ":",
                        label=lbl.rsplit("/", 1)[0], **style(lbl))
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


def plot_projectile_horizon(series: dict[str, Any], path: Path, style: Style) -> None:
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for lbl, s in sorted(series.items()):
        ls = {"none": "-", "hard": "--", "soft": ":"}[lbl.rsplit("/", 1)[1]]
        axes[0].plot(s["steps"], log_floor(s["grad"]), ls=ls, lw=1, label=lbl, **style(lbl))
        axes[1].plot(s["steps"], log_floor(s["rel"]), ls=ls, lw=1, label=lbl, **style(lbl))
    axes[0].set_ylabel("|grad| (float32)"); axes[1].set_ylabel("float32 gradient rel. error vs float64")
    for ax in axes:
        ax.set_xscale("log"); ax.set_yscale("log"); ax.set_xlabel("steps (dt = 0.025)")
        ax.grid(True, which="both", alpha=0.3); ax.legend(fontsize=5)
    fig.tight_layout(); fig.savefig(path, dpi=110); plt.close(fig)


EXPERIMENTS: dict[str, Experiment] = {e.name: e for e in (
    Experiment("projectile-lr", "learning-rate sweep x contact x optimiser", exp_projectile_lr,
               plot_projectile_lr, extra_markdown=lr_matrix, table_rows=lr_table_rows),
    Experiment("projectile-gradient", "gradient quality: hard vs soft vs finite differences",
               exp_projectile_gradient, plot_projectile_gradient),
    Experiment("projectile-horizon", "horizon sweep: gradient growth", exp_projectile_horizon,
               plot_projectile_horizon),
)}
