"""Assembling the site: the machine-and-method page, the navigation, and writing every page twice
(HTML and Markdown) plus matrix.md. Figures are drawn into DIR/figures by the page builders."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from compare.site import data, fmt, glossary, pages, pages_why, provenance, questions, reproducibility, topics
from compare.site import sittings as second
from compare.site import questions_pages as qp
from compare.site.data import Machine
from compare.site.render import H, Items, P, Table, page_html, page_md
from compare.results.environment import RunEnvironment
from compare.results.store import atomic_write


def _packages(m: Machine) -> list[tuple[str, str]]:
    """Every package version any run recorded (several versions of one package: all listed)."""
    seen: dict[str, list[str]] = {}
    for env in m.runs:
        for k, v in (env.get("packages") or {}).items():
            if str(v) not in seen.setdefault(k, []):
                seen[k].append(str(v))
    return [(k, ", ".join(vs)) for k, vs in sorted(seen.items())]


def _plan_parts(device: str) -> list[str]:
    """The parts a publish runs for ``device`` (every size assumed to fit)."""
    from compare.planning import publish_plan
    parts, _ = publish_plan.plan("DIR", [device], "all", have={"cpu": float("inf"), "cuda": float("inf")})
    return [p.name for p in parts]


def machine(c: qp.Ctx) -> list[Any]:
    m = c.m
    envs = list(m.runs)
    gpus = sorted({f"{g.get('name')} (driver {g.get('driver')}, {g.get('memory')})"
                   for e in envs for g in e.get("gpus") or [] if isinstance(g, dict)})
    first: RunEnvironment = next((e for e in envs if e.get("cpu")), RunEnvironment())
    blocks: list[Any] = [H("Hardware and software"), Items(tuple(x for x in (
        f"GPU: {'; '.join(gpus)}" if gpus else "GPU: none",
        f"CPU: {m.cpu_name()}, {first.get('memory_gib', '?')} GiB memory",
        f"OS: {first.get('os', '?')}; Python {', '.join(sorted({str(e.get('python')) for e in envs if e.get('python')}))}",
        "CUDA toolkit: " + ", ".join(sorted({str(e['cuda_toolkit']) for e in envs if e.get("cuda_toolkit")}) or ["-"]),
        f"Commits: {', '.join(sorted({provenance.short(e.get('git_commit')) for e in envs if e.get('git_commit')}))}",
    )))]
    blocks += [H("Package versions"), Table(("package", "version(s)"), tuple(_packages(m)))]
    yard = []
    for e in envs:
        for dev, hw in (e.get("hardware") or {}).items():
            if isinstance(hw, dict) and hw.get("copy_bytes_per_s"):
                yard.append((str(e.get("created", "?"))[:16], dev, fmt.rate(hw["copy_bytes_per_s"], "B/s"),
                             fmt.seconds(data.num(hw.get("launch_latency_s"))),
                             fmt.seconds(data.num(hw.get("launch_pipelined_s"))), str(hw.get("copy_how", ""))))
    if yard:
        blocks += [H("The same-run yardstick"),
                   P("Measured by each run with no framework involved: the device copy that floors "
                     "bandwidth-bound cells and the driver's empty-kernel launch that floors per-call cost."),
                   Table(("run", "device", "copy bandwidth", "launch + sync", "launch pipelined", "how"), tuple(yard))]
    blocks += reproducibility.blocks(c)
    pub = [p for p in ((m.publish.get("parts") if m.publish else None) or []) if isinstance(p, dict)]
    blocks += [H("Publish run time")]
    if pub:
        total = sum(data.num(p.get("seconds")) or 0.0 for p in pub)
        names = list(dict.fromkeys(str(p.get("name")) for p in pub))
        missing = [n for n in _plan_parts(c.device) if n not in names and n != "site"]
        blocks += [P(f"`python -m compare publish` ran {len(names)} part{'s' if len(names) != 1 else ''} on this machine in "
                     f"{fmt.seconds(total)} of wall time, every attempt counted (publish.json; an "
                     "attempt cut off, by a time limit or a signal, is resumed by the next, keeping "
                     "its finished cells)." + (f" Parts it has not run here: {', '.join(missing)}; "
                                               "any record of theirs comes from another run this page names." if missing else "")),
                   Table(("part", "backends", "started", "seconds", "exit code"), tuple(
                       (str(p.get("name")), _argv_value(p.get("argv"), "--backends"), str(p.get("started")),
                        f"{data.num(p.get('seconds')) or 0:.0f}",
                        "cut off" if p.get("exit_code") is None else str(p.get("exit_code"))) for p in pub))]
    else:
        blocks.append(P("No publish log (publish.json) beside these records: they were assembled from "
                        "the runs below, not by one `python -m compare publish`."))
    # the processor's family and model where runs recorded them: one CPU model name ("AMD EPYC")
    # can stand for several generations of processor
    ids = any(e.get("cpu_id") for e in envs)
    ran: dict[str, int] = {}      # the most processes any record of a run kept: fewer than asked if cut short
    for r in m.records:
        t = r.time
        if r.run and t is not None and t.processes is not None:
            k = str(r.run.get("created"))
            ran[k] = max(ran.get(k, 0), t.processes.count)
    blocks += [H("Runs that produced these records"),
               Table(("created", "commit", "tree", "timed", *(("processor",) if ids else ()), "command"), tuple(
                   (str(e.get("created", "?"))[:19], provenance.short(e.get("git_commit", "?")), _tree(e),
                    _timed(e, ran.get(str(e.get("created")))),
                    *((e.get("cpu_id") or "not recorded",) if ids else ()), str(e.get("command", "?")))
                   for e in envs))]
    blocks += sittings(envs, c.out)
    blocks += [H("Method"), P("How cells are timed, the regimes, the yardstick and the floors: "
                             + pages.doc_link(c.out, "measurement.md") + ". Framework defects found on the way: "
                             + pages.doc_link(c.out, "findings.md") + "."),
               P("One rule for every framework (each port's idiom and its sources: "
                 + pages.doc_link(c.out, "ports.md") + "): every ranked figure is IEEE arithmetic, so "
                 "a framework whose shipped default is fast math (Taichi, quadrants, Dr.Jit) runs exact "
                 "and its default is measured as its `fastmath` variant, shown and never ranked, as is "
                 "any record whose kernel says it ran with fast math; a variant that is a launch path "
                 "the user writes (Warp `record_cmd`, `torch.compile` modes, JAX's XLA command "
                 "buffers, a CUDA graph the port captures) counts on every row its record has; the "
                 "harness's replay of a captured call counts on the graph-replay row only.")]
    return blocks


def sittings(envs: list[RunEnvironment], out: Path) -> list[Any]:
    """Each run's sitting: its own check where it took one (compare.measuring.sitting), else its
    yardstick judged after the fact against the kind's quiet sittings learned from the stores (a
    run before the check existed, whose rows the page may still show); a noisy one named with its
    reasons: a line on the page its figures feed."""
    from compare.measuring import sitting_quiet as sq
    from compare.measuring.sitting import SittingCheck, judge, summary
    stores = sq.stored_runs([out.parent, out, *sq.repository_stores()])
    rows, noisy = [], []
    for e in envs:
        check = (e.get("sitting") or {}).get("start") if isinstance(e.get("sitting"), dict) else None
        hw = next(((d, v) for d, v in (e.get("hardware") or {}).items()
                   if isinstance(v, dict) and not v.get("error") and d == "cuda"), None)
        end = (e.get("sitting") or {}).get("end") if isinstance(e.get("sitting"), dict) else None
        if isinstance(check, dict):
            c, how = SittingCheck.from_json(check), "its check" + (
                f" (at its end: {summary(SittingCheck.from_json(end))})" if isinstance(end, dict) else "")
            why = list(e.get("noisy_sitting_reasons") or []) if e.get("noisy_sitting") else []
            if not (e.get("sitting") or {}).get("quiet"):      # judged without a reference: judge it now
                others = [s for s in stores if s.get("created") != e.get("created")]
                ref = sq.quiet(others, c.device, sq.kind_of(c.device, c.gpu, c.cpu, c.cpu_id, c.cores))
                why += [f"{r} (judged after the fact)" for r in judge(c, ref) if r not in why]
                how += (f", absolute limits only: the stores hold under {sq.MIN_RUNS} other runs of its kind, "
                        "no quiet sitting to compare with" if ref is None else
                        ", against the stores' quiet sittings after the fact ("
                        + ("it had none when it ran)" if "quiet" in (e.get("sitting") or {}) else "its reference was not recorded)"))
        elif hw:
            c = SittingCheck.of(device="cuda", gpu=hw[1].get("gpu"), launch_latency_s=hw[1].get("launch_latency_s"),
                                launch_pipelined_s=hw[1].get("launch_pipelined_s"),
                                copy_bytes_per_s=hw[1].get("copy_bytes_per_s"))
            why = list(judge(c, sq.quiet(stores, "cuda", sq.kind_of("cuda", c.gpu, None, None, None))))
            how = "its yardstick, after the fact"
        else:
            continue
        noisy += [e] if why else []
        rows.append((provenance.run_words(e.get("created"), e.get("git_commit"), e.get("git_dirty")), summary(c), how,
                     f"**noisy sitting**: {'; '.join(why)}" if why else "quiet"))
    if not rows:
        return []
    return [H("The sittings"),
            P("A run checks its sitting before its first cell (and a publish part after its last): "
              "the launch floor and its spread, the copy, host load, other GPU processes, throttling "
              "(" + pages.doc_link(out, "measurement.md") + ", the sitting check); a run from before "
              "the check is judged by its yardstick against the same quiet sittings. A noisy "
              "sitting's figures are slow for the machine, not its orderings: rank within its run. "
              + (f"**{len(noisy)} of {len(rows)} runs sat in a noisy sitting** (the table says why)."
                 if noisy else "Every run's sitting was quiet.")),
            Table(("run", "figures", "judged by", "verdict"), tuple(rows))]


def _timed(env: RunEnvironment, ran: int | None = None) -> str:
    """How the run timed its cells: processes a cell (``ran``: the most its records kept, fewer
    than asked where the run was cut short after a round), and what ran beside a window."""
    procs = env.get("processes")
    words = [f"{procs} processes" if procs not in (None, 1) else "1 process"]
    if isinstance(procs, int) and ran is not None and ran < procs:
        words[0] = f"{procs} processes asked, {ran} ran (cut short after round {ran})"
    if env.get("sitting_s") is not None:
        words.append(f"sitting {env['sitting_s']:g} s")
    if env.get("noisy_sitting"):
        words.append("noisy sitting")
    ahead = env.get("overlap") or 0
    if ahead:
        words.append(f"{ahead} set up ahead" + (", beside GPU windows" if env.get("overlap_beside") else ""))
    return "; ".join(words)


def _tree(env: RunEnvironment) -> str:
    """Whether the run's checkout was committed: clean, its uncommitted paths, or not known."""
    if env.get("git_dirty") is None:
        return "not known" + (f" ({env['git_note']})" if env.get("git_note") else "")
    if not env["git_dirty"]:
        return "clean"
    paths = env.get("git_dirty_paths") or []
    return "uncommitted changes" + (f": {', '.join(paths)}" if paths else "")


