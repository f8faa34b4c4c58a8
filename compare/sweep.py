"""``python -m compare sweep``: the measurement sweeps of docs/measurement.md.

    sweep bandwidth   launch overhead, copy roofline, SAXPY size sweep
    sweep error       time against error: precision, fast-math variants, dt (particles,
                      projectile) against a converged float64 reference, SDF resolution
    sweep scaling     particles over n: steps/s, particle-steps/s, memory
    sweep all         the three above
    sweep report F... rebuild the page and plots from saved sweep.json files (no rerun)

Every measurement is one cell run by compare.cells.run (one worker process each, the same
protocol as ``python -m compare``). Records accumulate in DIR/sweep.json (a cell run again
replaces its old record; --resume skips cells already ok), and every run rebuilds the Markdown
page (--page, default DIR/measurement.md) and the PNGs in DIR from the whole file.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import shlex
import sys
from pathlib import Path
from typing import Any, Callable

import numpy as np

import backends
import scenarios
from compare import cells, environment, plots_measure
from compare.report import atomic_write
from scenarios.base import PRECISIONS, ParamError

EXIT_OK, EXIT_FAIL, EXIT_USAGE = 0, 1, 2
KINDS = ("bandwidth", "error", "scaling")

# Knob values per (sweep, device, quick). Sizes are exponents of 2; CPU sizes stop where a cell
# still takes seconds on a small machine, GPU sizes where the arrays are ~1 GiB.
SAXPY_EXP = {("cpu", False): range(10, 25, 2), ("cpu", True): range(10, 21, 2),
             ("cuda", False): range(10, 29, 2), ("cuda", True): range(10, 23, 2)}
COPY_N = {("cpu", False): 1 << 25, ("cpu", True): 1 << 22,
          ("cuda", False): 1 << 28, ("cuda", True): 1 << 24}
SCALING_N = {("cpu", False): (256, 4096, 65536, 1 << 20), ("cpu", True): (256, 4096, 65536),
             ("cuda", False): (256, 4096, 65536, 1 << 20, 1 << 22, 1 << 24),
             ("cuda", True): (256, 4096, 65536, 1 << 20)}
SDF_RES = {("cpu", False): (64, 128, 256, 512, 1024, 2048), ("cpu", True): (32, 64, 128),
           ("cuda", False): (64, 128, 256, 512, 1024, 2048, 4096), ("cuda", True): (32, 64, 128)}
# dt halves down the list; every dt divides the fixed simulated time exactly (T = steps * dt).
PARTICLES_DT = {False: (0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125), True: (0.02, 0.01, 0.005)}
PROJECTILE_DT = {False: (0.05, 0.025, 0.0125, 0.00625, 0.003125, 0.0015625),
                 True: (0.05, 0.025, 0.0125)}
PARTICLES_T = 3.0          # the scenario's default 300 steps of 0.01 s
PROJECTILE_T = 4.5         # the scenario's default 180 steps of 0.025 s
REF_FACTOR = 16            # converged reference: dt_ref = smallest swept dt / REF_FACTOR
SDF_EVAL = 2001            # evaluation grid (per axis) of the SDF reconstruction error
CHECK_SAMPLE = 1 << 16     # items checked against the oracle in large per-item cells


class UsageError(Exception):
    pass


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit 2
        raise UsageError(message)


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="python -m compare sweep", description=__doc__)
    p.add_argument("kind", help="bandwidth | error | scaling | all | report")
    p.add_argument("files", nargs="*", help="report: sweep.json files to merge")
    p.add_argument("--backends", default=",".join(backends.BACKENDS))
    p.add_argument("--devices", default=",".join(backends.DEVICES))
    p.add_argument("--precision", default=None,
                   help="bandwidth/scaling: float32 (default); error: float32,float64 (default)")
    p.add_argument("--scenarios", default="saxpy,sdf,particles,projectile",
                   help="error: which scenarios to sweep")
    p.add_argument("--contact", default="soft", choices=("none", "hard", "soft"),
                   help="error: projectile contact model")
    p.add_argument("--record-every", type=int, default=0, metavar="K",
                   help="scaling: also keep every K-th particle state (default 0: no trajectory)")
    p.add_argument("--quick", action="store_true", help="few, small points (minutes on 2 cores)")
    p.add_argument("--repeat", type=int, default=None, help="minimum timed calls (10; quick 3)")
    p.add_argument("--min-time", type=float, default=None, help="minimum timed s (0.2; quick 0.05)")
    p.add_argument("--timeout", type=float, default=600.0, help="seconds before a cell is killed")
    p.add_argument("--cache", default="cold", choices=("cold", "warm"),
                   help="framework kernel caches for the first call (docs/measurement.md)")
    p.add_argument("--out", default="results/sweep", help="directory of sweep.json and PNGs")
    p.add_argument("--page", default=None, help="Markdown page (default OUT/measurement.md)")
    p.add_argument("--title", default=None, help="page title")
    p.add_argument("--notes", default=None, metavar="FILE",
                   help="Markdown inserted into the page as its Notes section")
    p.add_argument("--resume", action="store_true", help="skip cells already ok in OUT/sweep.json")
    p.add_argument("--fresh", action="store_true", help="drop OUT/sweep.json's records first")
    p.add_argument("--no-plots", action="store_true")
    return p


def split(value: str, allowed, what: str) -> list[str]:
    items = [v.strip() for v in value.split(",") if v.strip()]
    bad = [v for v in items if v not in allowed]
    if not items or bad:
        raise ParamError(f"unknown {what} {(bad or [''])[0]!r} (allowed: {', '.join(allowed)})")
    return items


# ---- plans ----------------------------------------------------------------------------------
def cell(kind: str, role: str, scenario: str, backend: str, device: str, precision: str,
         params: dict[str, Any], variant: str = "default", knob: dict[str, Any] | None = None,
         **extra: Any) -> dict[str, Any]:
    return {"scenario": scenario, "backend": backend, "device": device, "precision": precision,
            "variant": variant, "params": params, "sweep": kind, "role": role,
            "knob": knob or {}, **extra}


def plan_bandwidth(args, names, devices) -> list[dict[str, Any]]:
    precisions = split(args.precision or "float32", PRECISIONS, "precision")
    specs = []
    for dev in devices:
        for be in names:
            for prec in precisions:
                big = {"check_sample": CHECK_SAMPLE, "save_outputs": False}
                specs.append(cell("bandwidth", "launch", "launch", be, dev, prec, {"n": 1}))
                specs.append(cell("bandwidth", "copy", "copy", be, dev, prec,
                                  {"n": COPY_N[dev, args.quick]}, **big))
                for e in SAXPY_EXP[dev, args.quick]:
                    specs.append(cell("bandwidth", "saxpy", "saxpy", be, dev, prec, {"n": 1 << e},
                                      knob={"name": "n", "value": 1 << e}, **big))
    return specs


def plan_error(args, names, devices) -> list[dict[str, Any]]:
    precisions = split(args.precision or "float32,float64", PRECISIONS, "precision")
    chosen = split(args.scenarios, ("saxpy", "sdf", "particles", "projectile"), "scenario")
    specs = []
    for dev in devices:
        for be in names:
            for variant in backends.get(be).variants:
                for prec in precisions:
                    for sc in chosen:
                        for params, knob in error_points(sc, dev, args):
                            specs.append(cell("error", sc, sc, be, dev, prec, params, variant, knob))
    return specs


def error_points(sc: str, dev: str, args) -> list[tuple[dict[str, Any], dict[str, Any]]]:
    if sc == "saxpy":
        n = scenarios.get("saxpy").params(quick=args.quick).n
        return [({"n": n}, {"name": "precision", "value": None})]
    if sc == "sdf":
        return [({"width": r, "height": r}, {"name": "resolution", "value": r})
                for r in SDF_RES[dev, args.quick]]
    if sc == "particles":
        return [({"dt": dt, "steps": round(PARTICLES_T / dt)}, {"name": "dt", "value": dt})
                for dt in PARTICLES_DT[args.quick]]
    return [({"dt": dt, "steps": round(PROJECTILE_T / dt), "iters": 0, "contact": args.contact},
             {"name": "dt", "value": dt}) for dt in PROJECTILE_DT[args.quick]]


def plan_scaling(args, names, devices) -> list[dict[str, Any]]:
    precisions = split(args.precision or "float32", PRECISIONS, "precision")
    if args.record_every < 0:
        raise ParamError(f"--record-every must be >= 0, got {args.record_every}")
    return [cell("scaling", "particles", "particles", be, dev, prec,
                 {"n": n, "record_every": args.record_every},
                 knob={"name": "n", "value": n}, check_sample=4096, save_outputs=False)
            for dev in devices for be in names for prec in precisions
            for n in SCALING_N[dev, args.quick]]


# ---- converged float64 references (time against error) --------------------------------------
def particles_positions(params: dict[str, Any], dt: float, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Float64 rollout of the scenario's exact step (scenarios/particles.py) from its float64
    initial state: positions at T = steps * dt."""
    sc = scenarios.get("particles")
    p = sc.params({k: v for k, v in params.items() if k not in ("dt", "steps")})
    s0 = sc.inputs(p, "float64")
    x, y, u, v = (s0[k].astype(np.float64).copy() for k in ("x0", "y0", "vx0", "vy0"))
    g, damp, bounce, rad = p.gravity, p.damping, p.bounce, p.radius
    lo, hi, gdt = -1.0 + rad, 1.0 - rad, g * dt
    for _ in range(steps):
        v += gdt
        x += u * dt
        y += v * dt
        hit = y < rad
        y[hit] = rad; v[hit] *= -bounce; u[hit] *= damp
        hit = x < lo
        x[hit] = lo; u[hit] *= -bounce
        hit = x > hi
        x[hit] = hi; u[hit] *= -bounce
    return x, y


