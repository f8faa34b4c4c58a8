"""The figures docs/measurement.md quotes of the published stores, computed from the stores with the
site's own code (issue 57, item 5: docs that cannot drift). Each test reads the sentence from the
doc and the figure from docs/results/<machine>/, so a change to either fails it. Figures taken
from an evidence folder (docs/results/*/evidence/) are not held here: the doc names the folder.
The launch paths and fractions of the copy: test_measurement_launch.py; more figures:
test_doc_claims.py; the code constants it quotes: test_doc_constants.py. Fast tier."""
from __future__ import annotations

import json
import re
import statistics
from typing import Any, Mapping

import pytest

from compare.measuring import sitting, sitting_quiet as sq
from compare.results.record import Record
from compare.results.store import run_environments
from compare.site import data, fmt, matrix, provenance, questions
from compare.sweep import horizon
from compare.sweep.rows import throughput_s
from measurement_doc import NAMES, RESULTS, RULES, doc_text, machine, said, span

H100_GPU = "NVIDIA H100 80GB HBM3"

pytestmark = pytest.mark.xdist_group("measurement-claims")


@pytest.fixture(scope="module")
def doc() -> str:
    return doc_text()


def entries(key: str, suite: str) -> list[Mapping[str, Any]]:
    """A store's run entries, a merged entry's own and those it merged alike."""
    top = json.loads((RESULTS / key / f"{suite}.json").read_text())["runs"]
    return [*top, *(e for t in top if "environments" in t for e in run_environments(t))]


# ---- what the stores keep ------------------------------------------------------------------------
def test_the_h100_stress_stores_clean_entries_name_their_day_and_commit(doc: str) -> None:
    """'One row, one run': the counts are tests/results/test_store.py's; here the day and commit."""
    day, commit = said(doc, r"are of unknown tree state and \d+ of a checked clean commit \(([\d-]+), commit (\w+)")
    ok = [e for e in entries("h100", "stress") if e.get("git_dirty") is False]
    assert ok and {str(e["created"])[:10] for e in ok} == {day} and {provenance.short(e["git_commit"]) for e in ok} == {commit}


def test_the_h100_bandwidth_row_reads_the_clean_sweep_of_2026_12_06_alone(doc: str) -> None:
    assert ("the H100 bandwidth row reads the clean bandwidth sweep of 2026-12-06 alone, which timed every variant "
            "at n = 2^28") in doc
    recs = RULES["bandwidth"].pick(machine("h100"), "cuda")
    runs = {json.dumps(r.run, sort_keys=True, default=str) for r in recs}
    assert len(runs) == 1 and {(r.params or {}).get("n") for r in recs} == {2**28}
    run = recs[0].run or {}
    assert str(run.get("created")).startswith("2026-12-06") and run.get("dirty") is False
    command = next(e.get("command") for e in machine("h100").runs if e.get("created") == run.get("created"))
    assert "sweep bandwidth" in str(command)


@pytest.mark.parametrize("key", ["h100", "cpu", "xeon"])
def test_no_row_reads_a_dirty_or_unknown_tree(doc: str, key: str) -> None:
    assert "Those of unknown or dirty trees feed only pages that no row ranks" in doc
    for rule in questions.RULES:
        row = matrix.evaluate(rule, machine(key), fmt.value)
        assert not provenance.uncommitted(row.runs), (key, rule.key, row.runs)


def test_the_cpu_matrix_run_and_session_28s_second_sitting(doc: str) -> None:
    """'Measured reproducibility': the CPU rows read session 33's matrix run; session 28's is a sitting."""
    when, label = said(doc, r"Session 33's run of the matrix part \(([\d-]+ [\d:]+) UTC, .*? session 28's is kept as a "
                            r"second sitting \(`docs/results/cpu/sittings/([\w-]+)`\)")
    reads = {str((r.run or {}).get("created"))[:16].replace("T", " ") for r in RULES["latency"].pick(machine("cpu"), "cpu")}
    assert reads == {when}
    kept = json.loads((RESULTS / "cpu" / "sittings" / label / "results.json").read_text())["runs"]
    assert [str(e["created"])[:10] for e in kept] == [label[:10]]
    assert not any(str(e["created"]).startswith(label[:10]) for e in entries("cpu", "results"))


