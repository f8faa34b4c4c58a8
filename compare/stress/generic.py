"""The stress experiments that name no scenario: ``ulps`` (float32 error distributions, every
variant; the cases come from compare/stress/ulp_cases.py) and ``races`` (every scenario in 'all' run
twice, CPU against GPU, and the deliberately racy controls of ``Backend.control_variants``)."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import BinaryIO

import numpy as np

import backends
from backends.base import DEFAULT_VARIANT
import scenarios
from compare.render.figure_check import place_legends
from compare.spec import Cell
from compare.stress.numerics import (Experiment, Result, Series, StressContext, Style, bitwise_differences,
                                     check_of, log_floor, ulps)
from compare.stress.ulp_cases import ulp_cases
from scenarios.base import Precision


CONTROL = "control: "       # a racy control's row names what is wrong with it after this, in its detail


def race_verdict(device: str, differing: int, oracle_ok: tuple[bool, bool]) -> str:
    """Verdict of a racy control: flagged if two runs differ or a run misses the oracle's bound.
    The words say which evidence caught it: a race that gives the same wrong answer in both runs
    (no element differs) is caught by the oracle alone, and the verdict says so, so that a row of
    0 differing elements never reads as a detection by differing runs."""
    if differing != 0 or not all(oracle_ok):
        why = []
        if differing != 0:
            why.append(f"runs differ in {differing} values" if differing > 0 else "runs differ in shape")
        if not all(oracle_ok):
            why.append("outside the oracle's bound" + ("" if differing else
                                                     "; the two runs agree bitwise, wrong alike"))
        return "RACE DETECTED (" + ", ".join(why) + ")"
    return "race not observable on CPU" if device == "cpu" else "MISSED: race not flagged"


def exp_ulps(ctx: StressContext) -> Result:
    """float32 error distributions in ulps (every scenario's ulp cases), every variant."""
    name = "ulps"
    cases = [(sc.name, prm, key, setting) for sc in scenarios.SCENARIOS.values()
             for prm, key, setting in ulp_cases(sc.name, ctx.quick)]
    planned = [(case, ctx.spec(case[0], b, d, "float32", case[1], v))
               for b, d, v in ctx.targets(variants=True) for case in cases]
    refs = {}
    for scn, prm, key, _ in cases:
        sc = scenarios.get(scn)
        p = sc.params(prm)
        refs[(scn, json.dumps(prm))] = sc.oracle(p, sc.inputs(p, "float32"), Precision.FLOAT32)[key]
    results = ctx.run_cells([s for _, s in planned])
    rows, series = ctx.skip_rows(name, variants=True), {}
    defaults = {}
    for ((scn, prm, _, _), s), (rec, out) in zip(planned, results):     # keyed on the case's overrides
        if s.variant == DEFAULT_VARIANT and out is not None:
            defaults[(s.backend, str(s.device), scn, json.dumps(prm))] = out
    for ((scn, prm, key, case_setting), s), (rec, out) in zip(planned, results):
        setting = f"{case_setting}, variant={s.variant}"
        if rec.status == "error" or out is None:
            rows.append(ctx.error_row(name, s, setting, rec)); continue
        e = ulps(out[key], refs[(scn, json.dumps(prm))]).ravel()
        finite = np.isfinite(e)
        ok = rec.status == "ok"
        q = np.percentile(e[finite], [50, 99]) if finite.any() else [math.nan, math.nan]
        rows.append(ctx.row(name, s.backend, s.device, "float32", setting, "max error [ulps of the result]",
                            float(np.max(e)) if finite.all() else math.inf,
                            "within derived bound" if ok else "EXCEEDS derived bound",
                            f"median {q[0]:.3g}, p99 {q[1]:.3g} ulps; {100 * np.mean(e > 0.5):.3g}% not correctly "
                            f"rounded; scenario metric {ctx.fmt(check_of(rec).vs_oracle)} "
                            f"(bound {ctx.fmt(check_of(rec).tolerance)})"))
        if np.ndim(out[key]) == 2:        # an image: its per-pixel distribution is plotted
            srt = np.sort(e[finite])
            idx = np.unique(np.geomspace(1, srt.size, 200).astype(int)) - 1
            series[ctx.label(s)] = {"ulps": srt[idx].tolist(), "frac": ((idx + 1) / srt.size).tolist()}
        if s.variant != DEFAULT_VARIANT:
            base = defaults.get((s.backend, str(s.device), scn, json.dumps(prm)))
            if base is None:
                continue
            diff = bitwise_differences({key: out[key]}, {key: base[key]})
            change = ulps(out[key], base[key].astype(np.float64))
            rows.append(ctx.row(name, s.backend, s.device, "float32", setting, "elements changed by the variant",
                                diff, "bitwise identical to default" if diff == 0 else
                                f"changes results (max {float(np.max(change)):.3g} ulps); "
                                + ("still within derived bound" if ok else "EXCEEDS derived bound"),
                                f"of {out[key].size}"))
    return rows, series


def controls(ctx: StressContext) -> list[tuple[Cell, str]]:
    """(spec, what is wrong) of every racy control a chosen backend offers, at quick sizes."""
    out = []
    for b in ctx.backends:
        for scn, variants in backends.get(b).control_variants.items():
            sc = scenarios.get(scn)
            p = sc.params({}, quick=True)
            prm = {k: getattr(p, k) for k in sc.quick}
            out += [(ctx.spec(scn, b, d, "float32", prm, var), why) for var, why in variants.items()
                    for d in ctx.devices if not ctx.why_not(b, d)]
    return out


def exp_races(ctx: StressContext) -> Result:
    """Every cell twice (bitwise), CPU against GPU, and the racy control kernels."""
    name = "races"
    precisions = ("float32",) if ctx.quick else ("float32", "float64")
    cases = [(sc.name, sc.params({}, quick=True)) for sc in scenarios.SCENARIOS.values() if sc.in_all]
    specs = []
    for b, d, _ in ctx.targets():
        for scn, p in cases:
            for prec in ctx.precisions(b, d, precisions):
                prm = {k: getattr(p, k) for k in scenarios.get(scn).quick}
                specs += [ctx.spec(scn, b, d, prec, prm)] * 2
    control = controls(ctx)
    wrong = {(s.backend, s.scenario, s.variant): why for s, why in control}
    specs += [s for s, _ in control for _ in range(2)]
    results = ctx.run_cells(specs, fresh_process=True)      # run to run: two separate processes
    rows, first_run = ctx.skip_rows(name, precisions=precisions), {}
    for i in range(0, len(specs), 2):
        s = specs[i]
        (ra, oa), (rb, ob) = results[i], results[i + 1]
        setting = f"{s.scenario} (quick sizes)" + ("" if s.variant == DEFAULT_VARIANT else f", variant={s.variant}")
        if oa is None or ob is None:
            rows.append(ctx.error_row(name, s, setting, ra if oa is None else rb)); continue
        diff = bitwise_differences(oa, ob)
        why = wrong.get((s.backend, s.scenario, s.variant))
        if why is not None:
            verdict = race_verdict(str(s.device), diff, (ra.status == "ok", rb.status == "ok"))
            rows.append(ctx.row(name, s.backend, s.device, s.precision, setting,
                                "elements differing between two runs", diff, verdict,
                                f"error vs oracle {ctx.fmt(check_of(ra).vs_oracle)} and "
                                f"{ctx.fmt(check_of(rb).vs_oracle)} (bound {ctx.fmt(check_of(ra).tolerance)}); "
                                f"{CONTROL}{why}"))
            continue
        first_run[(s.scenario, s.backend, str(s.device), str(s.precision))] = (ra, oa)
        rows.append(ctx.row(name, s.backend, s.device, s.precision, setting,
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
            p = sc.params(ra.params)
            dist = sc.distance(p, sc.inputs(p, prec), og, oa)
            both = ra.status == "ok" and rg.status == "ok"
            rows.append(ctx.row(name, b, "cpu vs cuda", prec, f"{scn} (quick sizes)", "scenario distance cpu vs cuda",
                                dist, "bitwise identical" if diff == 0 else
                                ("differ, both within derived bound" if both else "DIFFER, one outside its bound"),
                                f"{diff} values differ bitwise"))
    return rows, {}


def plot_ulps(series: Series, path: Path | BinaryIO, style: Style) -> None:
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for lbl, s in sorted(series.items()):
        st = style(lbl)
        st["marker"] = None
        ax.plot(log_floor(s["ulps"], 1e-3), s["frac"], lw=1, label=lbl, ls="--" if "fastmath" in lbl else "-", **st)
    ax.set_xscale("log"); ax.set_xlabel("error [ulps of the correctly rounded pixel] (0 drawn at 1e-3)")
    ax.set_ylabel("fraction of pixels with error <= x"); ax.set_title("image outputs, float32", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    place_legends([ax], fontsize=6)     # clear of the curves, else below the axes
    fig.savefig(path, dpi=110, format="png"); plt.close(fig)


EXPERIMENTS: dict[str, Experiment] = {e.name: e for e in (
    Experiment("ulps", "float32 error distributions in ulps, fast-math", exp_ulps, plot_ulps,
               look="The share of an image's pixels within x ulps of the correctly rounded value, per framework "
                    "and variant: a curve further left and higher is closer to correctly rounded; fast-math "
                    "variants are dashed."),
    Experiment("races", "run-to-run, CPU vs GPU, racy control kernel", exp_races),
)}
