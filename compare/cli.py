"""``python -m compare``: list | all | <scenario> [options]. Knows only the registries."""
from __future__ import annotations

import argparse
import concurrent.futures
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

import backends
import scenarios
from compare import cells, environment, report
from scenarios.base import PRECISIONS, ParamError

EXIT_OK, EXIT_FAIL, EXIT_USAGE = 0, 1, 2


class UsageError(Exception):
    pass


class Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit 2, no usage dump
        raise UsageError(message)


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="python -m compare", description=__doc__)
    p.add_argument("command", help="list | all | " + " | ".join(scenarios.SCENARIOS))
    p.add_argument("--backends", default=",".join(backends.BACKENDS), help="comma-separated")
    p.add_argument("--devices", default=",".join(backends.DEVICES), help="cpu,cuda")
    p.add_argument("--precision", default=",".join(PRECISIONS), help="float32,float64")
    p.add_argument("--variants", default="default",
                   help="comma-separated variants (e.g. default,fastmath) or 'all'")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="scenario parameter (repeatable)")
    p.add_argument("--quick", action="store_true", help="small sizes (CI)")
    p.add_argument("--repeat", type=int, default=10, help="minimum timed calls per cell")
    p.add_argument("--min-time", type=float, default=0.2, help="minimum timed seconds per cell")
    p.add_argument("--timeout", type=float, default=900.0, help="seconds before a cell is killed")
    p.add_argument("--out", default="results", help="output directory")
    p.add_argument("--save-arrays", action="store_true", help="write inputs/outputs per cell (npz)")
    p.add_argument("--no-plots", action="store_true")
    return p


def split(value: str, allowed: tuple[str, ...] | list[str], what: str) -> list[str]:
    items = [v.strip() for v in value.split(",") if v.strip()]
    if not items:
        raise ParamError(f"--{what} is empty (allowed: {', '.join(allowed)})")
    for v in items:
        if v not in allowed:
            raise ParamError(f"unknown {what.rstrip('s')} {v!r} (allowed: {', '.join(allowed)})")
    return items


def parse_sets(pairs: list[str], chosen: list[scenarios.Scenario], quick: bool) -> dict[str, dict[str, Any]]:
    raw: dict[str, str] = {}
    for pair in pairs:
        if "=" not in pair:
            raise ParamError(f"--set expects KEY=VALUE, got {pair!r}")
        k, v = pair.split("=", 1)
        raw[k.strip()] = v.strip()
    per: dict[str, dict[str, Any]] = {}
    for sc in chosen:
        names = {f for f in sc.Params.__dataclass_fields__}
        per[sc.name] = {k: v for k, v in raw.items() if k in names}
        sc.params(per[sc.name], quick=quick)          # validate now: bad input never reaches a worker
    unknown = [k for k in raw if not any(k in sc.Params.__dataclass_fields__ for sc in chosen)]
    if unknown:
        known = sorted({f for sc in chosen for f in sc.Params.__dataclass_fields__})
        raise ParamError(f"unknown parameter {unknown[0]!r} (known: {', '.join(known)})")
    return per


def probe_all(names: list[str]) -> dict[str, dict[str, Any]]:
    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, len(names))) as pool:
        return dict(zip(names, pool.map(cells.probe, names)))


def cmd_list() -> int:
    probes = probe_all(list(backends.BACKENDS))
    print("scenarios:")
    for sc in scenarios.SCENARIOS.values():
        print(f"  {sc.name:11s} {sc.title}; defaults: {sc.describe_params()}")
    print("backends (device: available, or why not):")
    for name, b in backends.BACKENDS.items():
        avail = probes[name]["available"]
        devs = "; ".join(f"{d}: {'yes' if avail.get(d) is None else avail.get(d)}" for d in backends.DEVICES)
        ref = " (reference)" if b.is_reference else ""
        print(f"  {name:7s}{ref} gradient={b.gradient_method} variants={','.join(b.variants)}; {devs}")
    return EXIT_OK


def plan(args, chosen) -> tuple[list[dict[str, Any]], dict[str, dict[str, Any]]]:
    names = split(args.backends, list(backends.BACKENDS), "backends")
    devices = split(args.devices, backends.DEVICES, "devices")
    precisions = split(args.precision, PRECISIONS, "precision")
    all_variants = sorted({v for b in backends.BACKENDS.values() for v in b.variants})
    variants = all_variants if args.variants == "all" else split(args.variants, all_variants, "variants")
    if args.repeat < 1:
        raise ParamError(f"--repeat must be >= 1, got {args.repeat}")
    if not args.timeout > 0:
        raise ParamError(f"--timeout must be > 0, got {args.timeout}")
    sets = parse_sets(args.set, chosen, args.quick)
    ref = backends.reference()
    order = sorted(names, key=lambda n: n != ref)      # the reference runs first
    specs = []
    for sc in chosen:
        for name in order:
            for device in devices:
                for precision in precisions:
                    for variant in variants:
                        if variant not in backends.get(name).variants:
                            continue
                        specs.append({"scenario": sc.name, "backend": name, "device": device,
                                      "precision": precision, "variant": variant,
                                      "params": sets[sc.name], "quick": args.quick,
                                      "repeat": args.repeat, "min_time": args.min_time,
                                      "save_inputs": args.save_arrays})
    return specs, probe_all(order)


