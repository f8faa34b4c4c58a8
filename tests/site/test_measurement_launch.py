"""docs/measurement.md's figures of the H100 store's launch paths and fractions of the copy, computed
from the store with the site's own code (issue 57, item 5; the other figures:
test_measurement_claims.py). Each test reads the sentence and the store, so a change to either
fails it. Fast tier."""
from __future__ import annotations

import re

import pytest

from compare.results.record import Record
from compare.site import data, matrix
from measurement_doc import NAMES, RULES, doc_text, machine, names, said, span

pytestmark = pytest.mark.xdist_group("measurement-claims")


@pytest.fixture(scope="module")
def doc() -> str:
    return doc_text()


# ---- fractions of the copy -----------------------------------------------------------------------
def pct(r: Record) -> float:
    v = data.hw_fraction(r)
    assert v is not None, (r.backend, r.variant)
    return 100 * v


def saxpy(precision: str, n: int) -> list[Record]:
    return [r for r in machine("h100").records if r.scenario == "saxpy" and r.device == "cuda" and r.status == "ok"
            and r.precision == precision and (r.params or {}).get("n") == n]


def test_the_h100_fractions_of_the_copy(doc: str) -> None:
    m = machine("h100")
    cache = [pct(r) for r in saxpy("float64", 10**6) if data.fraction_label(r, m.runs) == "cache"]
    assert said(doc, r"\(float64 SAXPY at n = 10\^6: 24 MB, up to (\d+) % on the H100\)")[0] == f"{max(cache):.0f}"
    above = [pct(r) for r in RULES["bandwidth"].pick(m, "cuda") if data.fraction_label(r, m.runs) == "above copy"]
    assert said(doc, r"\(SAXPY at n = 2\^28 on the H100, (\S+) %:")[0] == span(above)
    large = saxpy("float32", 2**26) + saxpy("float32", 2**28)

    def of(fw: str, variant: str) -> str:
        return span(pct(r) for r in large if (r.backend, r.variant) == (fw, variant))
    assert said(doc, r"CuPy's SAXPY reaches (\S+) % of the memcpy")[0] == of("cupy", "default")
    assert said(doc, r"Warp sits at (\S+) % with one scalar load")[0] == of("warp", "default")
    assert said(doc, r"a `RawKernel` with 16-byte loads and stores, (\S+) %;")[0] == of("cupy", "vector")
    tile, both = said(doc, r"8 elements of each input in flight per thread, (\S+) % \(the sweep of 2026-12-06: (\d+) % "
                           r"for both at 2\^28\)")
    assert tile == of("warp", "tile")
    sweep = [r for r in saxpy("float32", 2**28) if data.tag(r, "sweep") == "bandwidth"
             and str((r.run or {}).get("created")).startswith("2026-12-06") and r.variant in ("vector", "tile")]
    assert len(sweep) == 2 and {f"{pct(r):.0f}" for r in sweep} == {both}
    torch = {f"{pct(r):.0f}" for r in saxpy("float32", 2**26) if (r.backend, r.variant) == ("torch", "default")}
    assert torch == {said(doc, r"which moved it from 56 % to (\d+) % of the memcpy")[0]}


# ---- launch paths --------------------------------------------------------------------------------
def per_call_run() -> list[Record]:
    """The H100 run the per-call rows read: its float32 cells at the default sizes."""
    created = {(r.run or {}).get("created") for r in RULES["pipelined"].pick(machine("h100"), "cuda")}
    assert len(created) == 1
    return [r for r in machine("h100").run if (r.run or {}).get("created") in created and r.status == "ok"
            and r.device == "cuda" and r.precision == "float32" and data.at_defaults(r)]


def host_share(r: Record) -> float | None:
    """The host's time issuing a call over the call (None: a call of 20 ms or more is its own batch)."""
    thr = r.time.throughput if r.time else None
    host, per = (data.num(thr.host_s), data.num(thr.median_s)) if thr else (None, None)
    return host / per if host is not None and per else None


def test_where_the_throughput_regime_is_host_bound(doc: str) -> None:
    within, count, listed = said(doc, r"is within (\d+) % of the same process's per-call time in every float32 SAXPY, SDF "
                                      r"and particles cell of the H100 run that the per-call rows read, at the default "
                                      r"sizes, but (\d+): (.*?)\. ")
    cells = [r for r in per_call_run() if r.scenario in ("saxpy", "sdf", "particles")]
    whole = [r for r in cells if host_share(r) is None]
    assert {r.backend for r in whole} == {NAMES[said(doc, r"([\w.]+)'s eager particle loop has no such figure")[0]]}
    assert all(r.time and r.time.throughput and r.time.throughput.same_as == "latency" for r in whole)
    cells = [r for r in cells if r not in whole]
    shares = {(r.backend, r.variant, r.scenario): host_share(r) or 0 for r in cells}
    off = {k: f"{100 * v:.0f}" for k, v in shares.items() if abs(v - 1) > int(within) / 100}
    words = re.findall(r"([\w.]+)'s (?:`(\w+)` variant of )?(\w+) \((\d+) %\)", listed)
    assert {(NAMES[w], v or "default", s.lower(), p) for w, v, s, p in words} == {(*k, p) for k, p in off.items()}
    assert int(count) == len(off)
    projectile = {r.backend: host_share(r) or 0 for r in per_call_run()
                  if r.scenario == "projectile" and r.variant == "default"}
    fws, share = said(doc, r"in one kernel \(([\w, ]+): host (\S+) % of the call\) and for Warp's graph replays")
    assert span(100 * projectile[f] for f in names(fws)) == share and projectile["warp"] < 0.05