BUILDERS = {**{k: build for k, (_, build) in topics.PAGES.items()},
            "accuracy": pages.accuracy, "compile": pages.compile_cost,
            "cpu": pages.cpu, "stability": pages.stability, "machine": machine}


def store_label(inputs: list[Path]) -> str:
    """How commands name the store: its path from the repository root when it lies there (the
    committed reports), else STORE."""
    root = pages.REPO_DOCS.parent
    try:
        return " ".join(str(Path(p).resolve().relative_to(root)) for p in inputs)
    except ValueError:
        return "STORE"


def _without(empty: list[qp.Row], page: str) -> list[Any]:
    """A page's rows with no figure on this machine, each named with what it reads, so a page whose
    rows all lack records (a store without the large parts) is not a bare introduction."""
    return [P(f"**{r.rule.question}**: no figure on this machine; what it reads: {r.rule.text}")
            for r in empty if r.rule.page == page and not r.rule.device]


MANIFEST = "site.json"        # what the site was built from: a rebuild reads it
OVERVIEW = "overview.png"     # the matrix as a picture, beside matrix.md (README shows it)


def _where(p: Path) -> str:
    """A store's path from the repository root when it lies there, else its absolute path."""
    try:
        return Path(p).resolve().relative_to(pages.REPO_DOCS.parent).as_posix()
    except ValueError:
        return str(Path(p).resolve())


