"""Achieved bandwidth as a fraction of the device's datasheet peak (fast tier): the GPU is named
by its record (else its run), looked up by its exact driver name (compare/site/datasheet.py);
a CPU, or a GPU the table lacks, gets no fraction and the page says why."""
from __future__ import annotations

import pytest

from compare.results.record import Record
from compare.site import datasheet


def saxpy(device: str = "cuda", gpu: str | None = "NVIDIA H100 80GB HBM3", bw: float = 3.015e12) -> Record:
    return Record(scenario="saxpy", backend="cupy", device=device, precision="float32", status="ok",
                  hardware={"gpu": gpu} if gpu else {}, throughput={"bytes_per_s": bw})


def test_the_datasheet_peaks_of_the_named_gpus():
    assert datasheet.peak("NVIDIA H100 80GB HBM3") == 3.35e12
    assert datasheet.peak("NVIDIA H200") == 4.8e12
    assert datasheet.peak("NVIDIA H100 PCIe") == 2.0e12      # a PCIe card is not the SXM part
    assert datasheet.peak("NVIDIA A40") is None and datasheet.peak(None) is None


def test_a_records_fraction_of_its_gpus_peak():
    assert datasheet.fraction(saxpy()) == pytest.approx(0.9)
    assert datasheet.fraction(saxpy(gpu="NVIDIA H200", bw=2.4e12)) == pytest.approx(0.5)
    assert datasheet.fraction(saxpy(gpu="NVIDIA A40")) is None
    assert datasheet.fraction(saxpy(device="cpu", gpu=None)) is None


def test_the_gpu_comes_from_the_run_where_the_record_names_none():
    runs = [{"gpus": [{"name": "NVIDIA H200", "memory": "143771 MiB"}]}]
    assert datasheet.gpu_of(saxpy(gpu=None), runs) == "NVIDIA H200"
    assert datasheet.fraction(saxpy(gpu=None, bw=4.8e12), runs) == pytest.approx(1.0)
    assert datasheet.gpu_of(saxpy(device="cpu", gpu=None), runs) is None


def test_the_page_names_the_peak_or_says_why_there_is_none():
    text = datasheet.words("cuda", "NVIDIA H100 80GB HBM3", 2.99e12)
    assert "3.35 TB/s" in text and "2.99 TB/s, 89 % of it" in text
    assert datasheet.words("cpu", None, 1e10).startswith("No datasheet bandwidth on a CPU")
    assert "No datasheet bandwidth known for NVIDIA A40" in datasheet.words("cuda", "NVIDIA A40", None)
