"""Clock validation table for docs/measurement.md: Nsight Compute's kernel time (ncu.csv, from
run.sh part C) against the unprofiled cells' clocks (results.json: n = 1e6, large.json: n = 2^26).
Run from the repository root: python docs/results/h100-regimes/clocks.py"""
import csv
import json
import statistics
from pathlib import Path

HERE = Path(__file__).parent
ncu: dict[tuple[str, int], list[float]] = {}
for row in csv.reader((HERE / "ncu.csv").open()):
    ncu.setdefault((row[0], int(row[1])), []).append(float(row[-1].replace(",", "")) * 1e-9)
cells = {}
for f in ("results.json", "large.json"):
    for r in json.loads((HERE / f).read_text())["records"]:
        if r["scenario"] == "saxpy" and r["precision"] == "float32" and r["variant"] == "default":
            cells[(r["backend"], r["params"]["n"])] = r["time"]


def us(x: float | None) -> str:
    return "-" if x is None else f"{x * 1e6:.3g} µs"


print("| backend | n | ncu kernel (median of 20) | CUDA events | wall latency | throughput per call "
      "| events / ncu | latency / ncu | throughput / ncu |")
print("|---|---|---|---|---|---|---|---|---|")
for (b, n), ks in sorted(ncu.items(), key=lambda kv: (kv[0][1], kv[0][0])):
    k, t = statistics.median(ks), cells[(b, n)]
    ev = t["median_s"] if t.get("timer") == "events" else None
    lat, thr = t["latency"]["median_s"], t["throughput"]["median_s"]
    print(f"| {b} | {n:,} | {us(k)} | {us(ev)} | {us(lat)} | {us(thr)} | "
          f"{'-' if ev is None else f'{ev / k:.2f}'} | {lat / k:.2f} | {thr / k:.2f} |")
