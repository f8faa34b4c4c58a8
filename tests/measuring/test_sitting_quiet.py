"""compare/measuring/sitting_quiet.py: the quiet sittings of a machine kind, learned from stored runs
(fast tier), and the H100 store's figures docs/measurement.md quotes."""
from __future__ import annotations

import json

import pytest

from compare.measuring import sitting, sitting_quiet as sq

H100 = "NVIDIA H100 80GB HBM3"


def gpu_run(lat_us: float, pipe_us: float, gpu: str = H100, **more) -> dict:
    return {"created": "t", "gpus": [{"name": gpu, "driver": "1", "memory": "1 MiB"}], **more,
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


def test_a_merged_entry_counts_its_runs_and_the_cpu_kind_names_the_processor():
    cpu = {"cpu": "AMD EPYC", "cpu_id": "family 25, model 17, stepping 1", "cores": 2,
           "hardware": {"cpu": {"copy_bytes_per_s": 3e10}}}
    runs = sq.stored_runs([]) + [{"merged_from": ["a"], "environments": [cpu] * 4}]
    kind = sq.kind_of("cpu", None, "AMD EPYC", "family 25, model 17, stepping 1", 2)
    flat = [r for env in runs for r in sq._runs(env)]
    got = sq.quiet(flat, "cpu", kind)
    assert got is not None and got.runs == 4 and got.copy_bytes_per_s == 3e10 and got.launch_latency_s is None
    assert sq.quiet(flat, "cpu", sq.kind_of("cpu", None, "AMD EPYC", "", 2)) is None   # another processor


def test_the_h100_store_gives_the_limits_measurement_md_states():
    """docs/measurement.md, "The sitting check", quotes these: rerun and update it when the store changes."""
    runs = sq.stored_runs(sq.repository_stores())
    q = sq.quiet(runs, "cuda", H100)
    assert q is not None and q.runs == 21
    assert round(q.launch_latency_s * 1e6, 1) == 10.5 and round(q.launch_pipelined_s * 1e6, 2) == 5.09
    refused = [r for r in runs if (hw := (r.get("hardware") or {}).get("cuda")) and sitting.judge(
        sitting.SittingCheck.of(device="cuda", launch_latency_s=hw["launch_latency_s"],
                                launch_pipelined_s=hw["launch_pipelined_s"], copy_bytes_per_s=hw["copy_bytes_per_s"]), q)]
    assert len(refused) == 11
    published = next(r for r in runs if str(r.get("created")).startswith("2026-11-27T20:28"))
    assert published in refused                      # the run that timed the published per-call rows
