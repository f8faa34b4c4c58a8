"""What each scenario contributes to the measurement sweeps (docs/measurement.md), by name.

A scenario holds physics; what is swept, how the sweep pages speak of it and what its converged
error is are the sweeps' business, so they live here, one ``Sweeps`` per scenario in ``SWEEPS``.
A scenario not listed takes part in no sweep. The suite finds rows by role and tags, never by
scenario name; this registry is the one place in compare/sweep that names scenarios.
"""
from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

import scenarios
from compare.sweep import converged
from compare.sweep.converged import REF_FACTOR, SDF_EVAL, dt_reference
from scenarios.base import dtype_of

CHECK_SAMPLE = 1 << 16     # items checked against the oracle in large per-item sweep cells

Point = dict[str, Any]


class Sweeps:
    """A scenario's part in the sweeps. Default: none.

    ``measures``: the generic role the bandwidth sweep and its page find rows by: 'launch'
    (trivial-launch overhead yardstick), 'copy' (bandwidth roofline yardstick), 'bandwidth' (the
    size sweep). ``error_metric``: what ``converged_error`` measures, in words. ``labels``: the
    words the sweep page and plots use for this scenario, all optional: 'name' (display name;
    default the scenario name), 'bytes' (how the bytes per call are counted), 'error_axis'
    (time-against-error y label; '{floor}' is replaced by the value an exact 0 is drawn at), for
    the scaling sweep 'items' (what the swept size counts), 'per_run' (the parameter counted per
    run, e.g. steps), 'item_rate' (the work item), 'rate_work' (the ``work()`` key the rate
    counts), and for the horizon sweep 'horizon_items' and 'horizon_memory'
    (compare/sweep/horizon.py)."""
    scenario: str = ""                     # the scenario's name: set from SWEEPS' key
    measures: ClassVar[str | None] = None
    error_metric: ClassVar[str] = ""
    labels: ClassVar[dict[str, str]] = {}
    # ``compare publish``'s kernel-dominated sizes: log2 n per device (and for --quick), the
    # variants worth timing there, and whether the oracle checks a sample (per-item scenarios)
    large: ClassVar[dict[str, tuple[int, ...]]] = {}
    large_quick: ClassVar[tuple[int, ...]] = ()
    large_variants: ClassVar[tuple[str, ...]] = ("default",)
    large_sampled: ClassVar[bool] = False

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        """The points of sweep ``kind`` ('bandwidth', 'error', 'scaling', 'horizon') on ``device``.

        Each point: {'params': {...}, 'knob': {'name', 'value'}} (knob optional), plus optional
        cell-spec options ('check_sample', 'save_outputs') and 'reference' (what
        ``converged_error`` compares against, e.g. the dt of a converged rollout: a property of
        the sweep, not of the cell, so it is handed back to ``converged_error``, never stored
        in the cell's identity)."""
        return []

    def converged_error(self, params: dict[str, Any], outputs: dict[str, np.ndarray] | None,
                        record: dict[str, Any], cache: dict[Any, Any],
                        reference: dict[str, Any] | None = None) -> dict[str, Any] | None:
        """Error of an error-sweep cell against a converged float64 reference of the same quantity:
        {'error': ..., 'metric': ..., 'reference': {...}, ...}, or None when it cannot be measured
        (e.g. the outputs were not kept). ``params``: the cell's parameters; ``record``: its
        record; ``cache``: a dict the suite keeps for a whole run, for memoising references;
        ``reference``: the point's 'reference' (None: the scenario's default)."""
        return None

    def state_bytes_per_step(self, precision: str) -> float | None:
        """Bytes of state one item carries per step: the least a tape storing every step keeps
        (the horizon sweep draws it beside each framework's measured memory). Default: none."""
        return None


# Bandwidth-sweep sizes per (device, quick), exponents of 2: CPU sizes stop where a cell still
# takes seconds on a small machine, GPU sizes where the arrays are ~1 GiB.
SAXPY_EXP = {("cpu", False): range(10, 25, 2), ("cpu", True): range(10, 21, 5),
             ("cuda", False): range(10, 29, 2), ("cuda", True): range(10, 23, 2)}


class SaxpySweeps(Sweeps):
    measures = "bandwidth"          # the size sweep (achieved bandwidth against size)
    large = {"cuda": (26, 28), "cpu": (24, 26)}
    large_quick = (16, 18)
    large_variants = ("default", "graph", "vector", "tile")
    error_metric = "scenario metric against the float64 oracle: max |err|/(|a x|+|y|)"
    labels = {"name": "SAXPY", "bytes": "3·n·itemsize",
              "error_axis": "max |err|/(|a x|+|y|) vs float64 oracle (0 drawn at {floor:g})"}

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        if kind == "bandwidth":
            return [{"params": {"n": 1 << e}, "knob": {"name": "n", "value": 1 << e},
                     "check_sample": CHECK_SAMPLE, "save_outputs": False}
                    for e in SAXPY_EXP.get((device, quick), ())]
        if kind == "error":        # knobs: precision and variant only
            return [{"params": {"n": scenarios.get(self.scenario).params(quick=quick).n},
                     "knob": {"name": "precision", "value": None}}]
        return []

    def converged_error(self, params: dict[str, Any], outputs: dict[str, np.ndarray] | None,
                        record: dict[str, Any], cache: dict[Any, Any],
                        reference: dict[str, Any] | None = None) -> dict[str, Any] | None:
        """The oracle's error is already converged: float64 of the same rounded inputs."""
        return {"error": record["error"]["vs_oracle"], "metric": self.error_metric,
                "reference": {"note": "float64 oracle of the same rounded inputs"}}