@pytest.mark.parametrize("key", ["cpu", "xeon"])
def test_the_busy_rows_processes(doc: str, key: str) -> None:
    """The CPU's busy row: 6 processes a cell, ranked; the Xeon's: one, so it names no best."""
    m = machine(key)
    counts = {data.process_count(r) for r in m.busy if r.status == "ok"}
    row = matrix.evaluate(RULES["busy"], m, fmt.value)
    if key == "cpu":
        a, b = said(doc, r"\(`--busy 1 --processes (\d+)`: each figure with a 95 % interval across (\d+) processes")
        assert counts == {int(a)} == {int(b)} and row.best is not None
    else:
        said(doc, r'Xeon store its "CPU, one core busy" row \(one process a cell: its ratios are shown and it names no\s+'
                  r'best, as the busy row ranks only figures repeated across processes\)')
        (label,) = said(doc, r"a row from one process a cell \(the Xeon's\)[^`]+`([^`]+)`")
        assert counts == {1} and row.best is None and row.best_text() == label == "— (one process)"


def test_the_amd_store_names_its_processor_from_2026_12_06_on(doc: str) -> None:
    day, cpu_id = said(doc, r"In the AMD store, the runs from ([\d-]+) on record (family \d+, model \d+, stepping \d+); "
                            r"the older runs record none")
    for suite in ("results", "sweep", "stress"):
        for e in entries("cpu", suite):
            want = cpu_id if str(e["created"]) >= day else None
            assert e.get("cpu_id") == want, (suite, e.get("created"), e.get("cpu_id"))


# ---- the sitting check ---------------------------------------------------------------------------
def test_the_empty_launch_spread_figures(doc: str) -> None:
    """Why the spread is a share of the quiet floor: every H100 sitting check's IQR (its spread
    times its floor), over its own median and over the quiet floor of the stored runs."""
    starts = [(e.get("sitting") or {}).get("start") or {} for e in sq.stored_runs([RESULTS / "h100"])]
    checks = sorted((c for c in starts if c.get("null_spread")), key=lambda c: c["launch_latency_s"])
    iqr = [c["null_spread"] * c["launch_latency_s"] for c in checks]
    lo, hi, n = said(doc, r"the empty launches' IQR is ([\d.]+)-([\d.]+) µs in every H100 sitting that recorded it "
                          r"\((\d+) runs\)")
    assert (lo, hi, int(n)) == (f"{min(iqr) * 1e6:.2f}", f"{max(iqr) * 1e6:.2f}", len(checks))
    # the two over the limit of their own median (the old rule's noisy ones), fastest first
    fast = [c for c in checks if c["null_spread"] > sitting.NULL_SPREAD]
    slow = [c for c in checks if c["null_spread"] <= sitting.NULL_SPREAD]
    got = said(doc, r"it is (\S+) % in the others \(floor (\S+) µs\) and (\S+) % in\s+the two the old rule called "
                    r"noisy \(([\d.]+) and ([\d.]+) µs, below the quiet floor\)")
    assert got == (span((100 * c["null_spread"] for c in slow), "{:.1f}"),
                   span((c["launch_latency_s"] * 1e6 for c in slow), "{:.1f}"),
                   span((100 * c["null_spread"] for c in fast), "{:.1f}"),
                   *(f"{c['launch_latency_s'] * 1e6:.2f}" for c in fast))
    quiet = sq.quiet(sq.stored_runs(sq.repository_stores()), "cuda", sq.kind_of("cuda", H100_GPU, None, None, None))
    assert quiet is not None and quiet.launch_latency_s
    floor, first, second = said(doc, r"Against the quiet floor \(([\d.]+) µs\) session 34's IQR is ([\d.]+) % and passes; "
                                     r"session 33's, ([\d.]+) %, is still noisy")
    shares = [c["null_spread"] * c["launch_latency_s"] / quiet.launch_latency_s for c in fast]
    assert (floor, first, second) == (f"{quiet.launch_latency_s * 1e6:.1f}", *(f"{100 * s:.1f}" for s in shares))
    assert shares[0] <= sitting.NULL_SPREAD < shares[1]
    assert all(quiet.launch_latency_s > c["launch_latency_s"] for c in fast)


