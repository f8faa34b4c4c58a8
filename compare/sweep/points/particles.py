"""The particles scenario's part in the measurement sweeps (``compare.sweep.points``)."""
from __future__ import annotations

from typing import Mapping

from compare.results.record import Record
from compare.sweep import converged
from compare.sweep.converged import REF_FACTOR, Cache, Converged, Param, Reference
from compare.sweep.points import Knob, Outputs, Point, Sweeps


# Time-against-error sweep: dt halves down the list at a fixed simulated time PARTICLES_T (the
# default 300 steps of 0.01 s; every dt divides it exactly). Scaling sweep: n per (device, quick).
PARTICLES_T = 3.0
PARTICLES_DT = {False: (0.04, 0.02, 0.01, 0.005, 0.0025, 0.00125), True: (0.02, 0.01)}
PARTICLES_N = {("cpu", False): (256, 4096, 65536, 1 << 20), ("cpu", True): (256, 4096),
               ("cuda", False): (256, 4096, 65536, 1 << 20, 1 << 22, 1 << 24),
               ("cuda", True): (256, 4096, 65536, 1 << 20)}
SCALING_CHECKED = 4096         # particles checked against the oracle in a large scaling cell


class ParticlesSweeps(Sweeps):
    error_metric = "RMS over particles of |position - reference| [m] at the same simulated time"
    large = {"cuda": (24,), "cpu": (20,)}
    large_quick = (12,)
    large_variants = ("default", "graph")
    large_sampled = True
    labels = {"error_axis": "RMS position error vs converged ref. [m] (log)",
              "per_run": "steps", "item_rate": "particle-steps"}      # items: the scenario's own word

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        if kind == "error":        # reference: the smallest dt / REF_FACTOR
            ref = Reference(dt=min(PARTICLES_DT[quick]) / REF_FACTOR)
            return [Point({"dt": dt, "steps": round(PARTICLES_T / dt)}, Knob("dt", dt), ref)
                    for dt in PARTICLES_DT[quick]]
        if kind == "scaling":      # no trajectory: every array is per particle, so sampled checks
            return [Point({"n": n, "record_every": 0}, Knob("n", n), check_sample=SCALING_CHECKED,
                          save_outputs=False) for n in PARTICLES_N.get((device, quick), ())]
        return []

    def converged_error(self, params: Mapping[str, Param], outputs: Outputs | None, record: Record,
                        cache: Cache, reference: Reference | None = None) -> Converged | None:
        """Positions at PARTICLES_T against a float64 rollout at the sweep point's reference dt
        (default: the full sweep's smallest dt / REF_FACTOR)."""
        if outputs is None:
            return None
        return self.against_dt_reference(params, outputs, cache, reference, min(PARTICLES_DT[False]) / REF_FACTOR,
                                         converged.converged_positions, converged.position_error, PARTICLES_T,
                                         ("x", "y"))


SWEEPS = ParticlesSweeps()
