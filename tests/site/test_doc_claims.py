"""More of docs/measurement.md's store figures, computed from the stores with the site's own code
(issue 57, item 5; the others: test_measurement_claims.py, test_measurement_launch.py; findings.md
and README: test_findings_claims.py; the code constants the docs quote: test_doc_constants.py).
Each test reads the sentence and the store, so a change to either fails it. Fast tier."""
from __future__ import annotations

import re
import statistics
from typing import Any
from collections import Counter

import pytest

from backends.base import UNRANKED_VARIANTS
from compare.measuring import sitting_quiet as sq
from compare.results.record import Record
from compare.results.store import Store
from compare.site import data, matrix, pages
from compare.sweep.rows import throughput_s
from measurement_doc import RESULTS, doc_text, machine, said, span

pytestmark = pytest.mark.xdist_group("measurement-claims")

COMMIT_39 = "9fb39d8"       # session 39's H100 matrix part: the report's per-call rows until session 41
COMMIT_41 = "69cbd3b"       # session 41's H100 matrix part: the report's per-call rows since
S39 = "h100/sittings/2026-12-07-session39"      # session 39's records, a sitting since session 41


@pytest.fixture(scope="module")
def doc() -> str:
    return doc_text()


def run_of(r: Record) -> str:
    return str((r.run or {}).get("commit", ""))


# ---- the rows and the runs they read -------------------------------------------------------------
def test_the_rows_that_read_session_41s_matrix_part(doc: str) -> None:
    """'Since session 41 the report's accuracy, first-call, per-call and small-particle rows read that
    session's matrix part (a quiet start check and a noisy end check, six processes a cell where a row
    ranks its timings, ...), and the runs they read before, session 31's and session 39's, are
    sittings': the H100 rows, that run's records and the two sittings."""
    said(doc, r"Since session 41 the report's accuracy, first-call, per-call and small-particle rows read that "
              r"session's matrix part \(`publish --part all`, a quiet start check and a noisy end check, six processes "
              r"a cell where a row ranks its timings, each cell with its own floor, set-ups overlapped;.*?and the runs "
              r"they read before, session 31's and session 39's, are sittings like the others")
    m = machine("h100")
    reads = {r.rule.key for r in pages.evaluate(m)[0] if r.runs and all(COMMIT_41 in w for w in r.runs)}
    assert reads == {"accuracy", "compile", "latency", "pipelined", "graph", "particles-small"}
    mine = [r for r in m.run if run_of(r).startswith(COMMIT_41) and r.status == "ok"]
    ranked = [r for r in mine if r.scenario in ("saxpy", "particles") and r.variant not in UNRANKED_VARIANTS]
    assert ranked and {data.process_count(r) for r in ranked} == {6} and all(r.cell_floor for r in mine)
    assert {data.process_count(r) for r in mine} == {1, 3, 6}       # the capped cells: driver.caps
    (entry,) = [e for e in m.runs if str(e.get("git_commit", "")).startswith(COMMIT_41)]
    sitting = entry["sitting"]
    assert sitting["start"] and sitting["end"] and (entry.get("overlap") or 0) > 0
    assert entry.get("noisy_sitting") and all(w.startswith("at the end") for w in entry["noisy_sitting_reasons"])
    for old in (S39, "h100/sittings/2026-12-06-session31"):        # a sitting's cells: another run now
        theirs = {r.key: run_of(r) for r in machine(old).run}
        assert theirs and all(run_of(r) != theirs[r.key] for r in m.run if r.key in theirs)