def test_the_cpu_kinds_and_their_quiet_reference(doc: str) -> None:
    runs = sq.stored_runs([RESULTS / "cpu"])
    copies = [e["hardware"]["cpu"]["copy_bytes_per_s"] for e in runs if not e.get("cpu_id")
              and ((e.get("hardware") or {}).get("cpu") or {}).get("copy_bytes_per_s")]
    assert said(doc, r'stands for hosts whose copies are ([\d.]+) to ([\d.]+) GB/s') == (
        f"{min(copies) / 1e9:.3g}", f"{max(copies) / 1e9:.3g}")
    assert "That kind gets no quiet reference" in doc
    assert sq.quiet(sq.stored_runs(sq.repository_stores()), "cpu", sq.kind_of("cpu", None, "AMD EPYC", None, 2)) is None
    day, fam, copy, n = said(doc, r"The AMD runs since ([\d-]+) are (family \d+, model \d+), another kind, with a quiet "
                                  r"reference of its own \(quiet copy ([\d.]+) GB/s, from its (\d+) runs not stamped noisy\)")
    ids = {e.get("cpu_id") for e in runs if str(e.get("created")) >= day}
    assert len(ids) == 1 and str(next(iter(ids))).startswith(fam)
    q = sq.quiet(sq.stored_runs(sq.repository_stores()), "cpu", sq.kind_of("cpu", None, "AMD EPYC", ids.pop(), 2))
    assert q is not None and q.copy_bytes_per_s and (copy, int(n)) == (f"{q.copy_bytes_per_s / 1e9:.3g}", q.runs)


# ---- the horizon and scaling sweeps --------------------------------------------------------------
def xeon_outside_bound() -> tuple[list[Record], list[Record]]:
    """The Xeon horizon sweep's float32 soft-contact cells at 600 steps: mismatches, and JAX's."""
    cells = [r for r in machine("xeon").sweep if data.tag(r, "sweep") == "horizon" and r.scenario == "projectile"
             and r.precision == "float32" and (r.params or {}).get("contact") == "soft"
             and (r.params or {}).get("steps") == 600]
    return [r for r in cells if r.status == "mismatch"], [r for r in cells if r.backend == "jax" and r.variant == "default"]


def vs_bound(r: Record) -> float:
    v = data.num(r.error.vs_oracle) if r.error else None
    assert v is not None, r.backend
    return v


def sci(x: float) -> str:
    """8.7e6, as the doc writes it."""
    return re.sub(r"e\+?0*(\d)", r"e\1", f"{x:.1e}")


