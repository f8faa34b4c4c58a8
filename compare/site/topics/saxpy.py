"""SAXPY on the site: large bandwidth-bound arrays, and the per-call cost of a small kernel."""
from __future__ import annotations

from compare.render import charts
from compare.site import data, datasheet, fmt, matrix
from compare.site.harness import harness_table
from compare.site.matrix import Rule, defaults_of, largest_of, regime
from compare.site.questions_pages import Ctx, Page, _bar, _group, _label, _launch_yardstick, _host_share, \
    timing_table, verdicts
from compare.site.render import Figure, H, P
from compare.site.topics import scenario_of

SCENARIO = scenario_of(__name__)
SMALL = True

RULES = (
    Rule("bandwidth", "Large bandwidth-bound arrays", "bandwidth", "s", "lower",
         "SAXPY (out = a·x + y, float32) at the largest n above its default in the records that two or more frameworks "
         "ran; time per call in the throughput regime (k calls, one synchronise); "
         f"{matrix.VARIANT_RULE}.",
         largest_of(SCENARIO, (None, "bandwidth"), data.beyond_defaults), regime("throughput")),
    Rule("latency", "Small kernel: one synchronised call", "per-call", "s", "lower",
         "SAXPY at its default n = 10^6, float32: median time of one call followed by a "
         f"synchronise (the latency regime), {matrix.VARIANT_RULE}.",
         defaults_of(SCENARIO), regime("latency")),
    Rule("pipelined", "Small kernel: pipelined calls", "per-call", "s", "lower",
         "SAXPY at n = 10^6, float32: per-call time of k back-to-back calls and one synchronise "
         f"(the throughput regime), {matrix.VARIANT_RULE}.",
         defaults_of(SCENARIO), regime("throughput")),
    Rule("graph", "Small kernel: graph replay", "per-call", "s", "lower",
         "SAXPY at n = 10^6, float32: per-call time of a captured call replayed (CUDA graphs, or "
         "the framework's own graph variant); a framework without replay has no cell.",
         defaults_of(SCENARIO), regime("graph")),
)


def bandwidth(c: Ctx) -> Page:
    rows = c.rows_of("bandwidth")
    blocks: Page = [P("Bandwidth-bound array work: SAXPY reads two arrays and writes one. At large n "
                      "each framework's kernel meets the memory system; the hardware fraction is "
                      "the scenario's floor (its bytes at the same-run copy yardstick, no framework "
                      "involved) divided by the time. A fraction is labelled `cache` where the "
                      "working set fits the GPU's L2 (or exceeds the copy with no L2 known), so "
                      "cache, not DRAM, serves it, and `above copy` where it exceeds 1 beyond the "
                      "L2: SAXPY reads two arrays per one written, a mix that moves a few percent "
                      "more bytes per second than the copy's one read per write (not profiled), "
                      "or a CPU copy's own limits (`docs/measurement.md`, the hardware yardstick).")]
    blocks += verdicts(rows)
    big = matrix.largest_of(SCENARIO, (None, "bandwidth"), data.beyond_defaults)(c.m, c.device)
    allvar = [r for r in c.m.records if r.device == c.device and r.scenario == SCENARIO
              and r.precision == "float32" and data.size(r) == (data.size(big[0]) if big else -1)
              and data.tag(r, "sweep") in (None, "bandwidth")]
    allvar = matrix.one_run(allvar)
    if allvar:
        gpu = next((g for r in allvar if (g := datasheet.gpu_of(r, c.m.runs))), None)
        copy = next((v for r in allvar if r.hardware and (v := data.num(r.hardware.copy_bytes_per_s))), None)
        png, rel, csv = c.fig("bandwidth-largest")
        charts.bars(png, f"SAXPY at the largest n ({data.scope(allvar)}), {c.device}, float32: per call, "
                    "throughput regime", "seconds per call (whiskers: quartiles)",
                    [_bar(r, matrix.regime("throughput")) for r in allvar], fmt=fmt.seconds)
        n = int(data.size(allvar[0]))
        blocks += [Figure(rel, "Every framework and variant at the largest n; bars sorted fastest first.",
                          c.cmd(f"run {SCENARIO} --devices {c.device} --precision float32 --variants all --set n={n}"), csv),
                   P(datasheet.words(c.device, gpu, copy)),
                   timing_table(allvar, ("latency", "throughput"),
                                lambda r: [fmt.fraction(data.hw_fraction(r), data.fraction_label(r, c.m.runs)),
                                           fmt.pct(datasheet.fraction(r, c.m.runs))],
                                ("hw fraction (of the copy)", "of the datasheet peak"))]
    sweep = [r for r in c.m.sweep if data.tag(r, "sweep") == "bandwidth" and r.scenario == SCENARIO
             and r.device == c.device and r.status == "ok"]
    if sweep:
        series = []
        for (fw, var), rs in sorted(_group(sweep).items()):
            pts = sorted((data.size(r), (r.work or {}).get("bytes", 0) / t.median / 1e9, t)
                         for r in rs if (t := data.per_call(r, "throughput") or data.timing(r, "latency")))
            if pts:
                series.append(charts.Series(_label(fw, var), fw,
                                            [p[0] for p in pts], [p[1] for p in pts]))
        png, rel, csv = c.fig("bandwidth-vs-n")
        charts.curves(png, f"SAXPY achieved bandwidth against n ({c.device}, float32, throughput regime "
                      "where measured)", "n (elements)", "GB/s (3·n·4 bytes / time)", series)
        blocks += [H("Bandwidth against size"),
                   Figure(rel, "Achieved bandwidth against n: small n is launch-bound, large n meets memory.",
                          c.cmd(f"sweep bandwidth --devices {c.device}"), csv)]
    return blocks