def projectile_loss_grad(params: dict[str, Any], dt: float, steps: int) -> tuple[float, np.ndarray]:
    """Float64 loss and adjoint gradient at v0 (scenarios/projectile.py rollout + adjoint)."""
    from scenarios import projectile as pj
    p = scenarios.get("projectile").params({k: v for k, v in params.items() if k not in ("dt", "steps")})
    c = {k: float(getattr(p, k)) for k in pj.CONSTANTS}
    c["dt"] = dt
    (x, y, _, _), tape = pj.rollout(c, p.contact, steps, p.vx0, p.vy0)
    dx, dy = x - p.target_x, y - p.target_y
    return dx * dx + dy * dy, np.array(pj.adjoint(c, tape, 2.0 * dx, 2.0 * dy))


def particles_error(px, py, rx, ry) -> dict[str, float]:
    d = np.hypot(np.asarray(px, np.float64) - rx, np.asarray(py, np.float64) - ry)
    return {"error": float(np.sqrt(np.mean(d * d))), "max": float(d.max())}


def projectile_error(loss, grad, rloss, rgrad) -> dict[str, float]:
    el = abs(float(np.asarray(loss).reshape(())) - rloss) / abs(rloss)
    eg = float(np.linalg.norm(np.asarray(grad, np.float64).reshape(2) - rgrad) / np.linalg.norm(rgrad))
    return {"error": max(el, eg), "loss_rel": el, "grad_rel": eg}


