"""compare/measuring/sitting_quiet.py: the quiet sittings of a machine kind, learned from stored runs
(fast tier), and the H100 store's figures docs/measurement.md quotes."""
from __future__ import annotations

import json

import pytest

from compare.measuring import sitting, sitting_quiet as sq

H100 = "NVIDIA H100 80GB HBM3"


def gpu_run(lat_us: float, pipe_us: float, gpu: str = H100, **more) -> dict:
    return {"created": f"t{lat_us}-{pipe_us}-{gpu}-{sorted(more)}", "gpus": [{"name": gpu, "driver": "1", "memory": "1 MiB"}], **more,
            "hardware": {"cuda": {"copy_bytes_per_s": 3e12, "launch_latency_s": lat_us * 1e-6,
                                  "launch_pipelined_s": pipe_us * 1e-6, "gpu": gpu}}}


def test_the_best_quartile_of_the_kind_is_quiet(tmp_path):
    runs = [gpu_run(x, x / 2) for x in (9.0, 10.0, 11.0, 12.0, 13.0)]
    runs += [gpu_run(1.0, 0.5, gpu="NVIDIA H200"), gpu_run(1.0, 0.5, noisy_sitting=True)]   # not counted
    (tmp_path / "results.json").write_text(json.dumps({"runs": runs[:3]}))
    (tmp_path / "sweep.json").write_text(json.dumps({"runs": runs[3:]}))
    (tmp_path / "stress.json").write_text("not json")                                   # skipped
    got = sq.quiet(sq.stored_runs([tmp_path, tmp_path]), "cuda", H100)                 # each file once
    assert got is not None and got.runs == 5 and got.kind == H100
    assert got.launch_latency_s == pytest.approx(10e-6) and got.launch_pipelined_s == pytest.approx(5e-6)
    assert got.copy_bytes_per_s == pytest.approx(3e12)
    assert sq.quiet(sq.stored_runs([tmp_path]), "cuda", "NVIDIA H200") is None        # fewer than MIN_RUNS


def test_later_sittings_are_runs_of_the_kind_and_a_run_kept_twice_counts_once(tmp_path):
    runs = [gpu_run(x, x / 2) for x in (9.0, 10.0, 11.0, 12.0)]
    (tmp_path / "results.json").write_text(json.dumps({"runs": runs[:2]}))
    later = tmp_path / "sittings" / "2026-12-06-later"
    later.mkdir(parents=True)
    (later / "results.json").write_text(json.dumps({"runs": runs[1:]}))              # runs[1] in both
    got = sq.quiet(sq.stored_runs([tmp_path]), "cuda", H100)
    assert got is not None and got.runs == 4
    assert got.launch_latency_s == pytest.approx(9.75e-6)


def test_a_merged_entry_counts_its_runs_and_the_cpu_kind_names_the_processor():
    cpu = {"cpu": "AMD EPYC", "cpu_id": "family 25, model 17, stepping 1", "cores": 2,
           "hardware": {"cpu": {"copy_bytes_per_s": 3e10}}}
    runs = sq.stored_runs([]) + [{"merged_from": ["a"], "environments": [cpu] * 4}]
    kind = sq.kind_of("cpu", None, "AMD EPYC", "family 25, model 17, stepping 1", 2)
    flat = [r for env in runs for r in sq._runs(env)]
    got = sq.quiet(flat, "cpu", kind)
    assert got is not None and got.runs == 4 and got.copy_bytes_per_s == 3e10 and got.launch_latency_s is None
    assert sq.quiet(flat, "cpu", sq.kind_of("cpu", None, "AMD EPYC", "", 2)) is None   # another processor
    unrecorded = [{**cpu, "cpu_id": None}] * 4        # enough runs, but no processor recorded: no reference
    assert sq.quiet(unrecorded, "cpu", sq.kind_of("cpu", None, "AMD EPYC", None, 2)) is None


def test_the_h100_store_refuses_its_slow_sittings_and_keeps_its_quiet_ones():
    """What docs/measurement.md's "The sitting check" says of the H100 store, held as it grows: the
    quiet figures lie inside the stored runs' range and the run that timed the first published
    per-call rows (pipelined 7.6 µs) is refused."""
    runs = sq.stored_runs(sq.repository_stores())
    q = sq.quiet(runs, "cuda", H100)
    assert q is not None and q.runs >= 21
    floors = [hw["launch_pipelined_s"] for r in runs if (hw := (r.get("hardware") or {}).get("cuda"))
              and hw.get("gpu", H100) == H100]
    assert min(floors) <= q.launch_pipelined_s <= max(floors)

    def refused(r: dict) -> bool:
        hw = r["hardware"]["cuda"]
        return bool(sitting.judge(sitting.SittingCheck.of(
            device="cuda", launch_latency_s=hw["launch_latency_s"], launch_pipelined_s=hw["launch_pipelined_s"],
            copy_bytes_per_s=hw["copy_bytes_per_s"]), q))
    # the run that timed the first published per-call rows (2026-11-27 20:28, no longer stored since
    # session 31's matrix run replaced its records): its yardstick
    first = {"hardware": {"cuda": {"launch_latency_s": 12.65e-6, "launch_pipelined_s": 7.6e-6, "copy_bytes_per_s": 3.0e12}}}
    assert refused(first)
    # measurement.md's two clusters: every stored slow sitting (pipelined 6.9 µs or more) is refused,
    # every quiet one (5.8 µs or less, with a synchronise 11.2 µs or less) passes
    h100 = [r for r in runs if (r.get("hardware") or {}).get("cuda", {}).get("gpu") == H100]
    assert all(refused(r) for r in h100 if r["hardware"]["cuda"]["launch_pipelined_s"] >= 6.9e-6)
    assert not any(refused(r) for r in h100 if r["hardware"]["cuda"]["launch_pipelined_s"] <= 5.8e-6
                   and r["hardware"]["cuda"]["launch_latency_s"] <= 11.2e-6)
    assert 4.0e-6 < q.launch_pipelined_s < 6.0e-6 and q.launch_pipelined_s * sitting.FLOOR_RATIO < 7.6e-6