FLOORS = ("Each latency and pipelined figure is also given in **launch floors** of the run that "
          "timed it: `37.9 µs = 2.77 floors` is 2.77 times that run's own empty-kernel launch, with "
          "a synchronise for the latency, pipelined for the pipelined calls (the driver's yardstick, "
          "`hardware.launch_latency_s` and `launch_pipelined_s` of the record). A slow sitting slows "
          "the launch with the calls, so floors compare runs of two sittings better than seconds "
          "where the yardstick was taken minutes before the cells (a `compare run`), not across a "
          "long `compare all` (docs/results/h100/evidence/units). Graph replay is in seconds only: "
          "it travels as it is. A record without a yardstick (a CPU run) has seconds only.")
OWN_FLOORS = ("A figure in **cell floors** is divided by the cell's own floor instead of its run's yardstick: "
              "the same empty-kernel launch, probed in the cell's worker seconds before its timed window "
              "(before the framework's set-up, or at the window's opening in an overlapped run; "
              "`cell_floor.before` of the record), so the floor is of the cell's own minutes, not the "
              "run's start. `floors` alone: the run's yardstick.")


def per_call(c: Ctx) -> Page:
    from compare.site import topics
    blocks: Page = [P("What one call costs when the kernel is small: the framework's launch path, "
                      "not the arithmetic. Latency is one call and a synchronise (a step of an "
                      "interactive loop); pipelined is k calls and one synchronise (a simulation "
                      "loop); graph replay is a captured call replayed.")] + verdicts(c.rows_of("per-call"))
    recs = [r for sc in topics.SMALL for r in matrix.defaults_of(sc)(c.m, c.device)]
    mine = [r for r in recs if r.scenario == SCENARIO]
    panels = [charts.Panel(g, [_bar(r, matrix.regime(g)) for r in mine
                               if r.status != "ok" or data.per_call(r, g) is not None])
              for g in data.REGIMES]
    panels = [p for p in panels if any(b.value is not None for b in p.bars)]
    png, rel, csv = c.fig(f"per-call-{SCENARIO}")
    charts.bar_panels(png, f"SAXPY n = 10^6 ({c.device}, float32): per-call cost by regime",
                      "seconds per call (whiskers: quartiles; log scale)", panels, log=True, fmt=fmt.seconds)
    yard = _launch_yardstick([r for r in mine if r.status == "ok"])
    blocks += [Figure(rel, "Per-call cost of the default-size SAXPY in the three regimes, every variant."
                      + (f" For scale, the driver's own empty-kernel launch in the run that timed these cells: {yard}." if yard else ""),
                      c.cmd(f"run {' '.join(topics.SMALL)} --devices {c.device} --precision float32 --variants all"), csv),
               H("Every small cell"),
               *([P(FLOORS)] if any(data.floors(r, "latency") for r in recs if r.status == "ok") else []),
               *([P(OWN_FLOORS)] if any(data.own_floor(r, g) for r in recs for g in data.FLOOR_OF
                                        if r.status == "ok") else []),
               timing_table(recs, extra=_host_share, extra_headers=("host share",), floors=True)]
    if any(r.time and r.time.null for r in mine):
        blocks += [H("What the clock costs"),
                   P("The latency is the wall clock around one call and the framework's synchronise, "
                     "nothing else between the clock reads. The null call (a no-op call and the same "
                     "synchronise, in the same worker) is the floor that regime can show; device events "
                     "are a separate pass of calls (the GPU's own time of one call, never mixed into the "
                     "latency); the framework's own timing utility, where it ships one, times the same "
                     "call + synchronise as its users would, alternated with our clock in one stretch of "
                     "the worker and compared in the tool's own statistic (torch.utils.benchmark "
                     "reports the median of blocks' means: ours in blocks of its size); 'ours / own' "
                     "(the median of the rounds' ratios) near 1 says the harness adds nothing. The "
                     "last column is our latency's statistic, the median single call, in the same "
                     "stretches: a tail of slow calls lifts a mean above it."), harness_table(mine)]
    return blocks


PAGES = {"bandwidth": ("Large arrays", bandwidth), "per-call": ("Per-call cost", per_call)}