def run_specs(specs, probes, args) -> tuple[list[dict[str, Any]], dict[int, dict[str, np.ndarray]]]:
    from tqdm import tqdm
    records: list[dict[str, Any]] = []
    outputs: dict[int, dict[str, np.ndarray]] = {}
    quiet = bool(os.environ.get("CI")) or not sys.stderr.isatty()
    bar = tqdm(specs, disable=quiet, unit="cell", file=sys.stderr)
    for spec in bar:
        key = f"{spec['scenario']}/{spec['backend']}/{spec['device']}/{spec['precision']}/{spec['variant']}"
        bar.set_description(key)
        base = {k: spec[k] for k in ("scenario", "backend", "device", "precision", "variant")}
        why = probes[spec["backend"]]["available"].get(spec["device"])
        if why:
            sc = scenarios.get(spec["scenario"])
            import dataclasses
            rec = {**base, "params": dataclasses.asdict(sc.params(spec["params"], quick=spec["quick"])),
                   "status": "skipped", "reason": why, "time": None, "error": None}
        else:
            rec, out = cells.run(spec, timeout=args.timeout)
            rec = {**base, **rec}
            rec.setdefault("params", None); rec.setdefault("time", None); rec.setdefault("error", None)
            if out is not None:
                outputs[len(records)] = out
            if quiet:
                print(f"  {key}: {rec['status']} {rec.get('reason', '')}".rstrip(), file=sys.stderr)
        records.append(rec)
    return records, outputs


def fill_vs_reference(records, outputs) -> None:
    """Distance of every port's outputs to the reference backend's, same device and precision
    (or, if the reference did not run there, the reference on another device)."""
    ref = backends.reference()
    for i, r in enumerate(records):
        if i not in outputs or r.get("error") is None:
            continue
        cands = [j for j, q in enumerate(records) if j in outputs and q["backend"] == ref
                 and q["scenario"] == r["scenario"] and q["precision"] == r["precision"]
                 and q["variant"] == "default" and q.get("params") == r.get("params")]
        cands.sort(key=lambda j: records[j]["device"] != r["device"])
        if not cands:
            continue
        sc = scenarios.get(r["scenario"])
        spec_params = sc.params({k: v for k, v in r["params"].items()})
        inputs = sc.inputs(spec_params, r["precision"])
        r["error"]["vs_warp"] = sc.distance(spec_params, inputs, outputs[i], outputs[cands[0]])
        r["error"]["vs_warp_device"] = records[cands[0]]["device"]


def save_arrays(out: Path, records, outputs) -> None:
    d = out / "arrays"
    d.mkdir(parents=True, exist_ok=True)
    for i, r in enumerate(records):
        if i not in outputs:
            continue
        data = dict(r.pop("_inputs", {}) or {})
        data.update(outputs[i])
        name = f"{r['scenario']}-{r['backend']}-{r['device']}-{r['precision']}"
        if r["variant"] != "default":
            name += f"-{r['variant']}"
        np.savez(d / f"{name}.npz", **data)


def cmd_run(args, chosen) -> int:
    specs, probes = plan(args, chosen)
    out = Path(args.out)
    records, outputs = run_specs(specs, probes, args)
    fill_vs_reference(records, outputs)
    env = environment.collect()
    env["backends"] = {n: p for n, p in probes.items()}
    if args.save_arrays:
        save_arrays(out, records, outputs)
    for r in records:
        r.pop("_inputs", None)
    from compare.worker import jsonable
    records = jsonable(records)
    report.write_results(out, env, records)
    if not args.no_plots:
        plots = out / "plots"
        plots.mkdir(parents=True, exist_ok=True)
        report.plot_time_vs_error(records, plots / "time_vs_error.png")
        report.plot_outputs(records, outputs, plots)
    print(report.tables(records))
    print(f"wrote {out / 'results.json'}, results.csv, results.md" + ("" if args.no_plots else ", plots/"))
    bad = [r for r in records if r["status"] in ("mismatch", "error")]
    return EXIT_FAIL if bad else EXIT_OK


def main(argv: list[str]) -> int:
    try:
        args = build_parser().parse_args(argv)
        if args.command == "list":
            return cmd_list()
        if args.command == "all":
            chosen = list(scenarios.SCENARIOS.values())
        else:
            chosen = [scenarios.get(args.command)]
        return cmd_run(args, chosen)
    except (UsageError, ParamError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
