"""What the clock itself costs, per framework, from the records that timed the cells: the null
call (a no-op ``run`` and the framework's synchronise: the floor of the latency regime), the
device's time of a call (events, a separate pass), and the framework's own timing utility around
the same call + synchronise where it ships one (a cross-check of the latency regime)."""
from __future__ import annotations

from compare.results.record import Record
from compare.results.record_parts import OwnTimer
from compare.site import data, fmt
from compare.site.render import Table
from compare.measuring.timing import events_of


def harness_table(recs: list[Record]) -> Table:
    rows = []
    for r in sorted(recs, key=lambda r: (r.backend, r.variant)):
        if r.status != "ok" or r.variant == "graph":
            continue
        t = r.time
        lat = data.timing(r, "latency")
        null = data.num(t.null.median_s) if t and t.null else None
        ev = data.num(e.median_s) if (e := events_of(t)) else None
        own = (t.own_timer if t else None) or OwnTimer()
        own_s = data.num(own.median_s)
        # ours in the same process: alternated with the own timer where recorded (in its statistic
        # since the record has ``block``), else that process's latency regime (never the median
        # across processes)
        ours = (data.num(own.ours_s) or (data.num(t.latency.median_s) if t and t.latency else None)) \
            if own_s else None
        ratio = data.num(own.ratio) or (ours / own_s if ours and own_s else None)
        how = (f"{own.rounds} rounds" if own.rounds else "once") + (f", blocks of {own.block}" if own.block else "")
        rows.append((r.backend, r.variant, fmt.seconds(lat.median if lat else None), fmt.seconds(null),
                     fmt.seconds(ev), fmt.seconds(own_s), str(own.tool or own.failed or "-"),
                     fmt.seconds(ours), f"{ratio:.2f}" if ratio else "-", how if own_s else "-",
                     fmt.seconds(data.num(own.ours_call_s))))
    return Table(("framework", "variant", "latency (ours)", "null call", "device events", "own timer",
                  "own timer's tool", "ours, its statistic", "ours / own", "alternated",
                  "ours per call, same stretches"), tuple(rows))