def test_the_xeon_soft_contact_cells_outside_their_bound(doc: str) -> None:
    bad, (jax,) = xeon_outside_bound()
    ratios = [vs_bound(r) for r in bad]
    assert max(ratios) <= min(ratios) * (1 + 1e-5)          # "equal to five digits"
    frameworks = {r.backend for r in bad}
    cells, fws, ratio = said(doc, r"fail their derived bound in (\d+) cells of (\d+) frameworks alike \(error/bound ([\d.]+)")
    assert (int(cells), int(fws), ratio) == (len(bad), len(frameworks), f"{min(ratios):.5g}")
    assert said(doc, r"and pass in JAX \(([\d.]+), its XLA arithmetic")[0] == f"{vs_bound(jax):.2g}" and jax.status == "ok"
    checked, worst, ratio2, fws2 = said(doc, r"exceeds the gradient bound on one of the (\d+) checked trajectories "
                                             r"\(checked trajectory (\d+), batch trajectory \d+\), by ([\d.]+) of the "
                                             r"bound in (\d+) frameworks")
    details = [r.error.details for r in bad if r.error]
    assert {str(r.error.checked_items).split(" of ")[0] for r in bad if r.error} == {checked}
    assert {d.get("worst_trajectory") for d in details} == {int(worst)}
    assert (ratio2, int(fws2)) == (ratio, len(frameworks))
    assert said(doc, r"JAX, whose float32 result differs, lands at (\d+\.\d+)")[0] == f"{vs_bound(jax):.2g}"
    mine, ref = said(doc, r"the float32 gradient's second component is (\S+) against (\S+) in float64")
    assert {sci(d["gradient_value"][1]) for d in details} == {mine}
    assert {sci(d["gradient_reference_value"][1]) for d in details} == {ref}
    assert "The error sweep has not run on the Xeon" in doc
    assert not [r for r in machine("xeon").sweep if data.tag(r, "sweep") == "error"]


def groups(key: str, device: str, precision: str, contact: str = "hard") -> dict[tuple[str, str], list[Record]]:
    """The horizon sweep's projectile series of one precision and contact, by backend and variant."""
    out = {}
    for k, rows in horizon.series(list(machine(key).sweep), device, "projectile").items():
        if k[2] == precision and json.loads(k[3]).get("contact") == contact:
            out[(k[0], k[1])] = rows
    return out


def slopes(rows: list[Record]) -> list[float]:
    return [s for s in horizon.slopes(rows) if s is not None]


def test_what_each_gradient_keeps_on_the_h100(doc: str) -> None:
    """Bytes per trajectory-step (every slope between horizons), the scaling sweep's figures at
    B = 2^20 and B = 1, and the horizon sweep's times (H100, float32, hard contact)."""
    hz = groups("h100", "cuda", "float32")
    for pattern, fws in ((r"Numba and CuPy keep one value and one flag per step \((\S+) B,", ("numba", "cupy")),
                         (r"Warp's tape keeps the state and its adjoint, (\S+) B,", ("warp",)),
                         (r"quadrants keeps (\S+) B in its launch-sized adstacks", ("quadrants",)),
                         (r"JAX keeps least \((\S+) B:", ("jax",))):
        assert said(doc, pattern)[0] == span(s for f in fws for s in slopes(hz[(f, "default")])), pattern

    def scaling(fw: str, batch: int) -> Record:
        return next(r for r in machine("h100").sweep if data.tag(r, "sweep") == "scaling" and r.scenario == "projectile"
                    and r.device == "cuda" and r.backend == fw and r.variant == "default" and r.status == "ok"
                    and (r.params or {}).get("batch") == batch)
    call = throughput_s(scaling("warp", 2**20))
    assert call and said(doc, r"\(85 ms at the copy bandwidth, of (\d+) ms measured\)")[0] == f"{call * 1e3:.0f}"
    taichi = scaling("taichi", 1).memory
    assert taichi and taichi.device_bytes
    assert said(doc, r"\(([\d.]+) GiB from B = 1\)")[0] == f"{taichi.device_bytes / 2**30:.3g}"
    torch = [throughput_s(r) or 0 for r in machine("h100").sweep if data.tag(r, "sweep") == "scaling"
             and r.scenario == "projectile" and r.device == "cuda" and r.backend == "torch" and r.variant == "default"
             and r.status == "ok"]
    assert said(doc, r"so a call costs (\S+) s from B = 1 to 2\^20")[0] == span(torch, "{:.2g}")

    def times(fw: str, variant: str = "default") -> dict[int, float]:
        return {int((r.params or {})["steps"]): throughput_s(r) or 0 for r in hz[(fw, variant)]}
    t = times("taichi")
    assert said(doc, r"where its time jumps (\d+)×")[0] == f"{t[3000] / t[1000]:.2g}"
    longest = max(times("warp"))
    steps = f"{longest:,}".replace(",", " ")
    warp, jax = said(doc, rf"At {steps} steps Warp's `checkpoint`, which keeps only segment boundaries, takes (\S+)× "
                          r"its default's time and JAX's (\S+)×")
    assert (warp, jax) == tuple(f"{times(f, 'checkpoint')[longest] / times(f)[longest]:.2g}" for f in ("warp", "jax"))


