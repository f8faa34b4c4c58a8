"""The projectile scenario's part in the measurement sweeps (``compare.sweep.points``)."""
from __future__ import annotations

from typing import Mapping

import numpy as np

from compare.results.record import Record
from compare.sweep import converged
from compare.sweep.converged import REF_FACTOR, Cache, Converged, Param, Reference
from compare.sweep.points import Knob, Outputs, Point, Sweeps
from scenarios.base import dtype_of
from scenarios.base import Precision


# Time-against-error sweep: dt halves down the list at a fixed simulated time PROJECTILE_T (the
# default 180 steps of 0.025 s; every dt divides it exactly), loss and gradient at v0 (iters 0),
# soft contact unless the sweep's --set contact=... says otherwise.
PROJECTILE_T = 4.5
PROJECTILE_DT = {False: (0.05, 0.025, 0.0125, 0.00625, 0.003125, 0.0015625), True: (0.05, 0.025)}
PROJECTILE_CONTACT = "soft"
# Gradient-throughput sweep: B = 1 ... 2^20 on CUDA (to 2^16 on a CPU), hard contact (the seeds'
# bounce), 21 evaluations per run; 64 trajectories of each batch checked against the oracle.
BATCH_SWEEP = {("cuda", False): tuple(4**k for k in range(11)), ("cpu", False): tuple(16**k for k in range(5)),
               ("cuda", True): (1, 64, 4096), ("cpu", True): (1, 256)}
BATCH_SWEEP_PARAMS: dict[str, Param] = {"contact": "hard", "iters": 20}
# Horizon sweep (one loss + gradient per trajectory at a fixed batch): AD memory per trajectory-
# step and the share of gradients that agree with finite differences, per contact model. Soft
# contact stops at 2000 steps: its oracle bound costs O(steps^2) per checked trajectory.
HORIZON_BATCH = {("cuda", False): 4096, ("cpu", False): 256, ("cuda", True): 256, ("cpu", True): 16}
HORIZON_STEPS: dict[bool, dict[str, tuple[int, ...]]] = {
    False: {"none": (180, 1000, 3000, 10000), "hard": (180, 1000, 3000, 10000), "soft": (180, 600, 2000)},
    True: {"hard": (180, 600)}}         # --quick: the memory figure's contact, two horizons


class ProjectileSweeps(Sweeps):
    error_metric = "max(rel. error of loss, rel. error of |grad|) at v0 against the reference"
    labels = {"error_axis": "max rel. error of loss, grad vs converged ref. (log)",
              "items": "trajectories", "item_rate": "trajectory-gradients", "rate_work": "gradients",
              "horizon_items": "batch", "horizon_memory": '{"contact": "hard"}'}

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        if kind == "scaling":     # gradient throughput against the batch
            return [Point({"batch": b, **BATCH_SWEEP_PARAMS}, Knob("batch", b), save_outputs=False)
                    for b in BATCH_SWEEP[(device, quick)]]
        if kind == "horizon":     # AD memory and gradient quality against the horizon
            batch = HORIZON_BATCH[(device, quick)]
            return [Point({"steps": n, "contact": c, "iters": 0, "batch": batch}, Knob("steps", n), save_outputs=False)
                    for c, ns in HORIZON_STEPS[quick].items() for n in ns]
        if kind != "error":
            return []
        ref = Reference(dt=min(PROJECTILE_DT[quick]) / REF_FACTOR)   # the smallest dt / REF_FACTOR
        return [Point({"dt": dt, "steps": round(PROJECTILE_T / dt), "iters": 0, "contact": PROJECTILE_CONTACT},
                      Knob("dt", dt), ref) for dt in PROJECTILE_DT[quick]]

    def converged_error(self, params: Mapping[str, Param], outputs: Outputs | None, record: Record,
                        cache: Cache, reference: Reference | None = None) -> Converged | None:
        """Loss and gradient at v0 against a float64 rollout + adjoint at the sweep point's
        reference dt (default: the full sweep's smallest dt / REF_FACTOR)."""
        if outputs is None:
            return None
        return self.against_dt_reference(params, outputs, cache, reference, min(PROJECTILE_DT[False]) / REF_FACTOR,
                                         converged.converged_loss_grad, converged.loss_grad_error, PROJECTILE_T,
                                         ("loss", "grad"))

    def state_bytes_per_step(self, precision: Precision) -> float:
        """x, y, vx, vy: what a tape that stores every step must keep at the least."""
        return 4.0 * np.dtype(dtype_of(precision)).itemsize


SWEEPS = ProjectileSweeps()