def test_every_cpu_row_reads_a_run_of_one_processor(doc: str) -> None:
    """'One model name is not one machine': each AMD row reads one run, every one of them of the
    processor the doc names; the large rows read session 44's, whose figures lie from session 23's
    (a sitting now) as the doc says, with the one ordering that reversed."""
    from compare.site import agreement, provenance, sittings
    (cpu_id,) = said(doc, r"In the AMD store, the runs from [\d-]+ on record (family \d+, model \d+, stepping \d+)")
    said(doc, r"Its rows read one run each, not all the same run, but since\s+session 44 \(2026-12-07\) every row "
              r"reads a run of that one processor")
    m = machine("cpu")
    rows = pages.evaluate(m)[0]
    assert all(len(r.runs) == 1 for r in rows)
    read = {w for r in rows for w in r.runs}
    assert len(read) > 1                                    # not all the same run
    entries = [e for e in m.runs if provenance.run_words(e.get("created"), e.get("git_commit"), e.get("git_dirty")) in read]
    assert len(entries) == len(read) and {e.get("cpu_id") for e in entries} == {cpu_id}
    (label,) = said(doc, r"session 23's run is\s+kept as a sitting \(`docs/results/cpu/sittings/([\w-]+)`\)")
    old = machine(f"cpu/sittings/{label}")
    assert not any(e.get("cpu_id") for e in old.runs)
    between = sittings.compare(rows, [(label, old)], m)
    med = {k: f"{statistics.median(b.spread for b in between if b.row == k):.2f}" for k in ("bandwidth", "particles-large")}
    said(doc, rf"lie {re.escape(med['bandwidth'])}× \(large arrays\) and {re.escape(med['particles-large'])}× \(large n\) "
              r"from the old ones in the median")
    large = {b.framework: b for b in between if b.row == "particles-large"}
    slower = {f for f, b in large.items() if b.other > b.first}     # a rate: lower on the new host
    assert slower == {"warp"} and all(b.other > b.first for b in between if b.row == "bandwidth")   # a time
    (warp, numpy) = said(doc, r"Warp's particle loop, ([\d.]+)× slower .*? NumPy \(([\d.]+)× faster\) against Warp")
    assert (warp, numpy) == (f"{large['warp'].spread:.2f}", f"{large['numpy'].spread:.2f}")
    held = agreement.hold(m, old)
    assert [(r.question, r.reversed_pairs) for r in held.rows if r.disagree] == [
        ("Particle loop, large n (cpu)", ("numpy vs warp",))]


def test_the_first_sitting_stored_for_the_h100(doc: str) -> None:
    """The particle row's interrupted round of 2026-12-06 03:54: a quiet sitting, one process a cell."""
    when, label = said(doc, r"The first one stored for the H100 is the particle row's interrupted round of "
                            r"([\d-]+ [\d:]+) \(a quiet sitting, one process a cell\).*?\[sittings/([\w-]+)\]")
    m = machine(f"h100/sittings/{label}")
    (entry,) = m.runs
    assert str(entry.get("created"))[:16].replace("T", " ") == when and not entry.get("noisy_sitting")
    timed = [r for r in m.run if r.status == "ok"]
    assert timed and {r.scenario for r in m.run} == {"particles"} and {data.process_count(r) for r in timed} == {1}


def test_cupy_missed_the_launch_target_in_session_39s_run(doc: str) -> None:
    """'plain launches meet it in all four for CuPy alone (...; they took 2.2-2.3x in session 39's run,
    now a sitting)': that run's CuPy SAXPY and particles over their run's pipelined launch (the current
    run's: test_measurement_launch.py)."""
    (took,) = said(doc, r"plain launches meet it in all four for CuPy alone \(its SAXPY and particles take \S+× the "
                        r"run's launch; they took (\S+)× in session 39's run, now a sitting\)")
    two = [r for r in machine(S39).run if r.backend == "cupy" and r.variant == "default" and r.status == "ok"
           and r.scenario in ("saxpy", "particles") and data.at_defaults(r)]

    def ratio(r: Record) -> float:
        t, floor = data.per_call(r, "throughput"), data.num(r.hardware.launch_pipelined_s) if r.hardware else None
        assert t and floor
        return t.median / floor
    assert len(two) == 2 and span((ratio(r) for r in two), "{:.2g}") == took