def test_what_each_gradient_keeps_on_the_cpu(doc: str) -> None:
    """AMD CPU, float64, hard contact: the slope between the two longest horizons."""
    last = {fw: slopes(rows)[-1] for (fw, variant), rows in groups("cpu", "cpu", "float64").items() if variant == "default"}
    got = said(doc, r"Warp, Taichi and quadrants keep (\S+) B per trajectory-step \(state and adjoint, 8 doubles\), "
                    r"PyTorch's autograd graph (\d+), Numba (\d+) \(one double and a flag\), NumPy (\d+) \(the flag alone\)")
    assert got == (span(last[f] for f in ("warp", "taichi", "quadrants")),
                   *(f"{last[f]:.0f}" for f in ("torch", "numba", "numpy")))


def test_the_largest_cpu_tape_slope(doc: str) -> None:
    """The preflight's tape model against the CPU store's horizon sweep: its largest slope."""
    every = [(s, fw) for (fw, _, _, _), rows in horizon.series(list(machine("cpu").sweep), "cpu", "projectile").items()
             for s in slopes(rows)]
    top, fw = max(every)
    name, figure = said(doc, r"the largest slope between horizons in the CPU store's horizon sweep is ([\w.]+)'s, "
                             r"(\d+) B per trajectory-step")
    assert (NAMES[name], figure) == (fw, f"{top:.0f}")


# ---- the code's constants it quotes --------------------------------------------------------------
def test_the_constants_and_coverages_it_quotes(doc: str) -> None:
    """Not store figures, but as apt to drift: the thresholds named in the doc and the coverage of
    the order-statistics interval at the process counts it names (compare.running.repeats)."""
    from compare.running import repeats, worker
    from compare.site import ranking
    code = {"SEPARATED_GAP": ranking.SEPARATED_GAP, "ONE_PROCESS_GAP": ranking.ONE_PROCESS_GAP,
            "PROFILE_S": worker.PROFILE_S, "COLD": repeats.COLD}
    quoted = dict(re.findall(r"`([A-Z_]+)` = ([\d.]+)", doc))
    assert quoted.keys() == code.keys() and all(float(quoted[k]) == v for k, v in code.items()), quoted
    assert said(doc, r"above ([\d.]+)× the quiet floor \(`FLOOR_RATIO`\)")[0] == f"{sitting.FLOOR_RATIO:g}"
    assert said(doc, r"below the quiet copy / ([\d.]+) \(`COPY_RATIO`\)")[0] == f"{sitting.COPY_RATIO:g}"
    spread = said(doc, r"IQR above (\d+) % of the quiet floor with a synchronise \(`NULL_SPREAD`")[0]
    assert spread == f"{100 * sitting.NULL_SPREAD:g}"

    def cover(n: int) -> str:
        return f"{100 * repeats.interval(list(range(n)))[2]:.3g}"
    six, ten, three = said(doc, r"with 6 processes that is the range, ([\d.]+) %; with 10, the 2nd and 9th values, "
                                r"([\d.]+) %\).*?\(3 processes: (\d+) %\)")
    assert (six, ten, three) == (cover(6), cover(10), cover(3))
    two, five = said(doc, r"less than 95 %: 2 processes (\d+) %, 5 processes (\d+) %\)")
    assert (two, five) == (f"{float(cover(2)):.0f}", f"{float(cover(5)):.0f}")


