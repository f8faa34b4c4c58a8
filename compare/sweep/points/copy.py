"""The copy scenario's part in the measurement sweeps (``compare.sweep.points``)."""
from __future__ import annotations

from compare.sweep.points import CHECK_SAMPLE, Point, Sweeps


# Bandwidth-sweep size per (device, quick): far beyond the caches; on the GPU ~1 GiB per array.
COPY_N = {("cpu", False): 1 << 25, ("cpu", True): 1 << 22,
          ("cuda", False): 1 << 28, ("cuda", True): 1 << 24}


class CopySweeps(Sweeps):
    measures = "copy"            # the bandwidth yardstick (the roofline)

    def points(self, kind: str, device: str, quick: bool) -> list[Point]:
        if kind != "bandwidth" or (device, quick) not in COPY_N:
            return []
        return [Point({"n": COPY_N[device, quick]}, check_sample=CHECK_SAMPLE, save_outputs=False)]


SWEEPS = CopySweeps()