def write_site(inputs: list[Path], out: Path, into: Path, title: str | None, against: list[Path],
               m: Machine, reference: Machine | None) -> list[Path]:
    """Every page, figure and the manifest of the site that will stand at ``out``, written into
    the empty folder ``into`` (compare/site/whole.py swaps it in); ``m`` is the stores ``inputs``
    loaded, ``reference`` those of ``against``."""
    figures = into / "figures"
    rows, empty = pages.evaluate(m)
    later = second.load_all(inputs)       # the rows measured again in later sittings (issue 57)
    c = qp.Ctx(m, rows, Path(out), store_label(inputs), into, later)
    title = title or f"Framework comparison: {m.name()}"
    nav = [("Overview", "index.html")] + [(t, f"{k}.html") for k, t in questions.PAGES.items()]
    written: list[Path] = []
    site = {"index": (title, pages.index(c, title, empty))}
    between = second.compare(rows, later, m)
    for key, label in questions.PAGES.items():
        more = (second.summary(between, [n for n, _ in later]) if key == "machine"
                else second.row_blocks(c.rows_of(key), between))
        site[key] = (f"{label} — {m.name()}", BUILDERS[key](c) + more + _without(empty, key))
    site.update(c.subpages)             # a page's detail pages (stability: one per experiment)
    if against and reference is not None:
        from compare.site import against as vs
        nav.append(("Against reference", "against.html"))
        site["against"] = (f"This machine against the reference — {m.name()}", vs.page(c, reference))
    nav.append((glossary.LABEL, glossary.href(out)))      # every page's words, defined
    written += glossary.place(out, into)
    for stem, (t, blocks) in site.items():
        for suffix, render in ((".html", page_html), (".md", page_md)):
            path = into / f"{stem}{suffix}"
            atomic_write(path, render(t, nav, blocks))
            written.append(path)
    atomic_write(into / "matrix.md", pages.matrix_md(rows, m.frameworks, key=pages_why.key_of(m)) + "\n")
    written.append(into / "matrix.md")
    pages.matrix_png(into / OVERVIEW, rows, m.frameworks, title)      # README's picture of the matrix
    written.append(into / OVERVIEW)
    atomic_write(into / MANIFEST, json.dumps({"inputs": [_where(p) for p in inputs], "title": title,
                                             "against": [_where(p) for p in against]}, indent=1) + "\n")
    written.append(into / MANIFEST)
    written += sorted(figures.glob("*")) if figures.is_dir() else []
    return written


def _argv_value(argv: Any, flag: str) -> str:
    """The value after ``flag`` in a publish part's command ('all' where absent)."""
    argv = argv if isinstance(argv, list) else []
    i = argv.index(flag) if flag in argv else -1
    return str(argv[i + 1]) if 0 <= i < len(argv) - 1 else "all"