# ---- the sittings and their yardsticks ------------------------------------------------------------
def test_the_narrowest_empty_launch_spreads_are_session_38s(doc: str) -> None:
    first, second = said(doc, r"The narrowest IQRs are session 38's two quiet runs \(([\d.]+) and ([\d.]+) µs\)")
    runs = sq.stored_runs([RESULTS / "h100"])
    iqr = sorted((c["null_spread"] * c["launch_latency_s"], str(e.get("created")), e.get("noisy_sitting"))
                 for e in runs if (c := (e.get("sitting") or {}).get("start") or {}).get("null_spread"))
    fresh = {str(e.get("created")) for e in machine("h100/sittings/2026-12-07-session38-percall").runs}
    assert [f"{x * 1e6:.2f}" for x, _, _ in iqr[:2]] == [first, second]
    assert {c for _, c, _ in iqr[:2]} == fresh and not any(noisy for _, _, noisy in iqr[:2])


def test_the_amd_copies_of_2026_12_01_and_2026_12_02(doc: str) -> None:
    """'On 2026-12-02 ... its yardstick copied 34.4 GB/s in one thread, against 24.9 GB/s on
    2026-12-01': session 28's run (a sitting now) and the `compare all` of 2026-12-01 (the float64
    part, kept in evidence/session27 since session 44's replaced it)."""
    late, early = said(doc, r"its yardstick copied ([\d.]+) GB/s in one thread, against ([\d.]+) GB/s on 2026-12-01")
    runs = [*sq.stored_runs([RESULTS / "cpu"]),
            *Store.read(RESULTS / "cpu" / "evidence" / "session27" / "float64" / "results.json").runs]

    def one_thread(day: str, command: str) -> set[str]:
        return {f"{e['hardware']['cpu']['copy_one_thread_bytes_per_s'] / 1e9:.1f}" for e in runs
                if str(e.get("created")).startswith(day) and str(e.get("command", "")).startswith(command)}
    assert one_thread("2026-12-02", "python -m compare all") == {late}
    assert one_thread("2026-12-01", "python -m compare all") == {early}


# ---- the matrix parts run twice -------------------------------------------------------------------
def publish_seconds(key: str) -> float:
    log = machine(key).publish
    assert log
    (part,) = log["parts"]
    return float(part["seconds"])


def test_the_rerun_folders_are_the_runs_the_doc_names(doc: str) -> None:
    """Each store's `rerun/`: the H100's session 26 (its row of the sitting table), the CPU's session
    22 (62 cells, 46.4 minutes, 60 of them to 10 processes), the Xeon's session 26."""
    said(doc, r"`docs/results/h100/rerun/` is session 26's run")
    day, total = said(doc, r"\| session 26, ([\d-]+), `--sitting 1500`.*?\| (\d+) s \(\*\*[\d.]+ min\*\*\) \|")
    h100 = machine("h100/rerun")
    assert {str(e.get("created"))[:10] for e in h100.runs} == {day} and f"{publish_seconds('h100/rerun'):.0f}" == total
    said(doc, r"session 22's run is `docs/results/cpu/rerun/`")
    cells, minutes, ten = said(doc, r"the same part \((\d+) cells\) took ([\d.]+) minutes in session 22 .*? and (\d+) of "
                                    r"the \d+ cells ran to 10 processes")
    ok = [r for r in machine("cpu/rerun").run if r.status == "ok"]
    assert (int(cells), minutes) == (len(ok), f"{publish_seconds('cpu/rerun') / 60:.1f}")
    assert int(ten) == sum(data.process_count(r) == 10 for r in ok)
    others, minutes = said(doc, r"session 26's, on the idle VM \(`others_cores` ([\d.]+), ([\d.]+) minutes, "
                                r"`docs/results/xeon/rerun/`\)")
    ok = [r for r in machine("xeon/rerun").run if r.status == "ok"]
    busy = [r.time.noise.others_cores for r in ok if r.time and r.time.noise and r.time.noise.others_cores is not None]
    assert (others, minutes) == (f"{statistics.median(busy):.2f}", f"{publish_seconds('xeon/rerun') / 60:.1f}")


