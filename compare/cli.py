"""``python -m compare``: list | all | <scenario> [options]. Knows only the registries."""
from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import json
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
    p.add_argument("command", help="list | all | report | " + " | ".join(scenarios.SCENARIOS))
    p.add_argument("files", nargs="*", help="report: results.json files to merge")
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
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run cells as tasks on a Dask distributed scheduler ('local': a LocalCluster)")
    p.add_argument("--page", default=None, metavar="FILE",
                   help="report: write one Markdown page (environment, tables, pictures) instead of results.*")
    p.add_argument("--title", default=None, help="report --page: the page title")
    p.add_argument("--notes", default=None, metavar="FILE",
                   help="report --page: hand-written Markdown put under the title (never numbers)")
    p.add_argument("--resume", action="store_true",
                   help="keep the cells already in DIR/results.json and run only the missing ones")
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
        params = sc.params(per[sc.name], quick=quick)   # validate now: bad input never reaches a worker
        check_memory(sc, params)
    unknown = [k for k in raw if not any(k in sc.Params.__dataclass_fields__ for sc in chosen)]
    if unknown:
        known = sorted({f for sc in chosen for f in sc.Params.__dataclass_fields__})
        raise ParamError(f"unknown parameter {unknown[0]!r} (known: {', '.join(known)})")
    return per


def check_memory(sc: scenarios.Scenario, params) -> None:
    """Refuse sizes that cannot fit in this machine's memory before any worker starts."""
    import psutil
    need = sc.footprint(params, "float64")
    have = psutil.virtual_memory().total
    if need > have:
        raise ParamError(f"{sc.name} with {sc.size_text(params)} needs about {need / 2**30:.1f} GiB "
                         f"of host memory; this machine has {have / 2**30:.1f} GiB")


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


def cell_key(rec: dict[str, Any]) -> tuple:
    return (rec["scenario"], rec["backend"], rec["device"], rec["precision"],
            rec.get("variant", "default"), json.dumps(rec.get("params"), sort_keys=True))


def executor(scheduler: str | None, timeout: float, runnable: list[dict[str, Any]]):
    """How cells run: local worker processes one at a time (default), or as tasks on a Dask
    distributed scheduler (``--scheduler ADDRESS``, or ``local`` for a one-worker LocalCluster),
    all submitted at once and collected in order. Each task still starts its own worker process,
    so isolation and timeouts are the same; give Dask workers one thread each so cells sharing a
    host do not time each other."""
    if not scheduler:
        return lambda spec: cells.run(spec, timeout=timeout)
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ParamError("--scheduler needs the 'distributed' package (pip install distributed)") from None
    if scheduler == "local":
        cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    else:
        try:
            client = Client(scheduler, timeout="30s")
        except (OSError, TimeoutError) as exc:
            raise ParamError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
    futures = {json.dumps(s, sort_keys=True): client.submit(cells.run, s, timeout, pure=False)
               for s in runnable}
    return lambda spec: futures[json.dumps(spec, sort_keys=True)].result()


def run_specs(specs, probes, args, env, previous=()):
    """Run the cells one after another (never concurrently: they would share cores and the GPU),
    saving results.json after every cell so an interrupted run keeps what it finished."""
    from tqdm import tqdm

    from compare.worker import jsonable
    records: list[dict[str, Any]] = list(previous)
    outputs: dict[int, dict[str, np.ndarray]] = {}
    inputs: dict[int, dict[str, np.ndarray]] = {}
    done = {cell_key(r) for r in records}
    out_dir = Path(args.out)
    quiet = bool(os.environ.get("CI")) or not sys.stderr.isatty()
    runner = executor(args.scheduler, args.timeout, [s for s in specs
                      if not probes[s["backend"]]["available"].get(s["device"])])
    bar = tqdm(specs, disable=quiet, unit="cell", file=sys.stderr)
    for spec in bar:
        key = f"{spec['scenario']}/{spec['backend']}/{spec['device']}/{spec['precision']}/{spec['variant']}"
        bar.set_description(key)
        base = {k: spec[k] for k in ("scenario", "backend", "device", "precision", "variant")}
        sc = scenarios.get(spec["scenario"])
        base["params"] = dataclasses.asdict(sc.params(spec["params"], quick=spec["quick"]))
        if cell_key(base) in done:
            continue
        why = probes[spec["backend"]]["available"].get(spec["device"])
        if why:
            rec = {**base, "status": "skipped", "reason": why, "time": None, "error": None}
        else:
            rec, out = runner(spec)
            rec = {**base, **rec}
            rec.setdefault("params", None); rec.setdefault("time", None); rec.setdefault("error", None)
            if out is not None:
                outputs[len(records)] = out
            if "_inputs" in rec:
                inputs[len(records)] = rec.pop("_inputs")
            if quiet:
                print(f"  {key}: {rec['status']} {rec.get('reason', '')}".rstrip(), file=sys.stderr)
        records.append(jsonable(rec))
        report.write_results(out_dir, env, records, json_only=True)
    return records, outputs, inputs


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


def array_file(out: Path, r: dict[str, Any]) -> Path:
    name = f"{r['scenario']}-{r['backend']}-{r['device']}-{r['precision']}"
    if r.get("variant", "default") != "default":
        name += f"-{r['variant']}"
    return out / "arrays" / f"{name}.npz"