def sdf_error(image: np.ndarray) -> dict[str, float]:
    """Bilinear reconstruction of the image against the analytic field on a fixed fine grid."""
    from scenarios.sdf import sdf_field
    img = np.asarray(image, np.float64)
    h, w = img.shape
    t = np.linspace(-1.0, 1.0, SDF_EVAL)
    exact = sdf_field(t[None, :], t[:, None])

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


METRICS = {
    "sdf": f"max |bilinear(image) - f| over a {SDF_EVAL}x{SDF_EVAL} grid, f the analytic field in float64",
    "particles": "RMS over particles of |position - reference| [m] at the same simulated time",
    "projectile": "max(rel. error of loss, rel. error of |grad|) at v0 against the reference",
    "saxpy": "scenario metric against the float64 oracle: max |err|/(|a x|+|y|)",
}


class References:
    """Converged references, computed once per (scenario, parameters without the knob)."""

    def __init__(self, dts: dict[str, tuple[float, ...]]) -> None:
        self.dts = dts
        self.cache: dict[str, tuple[Any, dict[str, Any]]] = {}

    def get(self, scenario: str, params: dict[str, Any]) -> tuple[Any, dict[str, Any]]:
        key = scenario + json.dumps({k: v for k, v in params.items() if k not in ("dt", "steps")},
                                    sort_keys=True)
        if key not in self.cache:
            T = PARTICLES_T if scenario == "particles" else PROJECTILE_T
            fn: Callable = particles_positions if scenario == "particles" else projectile_loss_grad
            dt = min(self.dts[scenario]) / REF_FACTOR
            ref = fn(params, dt, round(T / dt))
            coarse = fn(params, 2 * dt, round(T / (2 * dt)))
            err = (particles_error(*coarse, *ref) if scenario == "particles"
                   else projectile_error(*coarse, *ref))["error"]
            self.cache[key] = (ref, {"dt": dt, "steps": round(T / dt), "simulated_time_s": T,
                                     "self_difference": err,
                                     "note": "float64 NumPy rollout; self_difference: same metric "
                                             "against a reference at 2 dt (its own error scale)"})
        return self.cache[key]