def test_the_cpu_matrix_part_of_session_39(doc: str) -> None:
    """Its 71 cells, 23 of them to 10 processes: the sitting it is stored as."""
    cells, ten = said(doc, r"Session 39's, the first with a non-default variant cold once, took [\d.]+ minutes "
                           r"\(\d+ s, (\d+) cells, (\d+) of them to 10 processes\)")
    ok = [r for r in machine("cpu/sittings/2026-12-07-session39-matrix").run if r.status == "ok"]
    assert (int(cells), int(ten)) == (len(ok), sum(data.process_count(r) == 10 for r in ok))


def test_the_records_moved_to_unstamped(doc: str) -> None:
    """'the records made before runs were stamped (231 on the H100 and the AMD CPU, ...) moved on
    2026-11-28 to `evidence/unstamped/` beside each store, with their 21 run entries'."""
    records, runs = said(doc, r"the records made before runs were stamped \((\d+) on the H100 and the AMD CPU.*?"
                              r"`evidence/unstamped/` beside each store, with their (\d+) run entries")
    moved = [machine(f"{k}/evidence/unstamped") for k in ("h100", "cpu")]
    assert (int(records), int(runs)) == (sum(len(m.run) for m in moved), sum(len(m.runs) for m in moved))


# ---- memory -------------------------------------------------------------------------------------
def test_the_cuda_context_the_device_figure_leaves_out(doc: str) -> None:
    """`memory.context_bytes` of every cell of the H100 store (run and sweep records; the stress
    suite shares a worker between cells, so its baseline is no context)."""
    lo, hi = said(doc, r"So the context \((\d+)-(\d+) MiB in the H100 store's cells, mostly the same for every framework\)")
    by: dict[str, list[float]] = {}
    for r in machine("h100").records:
        if r.memory and (c := r.memory.extra.get("context_bytes")):
            by.setdefault(r.backend, []).append(c / 2**20)
    assert span((x for xs in by.values() for x in xs)) == f"{lo}-{hi}"
    assert all(max(xs) < 1.05 * min(xs) for xs in by.values()), by


def test_the_traffic_of_warps_tape(doc: str) -> None:
    """'moves about 255 GB a run at that batch (85 ms at the copy bandwidth)': twice its tape (written
    forward, read back) over B x steps x evaluations, with the slopes the doc quotes beside it, at
    the copy yardstick of the scaling sweep's Warp cell at B = 2^20."""
    gb, ms = said(doc, r"moves about (\d+) GB a run at that batch \((\d+) ms at the copy bandwidth")
    rows = [r for r in machine("h100").sweep if data.tag(r, "sweep") == "horizon" and r.scenario == "projectile"
            and r.device == "cuda" and r.backend == "warp" and r.variant == "default"
            and r.precision == "float32" and (r.params or {}).get("contact") == "hard" and r.status == "ok"]
    from compare.sweep import horizon
    slopes = [s for s in horizon.slopes(sorted(rows, key=lambda r: (r.params or {})["steps"])) if s is not None]
    (cell,) = [r for r in machine("h100").sweep if data.tag(r, "sweep") == "scaling" and r.scenario == "projectile"
               and r.device == "cuda" and r.backend == "warp" and r.variant == "default" and r.status == "ok"
               and (r.params or {}).get("batch") == 2**20]
    p = cell.params or {}
    moved = [2 * s * p["batch"] * p["steps"] * (p["iters"] + 1) / 1e9 for s in slopes]
    assert min(moved) <= float(gb) <= max(moved), moved
    copy = data.num(cell.hardware.copy_bytes_per_s) if cell.hardware else None
    assert copy and f"{float(gb) * 1e9 / copy * 1e3:.0f}" == ms and (throughput_s(cell) or 0) > float(ms) / 1e3