def save_arrays(out: Path, records, outputs, inputs) -> None:
    (out / "arrays").mkdir(parents=True, exist_ok=True)
    for i, r in enumerate(records):
        if i in outputs:
            np.savez(array_file(out, r), **{**inputs.get(i, {}), **outputs[i]})


def load_saved_outputs(out: Path, records, outputs) -> None:
    """Outputs of resumed cells (for the comparison with Warp), where --save-arrays kept them."""
    for i, r in enumerate(records):
        f = array_file(out, r)
        if i not in outputs and r.get("status") in ("ok", "mismatch") and f.exists():
            sc = scenarios.get(r["scenario"])
            with np.load(f) as z:
                outputs[i] = {k: z[k] for k in sc.outputs if k in z.files}


def load_previous(out: Path) -> list[dict[str, Any]]:
    path = out / "results.json"
    if not path.exists():
        return []
    try:
        return json.loads(path.read_text())["records"]
    except (OSError, ValueError, KeyError) as exc:
        raise ParamError(f"--resume: cannot read {path}: {exc}") from None


def cmd_run(args, chosen, argv) -> int:
    specs, probes = plan(args, chosen)
    out = Path(args.out)
    previous = load_previous(out) if args.resume else []
    env = environment.collect(argv)
    env["backends"] = {n: p for n, p in probes.items()}
    records, outputs, inputs_of = run_specs(specs, probes, args, env, previous)
    if args.save_arrays or args.resume:
        load_saved_outputs(out, records, outputs)
    fill_vs_reference(records, outputs)
    if args.save_arrays:
        save_arrays(out, records, outputs, inputs_of)
    if not args.no_plots:
        plots = out / "plots"
        plots.mkdir(parents=True, exist_ok=True)
        report.plot_time_vs_error(records, plots / "time_vs_error.png")
        report.plot_outputs(records, outputs, plots)
    report.write_results(out, env, records, images=report.images_in(out / "plots", out))
    print(report.tables(records))
    print(f"wrote {out / 'results.json'}, results.csv, results.md" + ("" if args.no_plots else ", plots/"))
    bad = [r for r in records if r["status"] in ("mismatch", "error")]
    return EXIT_FAIL if bad else EXIT_OK


def cmd_report(args) -> int:
    """Rebuild tables and plots from saved results.json files (merged), without running anything.
    Records from different machines are told apart by a 'machine' field (GPU model or host)."""
    if not args.files:
        raise ParamError("report needs at least one results.json")
    records, envs = [], []
    outputs: dict[int, dict[str, np.ndarray]] = {}
    for f in args.files:
        try:
            data = json.loads(Path(f).read_text())
            recs, env = data["records"], data["environment"]
        except (OSError, ValueError, KeyError) as exc:
            raise ParamError(f"cannot read results file {f}: {exc}") from None
        machine = (env.get("gpus") or [{}])[0].get("name") or env.get("hostname", "?")
        for r in recs:
            r.setdefault("machine", machine)
        # outputs kept beside the file (--save-arrays) redraw the scenario pictures too
        mine: dict[int, dict[str, np.ndarray]] = {}
        load_saved_outputs(Path(f).parent, recs, mine)
        outputs.update({len(records) + i: o for i, o in mine.items()})
        records += recs
        envs.append(env)
    out = Path(args.out)
    if not args.no_plots:
        (out / "plots").mkdir(parents=True, exist_ok=True)
        report.plot_time_vs_error(records, out / "plots" / "time_vs_error.png")
        report.plot_outputs(records, outputs, out / "plots")   # where saved arrays allow
    if args.page:
        # a published page: only the page (and plots); the source results.json stay untouched
        page = Path(args.page)
        try:
            notes = Path(args.notes).read_text() if args.notes else ""
        except OSError as exc:
            raise ParamError(f"cannot read --notes {args.notes}: {exc.strerror}") from None
        rebuild = "python -m compare report " + " ".join(args.files) + f" --out {args.out} --page {args.page}" \
            + (f" --title '{args.title}'" if args.title else "") + (f" --notes {args.notes}" if args.notes else "") \
            + (" --no-plots" if args.no_plots else "")
        report.atomic_write(page, report.page(args.title or "Results", envs, records,
                                              report.images_in(out / "plots", page.parent), notes, rebuild))
        print(f"wrote {page}")
        return EXIT_OK
    report.write_results(out, {"merged_from": args.files, "environments": envs}, records,
                         images=report.images_in(out / "plots", out))
    print(report.tables(records))
    return EXIT_OK


SUBCOMMANDS = {"stress": "compare.stress", "sweep": "compare.sweep"}   # each has its own main(argv)


def main(argv: list[str]) -> int:
    if argv and argv[0] in SUBCOMMANDS:
        import importlib
        return importlib.import_module(SUBCOMMANDS[argv[0]]).main(argv[1:])
    try:
        args = build_parser().parse_args(argv)
        if args.command == "list":
            return cmd_list()
        if args.command == "report":
            return cmd_report(args)
        if args.command == "all":
            chosen = [sc for sc in scenarios.SCENARIOS.values() if sc.in_all]
        else:
            chosen = [scenarios.get(args.command)]
        return cmd_run(args, chosen, argv)
    except (UsageError, ParamError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