def converged(rec: dict[str, Any], outputs: dict[str, np.ndarray] | None, refs: References) -> dict[str, Any] | None:
    sc = rec["scenario"]
    if rec.get("sweep") != "error" or rec.get("status") not in ("ok", "mismatch"):
        return None
    if sc == "saxpy":
        return {"error": rec["error"]["vs_oracle"], "metric": METRICS[sc],
                "reference": {"note": "float64 oracle of the same rounded inputs"}}
    if outputs is None:
        return None
    if sc == "sdf":
        return {**sdf_error(outputs["image"]), "metric": METRICS[sc],
                "reference": {"eval_grid": SDF_EVAL, "note": "analytic field, float64"}}
    ref, info = refs.get(sc, rec["params"])
    if sc == "particles":
        e = particles_error(outputs["x"], outputs["y"], *ref)
    else:
        e = projectile_error(outputs["loss"], outputs["grad"], *ref)
    return {**e, "metric": METRICS[sc], "reference": info}


# ---- running --------------------------------------------------------------------------------
def key(rec: dict[str, Any]) -> str:
    return json.dumps([rec.get("sweep"), rec["scenario"], rec["backend"], rec["device"],
                       rec["precision"], rec.get("variant", "default"), rec.get("params")],
                      sort_keys=True)


def load(path: Path) -> dict[str, Any]:
    try:
        data = json.loads(path.read_text())
        return {"runs": data.get("runs", []), "records": data["records"]}
    except (OSError, ValueError, KeyError) as exc:
        raise ParamError(f"cannot read sweep results {path}: {exc}") from None


def save(path: Path, data: dict[str, Any]) -> None:
    from compare.worker import jsonable
    atomic_write(path, json.dumps(jsonable(data), indent=1))


def run_specs(specs, probes, args, data, path: Path) -> None:
    """One cell at a time (never concurrently: they would share cores and the GPU)."""
    refs = References({"particles": PARTICLES_DT[args.quick], "projectile": PROJECTILE_DT[args.quick]})
    index = {key(r): i for i, r in enumerate(data["records"])}
    repeat = args.repeat or (3 if args.quick else 10)
    min_time = args.min_time if args.min_time is not None else (0.05 if args.quick else 0.2)
    for i, spec in enumerate(specs):
        sc = scenarios.get(spec["scenario"])
        spec["params"] = dataclasses.asdict(sc.params(spec["params"]))
        spec.update({"repeat": repeat, "min_time": min_time, "cache": args.cache})
        k = key(spec)
        if args.resume and k in index and data["records"][index[k]].get("status") == "ok":
            continue
        label = f"[{i + 1}/{len(specs)}] {spec['sweep']} {spec['scenario']}/{spec['backend']}/" \
                f"{spec['device']}/{spec['precision']}/{spec['variant']} {spec['knob'] or ''}"
        why = probes[spec["backend"]]["available"].get(spec["device"])
        ident = {k2: spec[k2] for k2 in ("scenario", "backend", "device", "precision", "variant",
                                         "params", "sweep", "role", "knob")}
        if why:
            rec = {**ident, "status": "skipped", "reason": why, "time": None, "error": None}
        else:
            got, outputs = cells.run(spec, timeout=args.timeout)
            rec = {**ident, **got}
            rec.setdefault("time", None); rec.setdefault("error", None)
            conv = converged(rec, outputs, refs)
            if conv is not None:
                rec["converged"] = conv
        print(f"{label}: {rec['status']} {rec.get('reason', '')}".rstrip(), file=sys.stderr, flush=True)
        if k in index:
            data["records"][index[k]] = rec
        else:
            index[k] = len(data["records"])
            data["records"].append(rec)
        save(path, data)