# ---- units that travel ---------------------------------------------------------------------------
def test_where_the_fresh_per_call_sitting_lands(doc: str) -> None:
    """Session 38's fresh per-call sitting against the report (session 41's matrix part): its median
    distance in floors and seconds, how many of its figures land in their own range and in their row's
    band, the bands' sizes and widths, and the earlier sittings' shares (compare/site/sittings.py)."""
    from compare.site import sitting_readme, sittings
    _, _, later, between, landed = sitting_readme._report(RESULTS / "h100")
    labels = list(later)
    fresh = "2026-12-07-session38-percall"
    by = {s.sitting: s for s in landed}
    x = by[fresh]
    assert said(doc, r"lies ([\d.]+)× from the\s+report in floors in the median, against ([\d.]+)× in seconds") == \
        (f"{x.median_floors:.2f}", f"{x.median_seconds:.2f}")
    assert said(doc, r"(\d+) of\s+its (\d+) figures land in floors \((\d+) in seconds\)") == \
        (str(x.inside_floors), str(x.figures), str(x.inside_seconds))
    before = sittings.bands(list(between), labels[:labels.index(fresh)])
    assert said(doc, r"\((\d+-\d+) ratios a row before session 38") == (span(b.n for b in before.values()),)
    got = said(doc, r"(\d+) of its (\d+) figures land in\s+floors \((\d+) %\), (\d+) in seconds \((\d+) %\)")
    assert got == (str(x.band_floors), str(x.banded), f"{100 * x.band_floors / x.banded:.0f}", str(x.band_seconds),
                   f"{100 * x.band_seconds / x.banded:.0f}")
    now = sittings.bands(list(between), labels)
    assert said(doc, r"the bands are wide \(now ([\d.]+)-([\d.]+)× in floors\)") == \
        (f"{min(min(b.floors) for b in now.values()):.2f}", f"{max(max(b.floors) for b in now.values()):.2f}")
    assert said(doc, r"session 30's figures lie ([\d.]+)× from the report in floors in the median") == \
        (f"{by['2026-12-06-session30'].median_floors:.2f}",)
    s36, s31 = by["2026-12-07-session36"], by["2026-12-06-session31"]
    assert said(doc, r"session 36's one-process run lands (\d+) % of its figures in its bands in floors") == \
        (f"{100 * s36.band_floors / s36.banded:.0f}",)
    assert said(doc, r"session 31's\s+two-process run (\d+) of its (\d+) \(its seconds (\d+)\)") == \
        (str(s31.band_floors), str(s31.banded), str(s31.band_seconds))
    assert len([b for b in between if b.sitting == fresh and b.row in before and b.floors_spread is not None
                and not before[b.row].holds(b)[0]]) == x.banded - x.band_floors
    assert said(doc, r"against session 41's it lies\s+([\d.]+)× and ([\d.]+)×") == (f"{x.median_floors:.2f}", f"{x.median_seconds:.2f}")
    s39 = by["2026-12-07-session39"]
    assert said(doc, r"session 39's three-process run (\d+) of its (\d+) \(its seconds (\d+)\)") == \
        (str(s39.band_floors), str(s39.banded), str(s39.band_seconds))
    assert said(doc, r"session 39's own figures, a sitting now, lie ([\d.]+)× in floors and ([\d.]+)× in\s+seconds") == \
        (f"{s39.median_floors:.2f}", f"{s39.median_seconds:.2f}")


COMMIT_39 = "9fb39d8"       # session 39's matrix part: the report's per-call rows until session 41 (a sitting since)