# ---- the horizon sweep's soft contact --------------------------------------------------------------
def test_every_framework_is_within_the_soft_contact_bound_at_180_steps(doc: str) -> None:
    said(doc, r"It would also take 11 % of a 256-trajectory batch at the default 180 steps, where every framework "
              r"is within the bound")
    cells = [r for r in machine("xeon").sweep if data.tag(r, "sweep") == "horizon" and r.scenario == "projectile"
             and (r.params or {}).get("contact") == "soft" and (r.params or {}).get("steps") == 180
             and (r.params or {}).get("batch") == 256]
    got = Counter(r.status for r in cells)
    assert got["ok"] >= 10 and set(got) <= {"ok", "skipped"}, got


# ---- scale-out ----------------------------------------------------------------------------------
def test_the_scale_out_over_two_gpus(doc: str) -> None:
    """The same 27-cell sweep on two H200s and on one: its command, its wall times (wall.txt) and
    every cell's status and error alike in the two stores."""
    cells, command, two, one = said(doc, r"the same (\d+)-cell `(sweep bandwidth [^`]+)` took ([\d.]+) s with both GPUs "
                                         r"and ([\d.]+) s with one")
    stores = {k: machine(f"h200x2-scaleout/{k}") for k in ("two", "one")}
    assert all(set(command.split()) <= set(str(e.get("command")).split()) for m in stores.values() for e in m.runs)
    wall = (RESULTS / "h200x2-scaleout" / "wall.txt").read_text()
    assert f"wall: two GPUs {two} s, one GPU {one} s" in wall
    by = {k: {r.key: r for r in m.sweep} for k, m in stores.items()}
    assert by["two"].keys() == by["one"].keys() and len(by["two"]) == int(cells)
    assert all(a.status == by["one"][k].status and a.error == by["one"][k].error for k, a in by["two"].items())



def test_the_cold_compiles_the_caches_section_repeats(doc: str) -> None:
    """*Caches* repeats the cold rounds of session 39's matrix part: the same figures as the sentence
    test_measurement_claims.py holds to the store, and the day of that run."""
    held = said(doc, r"took (\d+) s \((\d+) s a cold round; PyTorch's variants (\d+) s of it, mostly `compile`, MLX's (\d+) "
                     r"s\), the defaults' (\d+) s")
    total, per_round, torch, mlx, defaults = held
    got = said(doc, r"their cold compiles cost (\d+) s a cold round on the H100 matrix part \(([\d-]+), (\d+) cells: (\d+) s "
                    r"over three cold processes, (\d+) s of it PyTorch's, (\d+) s MLX's, against (\d+) s for the defaults\)")
    (cells,) = said(doc, r"over (\d+) cells, \d+ more than in session 26")
    assert got == (per_round, *(str(e.get("created"))[:10] for e in machine(S39).runs
                                 if str(e.get("git_commit", "")).startswith(COMMIT_39)), cells, total, torch, mlx, defaults)


def test_the_busy_row_is_published_from_its_run_of_2026_12_06(doc: str) -> None:
    """'(`--busy 1 --processes 6`: ... as the published row since 2026-12-06)': the run the CPU
    report's busy row reads (its processes: test_measurement_claims.py)."""
    (day,) = said(doc, r"across 6 processes, as the published\s+row since ([\d-]+)\)")
    (row,) = [r for r in pages.evaluate(machine("cpu"))[0] if r.rule.key == "busy"]
    assert len(row.runs) == 1 and row.runs[0].startswith(f"run {day} ")


def test_how_far_a_cells_processes_disagree(doc: str) -> None:
    """The one-process gap's reason, dated, beside what the stores' repeated cells show now: the span
    (largest over smallest) of each cell's processes' latencies, in the median over the cells."""
    said(doc, r"when the rule was set \(2026-11-26\), a cell's one-process median disagreed between worker processes by up "
              r"to 1.6×")
    spread = said(doc, r"their processes' latencies span ([\d.]+)× on the H100, ([\d.]+)× on the AMD CPU and ([\d.]+)× on "
                       r"the Xeon in the median\)")

    def spans(key: str) -> str:
        each = [f.each for r in machine(key).run if r.time and r.time.processes
                and (f := r.time.processes.figure("latency")) and len(f.each) > 1]
        return f"{statistics.median(max(v) / min(v) for v in each):.2f}"
    assert (spans("h100"), spans("cpu"), spans("xeon")) == spread