def rebuild(data: dict[str, Any], args, sources: list[str]) -> Path:
    """Write the PNGs into --out and the Markdown page (--page); returns the page's path."""
    out = Path(args.out)
    page = Path(args.page) if args.page else out / "measurement.md"
    notes = ""
    if args.notes:
        try:
            notes = Path(args.notes).read_text()
        except OSError as exc:
            raise ParamError(f"cannot read --notes {args.notes}: {exc}") from None
    written = plots_measure.write_plots(data["records"], out) if not args.no_plots else {}
    cmd = ["python -m compare sweep report", *map(shlex.quote, [*sources, "--out", str(out),
                                                                "--page", str(page)])]
    if args.title:
        cmd += ["--title", shlex.quote(args.title)]
    if args.notes:
        cmd += ["--notes", shlex.quote(args.notes)]
    text = plots_measure.page(data, written, page, args.title, sources, " ".join(cmd), notes)
    atomic_write(page, text)
    return page


def cmd_run(args, argv: list[str]) -> int:
    from compare.cli import probe_all
    names = split(args.backends, list(backends.BACKENDS), "backend")
    devices = split(args.devices, backends.DEVICES, "device")
    if args.repeat is not None and args.repeat < 1:
        raise ParamError(f"--repeat must be >= 1, got {args.repeat}")
    if not args.timeout > 0:
        raise ParamError(f"--timeout must be > 0, got {args.timeout}")
    kinds = KINDS if args.kind == "all" else (args.kind,)
    planners = {"bandwidth": plan_bandwidth, "error": plan_error, "scaling": plan_scaling}
    specs = [s for k in kinds for s in planners[k](args, names, devices)]
    out = Path(args.out)
    path = out / "sweep.json"
    data = load(path) if path.exists() and not args.fresh else {"runs": [], "records": []}
    probes = probe_all(names)
    env = environment.collect(["sweep", *map(shlex.quote, argv)])   # a command one can paste
    env["backends"] = probes
    env["kinds"] = list(kinds)
    data["runs"].append(env)
    save(path, data)
    run_specs(specs, probes, args, data, path)
    page = rebuild(data, args, [str(path)])
    print(plots_measure.summary(data["records"]))
    print(f"wrote {path} and {page}")
    bad = [r for r in data["records"] if r["status"] in ("mismatch", "error")]
    return EXIT_FAIL if bad else EXIT_OK


def cmd_report(args) -> int:
    if not args.files:
        raise ParamError("report needs at least one sweep.json")
    merged: dict[str, Any] = {"runs": [], "records": []}
    seen: dict[str, int] = {}
    for f in args.files:
        data = load(Path(f))
        merged["runs"] += data["runs"]
        for r in data["records"]:          # a later file's record of the same cell wins
            k = key(r)
            if k in seen:
                merged["records"][seen[k]] = r
            else:
                seen[k] = len(merged["records"])
                merged["records"].append(r)
    rebuild(merged, args, list(args.files))
    print(plots_measure.summary(merged["records"]))
    return EXIT_OK


def main(argv: list[str]) -> int:
    try:
        args = build_parser().parse_args(argv)
        if args.kind == "report":
            return cmd_report(args)
        if args.kind not in (*KINDS, "all"):
            raise UsageError(f"unknown sweep {args.kind!r} (bandwidth, error, scaling, all, report)")
        if args.files:
            raise UsageError(f"unexpected argument {args.files[0]!r}")
        return cmd_run(args, argv)
    except (UsageError, ParamError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
