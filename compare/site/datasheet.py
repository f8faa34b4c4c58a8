"""The datasheet peak memory bandwidth of a GPU, by the name its driver reports (the name each
record's ``hardware.gpu`` and each run's ``gpus`` carry), so the bandwidth page can give an
achieved bandwidth as a fraction of what the vendor states as well as of the same-run copy.

Sources, decimal units (1 TB/s = 10^12 bytes/s), as NVIDIA states them:
- NVIDIA H100 Tensor Core GPU datasheet and https://www.nvidia.com/en-us/data-center/h100/
  ("Technical Specifications", GPU memory bandwidth): H100 SXM 3.35 TB/s, H100 NVL 3.9 TB/s,
  H100 PCIe 2 TB/s.
- NVIDIA H200 Tensor Core GPU datasheet and https://www.nvidia.com/en-us/data-center/h200/:
  H200 SXM and H200 NVL 4.8 TB/s.
A CPU has no entry: its bandwidth depends on the memory fitted, the channels populated and the
socket, none of which a model name fixes, so the page says so and keeps the copy yardstick.
"""
from __future__ import annotations

from typing import Iterable, Mapping

from compare.results.environment import RunEnvironment
from compare.results.record import Record
from compare.site.data import num

PEAK_BYTES_PER_S: dict[str, float] = {
    "NVIDIA H100 80GB HBM3": 3.35e12,       # H100 SXM5
    "NVIDIA H100 NVL": 3.9e12,
    "NVIDIA H100 PCIe": 2.0e12,
    "NVIDIA H200": 4.8e12,                  # H200 SXM
    "NVIDIA H200 NVL": 4.8e12,
}


def gpu_of(rec: Record, runs: Iterable[RunEnvironment] = ()) -> str | None:
    """The GPU a CUDA record ran on: its own yardstick's ``gpu``, else its run's first GPU."""
    if rec.device != "cuda":
        return None
    hw = rec.hardware if isinstance(rec.hardware, Mapping) else {}
    if hw.get("gpu"):
        return str(hw["gpu"])
    for env in runs:
        for g in env.get("gpus") or () if isinstance(env, Mapping) else ():
            if isinstance(g, Mapping) and g.get("name"):
                return str(g["name"])
    return None


def peak(gpu: str | None) -> float | None:
    """The datasheet bandwidth of a GPU named exactly as in the table; None otherwise (never a
    neighbour's figure: a PCIe card is not an SXM one)."""
    return PEAK_BYTES_PER_S.get(gpu.strip()) if gpu else None


def fraction(rec: Record, runs: Iterable[RunEnvironment] = ()) -> float | None:
    """The record's achieved bandwidth (``throughput.bytes_per_s``) over its GPU's datasheet peak."""
    bw, top = num(rec.throughput.bytes_per_s if rec.throughput else None), peak(gpu_of(rec, runs))
    return bw / top if bw is not None and top else None


def words(device: str, gpu: str | None, copy_bytes_per_s: float | None) -> str:
    """The page's sentence: the device's datasheet peak and the same-run copy against it, or why
    there is no datasheet figure."""
    if device != "cuda":
        return ("No datasheet bandwidth on a CPU: a CPU's depends on the memory fitted and the "
                "channels populated, which its model name does not fix; fractions here are of the "
                "same-run copy only.")
    top = peak(gpu)
    if top is None:
        return (f"No datasheet bandwidth known for {gpu or 'this GPU (no name in the records)'}: "
                "add it to compare/site/datasheet.py with its source; fractions here are of the "
                "same-run copy only.")
    copy = (f" The same-run copy reached {copy_bytes_per_s / 1e12:.3g} TB/s, "
            f"{100 * copy_bytes_per_s / top:.0f} % of it." if copy_bytes_per_s else "")
    return (f"Datasheet peak memory bandwidth of the {gpu} (named in the records): {top / 1e12:g} TB/s "
            f"(NVIDIA's datasheet; compare/site/datasheet.py cites it); the table gives each cell's "
            f"achieved bandwidth as a fraction of it too.{copy}")