def test_the_launch_target_against_the_store(doc: str) -> None:
    """The issue's 2× target: pipelined within 2× of the same run's driver launch, over SAXPY, SDF,
    particles and the empty launch at their defaults (the bandwidth sweep times the empty launch)."""
    four = ("saxpy", "sdf", "particles", "launch")
    recs = matrix.latest([r for r in machine("h100").records if r.scenario in four and r.status == "ok"
                          and r.device == "cuda" and r.precision == "float32" and data.at_defaults(r)])
    cell = {(r.backend, r.variant, r.scenario): r for r in recs}

    def ratio(r: Record, regime: str) -> float | None:
        t = data.per_call(r, regime) if regime == "throughput" else data.timing(r, regime)
        floor = data.num(r.hardware.launch_pipelined_s) if r.hardware else None
        return t.median / floor if t and floor else None

    def meets(fw: str, regime: str, variant: str = "default") -> set[str]:
        return {s for s in four if (r := cell.get((fw, variant, s))) and (x := ratio(r, regime)) is not None and x <= 2}
    frameworks = {fw for fw, _, _ in cell}
    plain = {fw for fw in frameworks if meets(fw, "throughput") == set(four)}
    graph = {fw for fw in frameworks if meets(fw, "graph") == set(four)}
    (who,) = said(doc, r"plain launches meet it in all four for (no framework|\S+ alone)")
    assert plain == (set() if who == "no framework" else {NAMES[who.removesuffix(" alone")]})
    (near,) = said(doc, r"its SAXPY and particles take (\S+)× the run's launch")
    assert span((ratio(cell[("cupy", "default", s)], "throughput") or 0 for s in ("saxpy", "particles")), "{:.2g}") == near
    assert meets("warp", "throughput", "record_cmd") == set(four)
    us, rec, launch = said(doc, r"`record_cmd` variant: (\S+) µs pipelined, (\S+)× the driver's launch in the same run, "
                                r"where `wp.launch` costs (\S+)×\)")
    mine = [cell[("warp", "record_cmd", s)] for s in four]
    pipelined = [data.per_call(r, "throughput") for r in mine]
    assert us == span((t.median * 1e6 for t in pipelined if t), "{:.2g}") and all(pipelined)
    assert rec == span((ratio(r, "throughput") or 0 for r in mine), "{:.2g}")
    assert launch == span((ratio(cell[("warp", "default", s)], "throughput") or 0 for s in four), "{:.2g}")
    assert graph == names(said(doc, r"Graph replays meet it in all four for (.*?)\. ")[0])
    sdf, particles = said(doc, r"so they meet it for SAXPY and the empty launch only \(a replay of SDF takes (\S+) µs, "
                               r"of particles (\S+) ms\)")
    assert meets("torch", "graph") == {"saxpy", "launch"}
    replay = [data.timing(cell[("torch", "default", s)], "graph") for s in ("sdf", "particles")]
    assert replay[0] and replay[1]
    assert (sdf, particles) == (f"{replay[0].median * 1e6:.2g}", f"{replay[1].median * 1e3:.3g}")
    upstream, none = said(doc, r"The others meet it in all four neither way: ([\w, ]+) for the upstream reasons in the table "
                               r"\(.*?\), ([\w.]+ and \w+) with no graph path here")
    assert names(upstream) | names(none) == frameworks - plain - graph - {"warp", "torch"}
    assert not any(ratio(r, "graph") for (fw, _, _), r in cell.items() if fw in names(upstream) | names(none))


def test_what_jax_command_buffers_and_torch_graphs_change(doc: str) -> None:
    run = {(r.backend, r.variant, r.scenario): r for r in per_call_run()}

    def per(fw: str, variant: str, scenario: str) -> float:
        t = data.per_call(run[(fw, variant, scenario)], "throughput")
        assert t is not None
        return t.median
    got = said(doc, r"the particles rollout \(300 steps\) drops from (\d+) to (\d+) µs a call, and the projectile "
                    r"\(a while loop of 180 steps per evaluation\) from (\S+) ms to (\S+) ms, no longer host-bound "
                    r"\(host (\S+) ms a call\)")
    graph = run[("jax", "graph", "projectile")]
    host = graph.time.throughput.host_s if graph.time and graph.time.throughput else None
    assert host is not None
    assert got == (f"{per('jax', 'default', 'particles') * 1e6:.0f}", f"{per('jax', 'graph', 'particles') * 1e6:.0f}",
                   f"{per('jax', 'default', 'projectile') * 1e3:.3g}", f"{per('jax', 'graph', 'projectile') * 1e3:.3g}",
                   f"{host * 1e3:.2g}")
    big = [r for r in machine("h100").records
           if (r.backend, r.variant, r.scenario, r.device) == ("torch", "default", "particles", "cuda")
           and r.status == "ok" and (r.params or {}).get("n") == 2**24
           and r.time and r.time.throughput and r.time.throughput.host_s]
    call, issue, cut = said(doc, r"\(particles at n = 2\^24: (\d+) ms a call, (\d+) ms of it issuing\), which its CUDA graph "
                                 r"cuts by (\S+)× at the default size")
    thr = big[0].time.throughput if len(big) == 1 and big[0].time else None
    assert thr is not None and thr.median_s and thr.host_s
    assert (call, issue) == (f"{thr.median_s * 1e3:.0f}", f"{thr.host_s * 1e3:.0f}")
    replay = data.timing(run[("torch", "default", "particles")], "graph")
    assert replay is not None and cut == f"{per('torch', 'default', 'particles') / replay.median:.2g}"