# ---- floors under --overlap ----------------------------------------------------------------------
def test_floors_under_overlap_differ_between_sittings(doc: str) -> None:
    """'Floors under --overlap ... differs between sittings': session 39's run (a sitting now) and
    session 41's (the report's) against their start checks, per framework; session 38's (nothing set
    up beside) and the float64 part's (alone, probes before set-up), from the stores."""
    us = "{:.2f}"

    def floors(key: str, commit: str = "") -> list[Record]:
        return [r for r in machine(key).records if run_of(r).startswith(commit) and r.cell_floor and r.cell_floor.before]

    def entry(key: str, commit: str, command: str = "compare all") -> dict:
        (e,) = [e for e in machine(key).runs if str(e.get("git_commit", "")).startswith(commit) and command in str(e.get("command"))]
        return dict(e)

    def figures(mine: list[Record], start: dict) -> tuple[str, ...]:
        fl = [r.cell_floor.before for r in mine if r.cell_floor and r.cell_floor.before]
        lat, pipe = statistics.median(f.latency_s for f in fl), statistics.median(f.pipelined_s for f in fl if f.pipelined_s)
        return (us.format(lat * 1e6), us.format(pipe * 1e6), f"{lat / start['launch_latency_s']:.2f}",
                f"{pipe / start['launch_pipelined_s']:.2f}", f"{start['launch_latency_s'] * 1e6:.1f}",
                f"{start['launch_pipelined_s'] * 1e6:.2f}")

    def per_framework(mine: list[Record]) -> tuple[str, str]:
        per = [statistics.median(f.cell_floor.before.latency_s for f in mine if f.backend == b and f.cell_floor
                                 and f.cell_floor.before) * 1e6 for b in {r.backend for r in mine}]
        return span(per, us), f"{max(per) / min(per):.2f}"

    for key, commit in ((S39, COMMIT_39), ("h100", COMMIT_41)):
        mine = floors(key, commit)
        assert mine and all("window" in str(r.cell_floor.before.context) for r in mine if r.cell_floor and r.cell_floor.before)
    old, new = floors(S39, COMMIT_39), floors("h100", COMMIT_41)
    assert said(doc, r"Session 39's run \(the report's until session 41\) read ([\d.]+) µs with a synchronise and ([\d.]+) µs "
                     r"pipelined in the median, ([\d.]+)× and ([\d.]+)× its quiet start check \(([\d.]+) and ([\d.]+) µs\)") == \
        figures(old, entry(S39, COMMIT_39)["sitting"]["start"])
    assert said(doc, r"every framework alike \(per-framework medians ([\d.]+-[\d.]+) µs, within ([\d.]+)×\)") == per_framework(old)
    s38 = [r.cell_floor.before for r in machine("h100/sittings/2026-12-07-session38-percall").records
           if r.cell_floor and r.cell_floor.before]
    assert said(doc, r"session 38's, with nothing set up beside, read ([\d.]+) and ([\d.]+) µs") == \
        (us.format(statistics.median(f.latency_s for f in s38) * 1e6),
         us.format(statistics.median(f.pipelined_s for f in s38 if f.pipelined_s) * 1e6))
    got = said(doc, r"Session 41's run, the same protocol and the same cells on another lease, read ([\d.]+) and ([\d.]+) µs, "
                    r"([\d.]+)× and ([\d.]+)× its quiet start check \(([\d.]+) and ([\d.]+) µs; per framework ([\d.]+-[\d.]+) µs, "
                    r"within ([\d.]+)×\)")
    assert got == (*figures(new, entry("h100", COMMIT_41)["sitting"]["start"]), *per_framework(new))
    assert {r.key for r in old} == {r.key for r in new}
    commit, alone, ratio = said(doc, r"the same store's float64 part \(commit (\w+), one cell at a time, each probe before its "
                                     r"framework's set-up\), which read ([\d.]+) µs, ([\d.]+)× its own start check")
    other = floors("h100", commit)
    assert other and all("before the framework's set-up" in str(r.cell_floor.before.context)
                         for r in other if r.cell_floor and r.cell_floor.before)
    e = entry("h100", commit, "--precision float64")
    assert not e.get("overlap") and e["sitting"].get("start")
    o = statistics.median(r.cell_floor.before.latency_s for r in other if r.cell_floor and r.cell_floor.before)
    assert us.format(o * 1e6) == alone and f"{o / e['sitting']['start']['launch_latency_s']:.2f}" == ratio
    loads = said(doc, r"its start check read a host load of ([\d.]+), session 41's ([\d.]+)")
    assert loads == tuple(f"{entry(k, c)['sitting']['start']['loadavg_1m']:.2f}" for k, c in ((S39, COMMIT_39), ("h100", COMMIT_41)))