# Time-against-error sweep: resolutions r x r per (device, quick).
SDF_RES = {("cpu", False): (64, 128, 256, 512, 1024, 2048), ("cpu", True): (32, 64, 128),
           ("cuda", False): (64, 128, 256, 512, 1024, 2048, 4096), ("cuda", True): (32, 64, 128)}


class SdfSweeps(Sweeps):
    error_metric = (f"max |bilinear(image) - f| over a {SDF_EVAL}x{SDF_EVAL} grid, "
                    "f the analytic field in float64")
    labels = {"error_axis": "max |bilinear(image) - field| (log)"}

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        if kind != "error":
            return []
        return [{"params": {"width": r, "height": r}, "knob": {"name": "resolution", "value": r}}
                for r in SDF_RES.get((device, quick), ())]

    def converged_error(self, params: dict[str, Any], outputs: dict[str, np.ndarray] | None,
                        record: dict[str, Any], cache: dict[Any, Any],
                        reference: dict[str, Any] | None = None) -> dict[str, Any] | None:
        if outputs is None:
            return None
        return {**converged.reconstruction_error(outputs["image"], cache), "metric": self.error_metric,
                "reference": {"eval_grid": SDF_EVAL, "note": "analytic field, float64"}}


# Time-against-error sweep: dt halves down the list at a fixed simulated time PARTICLES_T (the
# default 300 steps of 0.01 s; every dt divides it exactly). Scaling sweep: n per (device, quick).
PARTICLES_T = 3.0
PARTICLES_DT = {False: (0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125), True: (0.02, 0.01, 0.005)}
PARTICLES_N = {("cpu", False): (256, 4096, 65536, 1 << 20), ("cpu", True): (256, 4096, 65536),
               ("cuda", False): (256, 4096, 65536, 1 << 20, 1 << 22, 1 << 24),
               ("cuda", True): (256, 4096, 65536, 1 << 20)}
PARTICLES_CHECKED = 4096       # particles checked against the oracle in a large scaling cell


class ParticlesSweeps(Sweeps):
    error_metric = "RMS over particles of |position - reference| [m] at the same simulated time"
    large = {"cuda": (24,), "cpu": (20,)}
    large_quick = (12,)
    large_variants = ("default", "graph")
    large_sampled = True
    labels = {"error_axis": "RMS position error vs converged ref. [m] (log)",
              "items": "particles", "per_run": "steps", "item_rate": "particle-steps"}

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        if kind == "error":        # reference: the smallest dt / REF_FACTOR
            ref = {"dt": min(PARTICLES_DT[quick]) / REF_FACTOR}
            return [{"params": {"dt": dt, "steps": round(PARTICLES_T / dt)},
                     "knob": {"name": "dt", "value": dt}, "reference": ref} for dt in PARTICLES_DT[quick]]
        if kind == "scaling":      # no trajectory: every array is per particle, so sampled checks
            return [{"params": {"n": n, "record_every": 0}, "knob": {"name": "n", "value": n},
                     "check_sample": PARTICLES_CHECKED, "save_outputs": False}
                    for n in PARTICLES_N.get((device, quick), ())]
        return []

    def converged_error(self, params: dict[str, Any], outputs: dict[str, np.ndarray] | None,
                        record: dict[str, Any], cache: dict[Any, Any],
                        reference: dict[str, Any] | None = None) -> dict[str, Any] | None:
        """Positions at PARTICLES_T against a float64 rollout at the sweep point's reference dt
        (default: the full sweep's smallest dt / REF_FACTOR)."""
        if outputs is None:
            return None
        ref, info = dt_reference(cache, scenarios.get(self.scenario), params, reference,
                                 min(PARTICLES_DT[False]) / REF_FACTOR,
                                 converged.converged_positions,
                                 lambda a, b: converged.position_error(*a, *b)["error"], PARTICLES_T)
        return {**converged.position_error(outputs["x"], outputs["y"], *ref), "metric": self.error_metric,
                "reference": info}


# Time-against-error sweep: dt halves down the list at a fixed simulated time PROJECTILE_T (the
# default 180 steps of 0.025 s; every dt divides it exactly), loss and gradient at v0 (iters 0),
# soft contact unless the sweep's --set contact=... says otherwise.
PROJECTILE_T = 4.5
PROJECTILE_DT = {False: (0.05, 0.025, 0.0125, 0.00625, 0.003125, 0.0015625), True: (0.05, 0.025, 0.0125)}
PROJECTILE_CONTACT = "soft"
# Gradient-throughput sweep: B = 1 ... 2^20 on CUDA (to 2^16 on a CPU), hard contact (the seeds'
# bounce), 21 evaluations per run; 64 trajectories of each batch checked against the oracle.
BATCH_SWEEP = {("cuda", False): tuple(4**k for k in range(11)), ("cpu", False): tuple(16**k for k in range(5)),
               ("cuda", True): (1, 64, 4096), ("cpu", True): (1, 16, 256)}