def test_the_matrix_parts_cold_rounds(doc: str) -> None:
    """Session 39's matrix part: its first calls and windows against the run it replaced (session 31's,
    now a sitting), cell by cell, and what its three cold processes spent on set-up + first call, by
    variant kind (the stores)."""
    mine = json.loads((RESULTS / "h100" / "sittings" / "2026-12-07-session39" / "results.json").read_text())
    before = json.loads((RESULTS / "h100" / "sittings" / "2026-12-06-session31" / "results.json").read_text())

    def key(r: Mapping[str, Any]) -> tuple[Any, ...]:
        return r["scenario"], r["backend"], r["device"], r["precision"], r["variant"], json.dumps(r["params"], sort_keys=True)

    ok = [r for r in mine["records"] if r["status"] == "ok" and r["run"]["commit"].startswith(COMMIT_39)]
    theirs = {key(r): r for r in before["records"] if r["status"] == "ok"}
    pairs = [(r["time"], theirs[key(r)]["time"]) for r in ok if key(r) in theirs]
    assert len(pairs) == len(ok) == 85
    first = statistics.median(a["first_call_s"] / b["first_call_s"] for a, b in pairs)
    window = statistics.median((a["window"][1] - a["window"][0]) / (b["window"][1] - b["window"][0]) for a, b in pairs)
    assert said(doc, r"first calls ([\d.]+)×, whole windows ([\d.]+)× the\s+run it replaced") == (f"{first:.2f}", f"{window:.2f}")
    assert said(doc, r"over (\d+) cells, (\d+) more than in session 26") == ("85", "14")

    def spent(rs: list[Mapping[str, Any]]) -> float:
        return sum(sum(r["time"]["processes"]["first_result"]["values"]) for r in rs)

    other = [r for r in ok if r["variant"] != "default"]
    by = {b: spent([r for r in other if r["backend"] == b]) for b in ("torch", "mlx")}
    got = said(doc, r"took (\d+) s\n?\s*\((\d+) s a cold round; PyTorch's variants (\d+) s of it, mostly `compile`, MLX's (\d+) s\), "
                    r"the defaults' (\d+) s")
    assert got == (f"{spent(other):.0f}", f"{spent(other) / 3:.0f}", f"{by['torch']:.0f}", f"{by['mlx']:.0f}",
                   f"{spent([r for r in ok if r['variant'] == 'default']):.0f}")

    def beyond(r: Mapping[str, Any]) -> float:    # a repeat round's window: no first-process-only phase
        p, w = r["time"]["phases"], r["time"]["window"]
        return w[1] - w[0] - sum(p.get(k, 0.0) for k in ("first_call", "host_profile", "own_timer", "memory_pass"))

    (round_s,) = said(doc, r"projectile's variants' windows took about (\d+) s a round\s+beyond their first calls")
    assert round_s == f"{sum(beyond(r) for r in other if r['scenario'] == 'projectile'):.0f}"
    n, total, sdf_s, all_s = said(doc, r"the SDF's\s+cells were (\d+) of the part's (\d+) \(their windows (\d+) s a round "
                                       r"beyond first calls: a round's time is\s+mostly its workers' set-ups, \d+ cells' "
                                       r"windows (\d+) s of a 395 s round\)")
    sdf = [r for r in ok if r["scenario"] == "sdf"]
    assert (int(n), int(total)) == (len(sdf), len(ok))
    assert (sdf_s, all_s) == (f"{sum(beyond(r) for r in sdf):.0f}", f"{sum(beyond(r) for r in ok):.0f}")


def test_the_preflights_per_trajectory_slopes(doc: str) -> None:
    """The memory preflight's margin of two: PyTorch's peak RSS per trajectory between three batch
    sizes, from the stored runs of evidence/session38-rss-slope."""
    peak = {}
    for b in (4096, 16384, 65536):
        data = json.loads((RESULTS / "cpu" / "evidence" / "session38-rss-slope" / f"b{b}" / "results.json").read_text())
        (r,) = [r for r in data["records"] if r["backend"] == "torch" and r["status"] == "ok"]
        assert r["params"]["batch"] == b and r["precision"] == "float32"
        peak[b] = r["memory"]["peak_host_rss_bytes"]
    first, second = said(doc, r"([\d.]+) kB per trajectory between B = 4096 and 16384,\s*([\d.]+) kB between 16384 and 65536")
    assert (first, second) == (f"{(peak[16384] - peak[4096]) / 12288 / 1e3:.1f}",
                               f"{(peak[65536] - peak[16384]) / 49152 / 1e3:.1f}")