def test_the_fast_math_cells_of_the_h100_matrix_part(doc: str) -> None:
    """'runs in one process on every device (...): 16 of the H100 matrix part's 85 cells, 4 of them
    the projectile's, capped already': the report's run's records (session 41's) and the variant list."""
    n, total, proj = said(doc, r"`backends.base.UNRANKED_VARIANTS`\): no row reads its interval or its first result "
                               r"\((\d+) of the H100 matrix part's (\d+) cells, (\d+) of them the projectile's")
    mine = [r for r in machine("h100").run if run_of(r).startswith(COMMIT_41) and r.status == "ok"]
    fast = [r for r in mine if r.variant in UNRANKED_VARIANTS]
    assert (len(fast), len(mine), sum(r.scenario == "projectile" for r in fast)) == (int(n), int(total), int(proj))



def test_the_sdf_and_the_projectile_are_capped_on_cuda(doc: str) -> None:
    """'on CUDA that is the projectile at its defaults, ... and the SDF at its defaults': the
    attribute the driver reads (test_timings_ranked.py holds it to the rows)."""
    import scenarios
    said(doc, r"\(`Scenario.timings_ranked_on`, `driver.caps`\): on CUDA that is the projectile at its defaults, "
              r"whose timed rows there are the gradient rows at batch 2\^20, and the SDF at its defaults, which no "
              r"CUDA row times")
    assert {n for n, s in scenarios.SCENARIOS.items() if s.timings_ranked_on is not None} == {"sdf", "projectile"}
    assert all(scenarios.get(s).timings_ranked_on == ("cpu",) for s in ("sdf", "projectile"))


def test_the_orderings_that_reversed_came_from_another_host(doc: str) -> None:
    """'Measured reproducibility': every second run (rerun/ and the sittings) held against its report
    on the cells both measured: none reversed on the H100; on the AMD VM only runs of the day whose
    processor was not recorded."""
    from compare.site import agreement, sittings
    (count, day) = said(doc, r"the H100 report's (\w+) second runs reverse no\s+ordering, .*? every reversal there is "
                             r"against a run of ([\d-]+), whose processor was not\s+recorded")

    def held(key: str) -> list[tuple[Any, agreement.Held]]:
        m = machine(key)
        others = [machine(f"{key}/rerun"), *(o for _, o in sittings.load_all([RESULTS / key]))]
        return [(o, agreement.hold(m, o)) for o in others]
    h100 = held("h100")
    assert len(h100) == {"nine": 9, "ten": 10, "eleven": 11}[count] and not any(h.reversed for _, h in h100)
    report = {e.get("cpu_id") for e in machine("cpu").runs if e.get("cpu_id")}
    amd = held("cpu")
    reversed_in = [o for o, h in amd if h.reversed]
    assert reversed_in and all({str(e.get("created"))[:10] for e in o.runs} == {day} and not any(e.get("cpu_id") for e in o.runs)
                               for o in reversed_in)
    same = [h for o, h in amd if {e.get("cpu_id") for e in o.runs} <= report]
    assert same and not any(h.reversed for h in same)