BATCH_SWEEP_PARAMS = {"contact": "hard", "iters": 20}
# Horizon sweep (one loss + gradient per trajectory at a fixed batch): AD memory per trajectory-
# step and the share of gradients that agree with finite differences, per contact model. Soft
# contact stops at 2000 steps: its oracle bound costs O(steps^2) per checked trajectory.
HORIZON_BATCH = {("cuda", False): 4096, ("cpu", False): 256, ("cuda", True): 256, ("cpu", True): 16}
HORIZON_STEPS = {False: {"none": (180, 1000, 3000, 10000), "hard": (180, 1000, 3000, 10000),
                         "soft": (180, 600, 2000)},
                 True: {"none": (180, 600), "hard": (180, 600), "soft": (180, 300)}}


class ProjectileSweeps(Sweeps):
    error_metric = "max(rel. error of loss, rel. error of |grad|) at v0 against the reference"
    labels = {"error_axis": "max rel. error of loss, grad vs converged ref. (log)",
              "items": "trajectories", "item_rate": "trajectory-gradients", "rate_work": "gradients",
              "horizon_items": "batch", "horizon_memory": '{"contact": "hard"}'}

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        if kind == "scaling":     # gradient throughput against the batch
            return [{"params": {"batch": b, **BATCH_SWEEP_PARAMS}, "knob": {"name": "batch", "value": b},
                     "save_outputs": False} for b in BATCH_SWEEP[(device, quick)]]
        if kind == "horizon":     # AD memory and gradient quality against the horizon
            batch = HORIZON_BATCH[(device, quick)]
            return [{"params": {"steps": n, "contact": c, "iters": 0, "batch": batch},
                     "knob": {"name": "steps", "value": n}, "save_outputs": False}
                    for c, ns in HORIZON_STEPS[quick].items() for n in ns]
        if kind != "error":
            return []
        ref = {"dt": min(PROJECTILE_DT[quick]) / REF_FACTOR}   # reference: the smallest dt / REF_FACTOR
        return [{"params": {"dt": dt, "steps": round(PROJECTILE_T / dt), "iters": 0,
                            "contact": PROJECTILE_CONTACT},
                 "knob": {"name": "dt", "value": dt}, "reference": ref} for dt in PROJECTILE_DT[quick]]

    def converged_error(self, params: dict[str, Any], outputs: dict[str, np.ndarray] | None,
                        record: dict[str, Any], cache: dict[Any, Any],
                        reference: dict[str, Any] | None = None) -> dict[str, Any] | None:
        """Loss and gradient at v0 against a float64 rollout + adjoint at the sweep point's
        reference dt (default: the full sweep's smallest dt / REF_FACTOR)."""
        if outputs is None:
            return None
        ref, info = dt_reference(cache, scenarios.get(self.scenario), params, reference,
                                 min(PROJECTILE_DT[False]) / REF_FACTOR,
                                 converged.converged_loss_grad,
                                 lambda a, b: converged.loss_grad_error(*a, *b)["error"], PROJECTILE_T)
        return {**converged.loss_grad_error(outputs["loss"], outputs["grad"], *ref),
                "metric": self.error_metric, "reference": info}

    def state_bytes_per_step(self, precision: str) -> float:
        """x, y, vx, vy: what a tape that stores every step must keep at the least."""
        return 4.0 * np.dtype(dtype_of(precision)).itemsize


class LaunchSweeps(Sweeps):
    measures = "launch"          # the trivial-launch overhead yardstick

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        return [{"params": {"n": 1}}] if kind == "bandwidth" else []


# Bandwidth-sweep size per (device, quick): far beyond the caches; on the GPU ~1 GiB per array.
COPY_N = {("cpu", False): 1 << 25, ("cpu", True): 1 << 22,
          ("cuda", False): 1 << 28, ("cuda", True): 1 << 24}


class CopySweeps(Sweeps):
    measures = "copy"            # the bandwidth yardstick (the roofline)

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        if kind != "bandwidth" or (device, quick) not in COPY_N:
            return []
        return [{"params": {"n": COPY_N[device, quick]}, "check_sample": CHECK_SAMPLE,
                 "save_outputs": False}]


SWEEPS: dict[str, Sweeps] = {"saxpy": SaxpySweeps(), "sdf": SdfSweeps(), "particles": ParticlesSweeps(),
                             "projectile": ProjectileSweeps(), "launch": LaunchSweeps(), "copy": CopySweeps()}
for _name, _sweeps in SWEEPS.items():       # the registry's key is the one place a scenario is named
    _sweeps.scenario = _name
NONE = Sweeps()


def sweeps(scenario: str) -> Sweeps:
    """``scenario``'s part in the sweeps (none for a scenario not registered)."""
    return SWEEPS.get(scenario, NONE)
