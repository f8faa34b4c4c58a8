"""One cell, in its own process: ``python -m compare.worker SPEC.json OUT_DIR``.

Process-global framework state (ti.init's precision, JAX's x64 flag, CUDA contexts) lives and dies
with this process, and a crash here becomes an ``error`` record in the parent, not a lost run.
Writes OUT_DIR/record.json and OUT_DIR/outputs.npz (the outputs, for cross-backend comparison).
"""
from __future__ import annotations

import dataclasses
import json
import os
import platform
import sys
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

import backends
import scenarios
from compare import timing


def jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        x = float(x)
        return x if np.isfinite(x) else str(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def peak_rss_bytes() -> int:
    """Peak resident set size of this worker (the cell alone: each cell has its own process)."""
    import resource
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * 1024   # Linux reports KiB


def injected_fault(spec: dict[str, Any]) -> str | None:
    """Test hook: COMPARE_FAULT="<scenario>/<backend>:<kind>" (kind: crash, hang, raise, mismatch)
    makes matching cells misbehave, so the driver's handling of each failure can be tested."""
    rule = os.environ.get("COMPARE_FAULT", "")
    if ":" not in rule:
        return None
    target, kind = rule.rsplit(":", 1)
    return kind if target == f"{spec['scenario']}/{spec['backend']}" else None


def run_cell(spec: dict[str, Any], out_dir: Path) -> dict[str, Any]:
    """Build, time, download and check one cell. Exceptions propagate (the parent records them)."""
    sc = scenarios.get(spec["scenario"])
    be = backends.get(spec["backend"])
    device, precision, variant = spec["device"], spec["precision"], spec.get("variant", "default")
    params = sc.params(spec.get("params", {}), quick=spec.get("quick", False))
    inputs = sc.inputs(params, precision)

    be.setup(device, precision, variant)
    sync = lambda r: be.synchronize(device, r)  # noqa: E731
    t0 = time.perf_counter()
    kernel = be.kernel(sc.name)(params, inputs, device, precision, variant)
    sync(None)
    setup_s = time.perf_counter() - t0
    first_call_s = timing.call(kernel.run, sync)
    t = timing.steady_state(kernel.run, sync, repeat=spec.get("repeat", 10),
                            min_time=spec.get("min_time", 0.2), max_time=spec.get("max_time", 10.0))
    t0 = time.perf_counter()
    outputs = {k: np.asarray(v) for k, v in kernel.outputs().items()}
    download_s = time.perf_counter() - t0

    fault = injected_fault(spec)
    if fault == "crash":
        os.abort()
    if fault == "hang":
        time.sleep(10**6)
    if fault == "raise":
        raise RuntimeError("injected fault")
    if fault == "mismatch":
        outputs = {k: v + np.asarray(1, v.dtype) if v.dtype.kind == "f" else v for k, v in outputs.items()}

    reference = sc.oracle(params, inputs)
    check = sc.check(params, inputs, outputs, reference, precision)
    work = sc.work(params, precision)
    record: dict[str, Any] = {
        "status": "ok" if check.ok else "mismatch",
        "reason": "" if check.ok else f"error {check.error:.3g} exceeds tolerance {check.tolerance:.3g}",
        "params": dataclasses.asdict(params),
        "time": {"first_call_s": first_call_s, **t, "setup_s": setup_s, "download_s": download_s,
                 "clock": timing.CLOCK},
        "error": {"vs_oracle": check.error, "tolerance": check.tolerance, "vs_warp": None,
                  **{k: v for k, v in check.details.items()}},
        "work": work,
        "throughput": {f"{k}_per_s": v / t["median_s"] for k, v in work.items() if t["median_s"] > 0},
        "memory": {"peak_host_rss_bytes": peak_rss_bytes(), **be.memory(device)},
        "info": kernel.info(),
        "host": platform.node(),
        "versions": be.versions(),
    }
    if sc.has_gradient:
        record["gradient"] = {
            "method": be.gradient_method,
            "value": outputs["grad"],
            "reference": check.details.get("gradient_reference"),
            "reference_value": reference["grad"],
            "vs_oracle": check.details.get("gradient_error"),
            "vs_oracle_rel": check.details.get("gradient_rel_error"),
            "tolerance": check.details.get("gradient_tolerance"),
        }
    np.savez(out_dir / "outputs.npz", **outputs)
    if spec.get("save_inputs"):
        np.savez(out_dir / "inputs.npz", **inputs)
    return record


def main(argv: list[str]) -> int:
    spec = json.loads(Path(argv[0]).read_text())
    out_dir = Path(argv[1])
    try:
        record = run_cell(spec, out_dir)
    except Exception as exc:  # the record says what went wrong; the parent keeps going
        record = {"status": "error", "reason": f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}",
                  "traceback": traceback.format_exc()}
    (out_dir / "record.json").write_text(json.dumps(jsonable(record)))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
