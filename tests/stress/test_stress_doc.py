"""docs/stress.md's claims about the H100 results against the H100 store (issue 58: the page said
"all seven CUDA backends" beside ten, and "two runs differ in 96 values" where the store has 0)."""
from __future__ import annotations

import json
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DOC = " ".join((ROOT / "docs" / "stress.md").read_text(encoding="utf-8").split())
ROWS = json.loads((ROOT / "docs" / "results" / "h100" / "stress.json").read_text())["analysis"]["rows"]
WORDS = {w: i for i, w in enumerate("zero one two three four five six seven eight nine ten eleven twelve".split())}


def h100_part() -> str:
    return DOC[DOC.index("## Results: GPU (NVIDIA H100)"):]


def test_the_number_of_cuda_backends_is_the_stores():
    ran = {r["backend"] for r in ROWS if r["device"] == "cuda" and r["verdict"] != "skipped"}
    said = re.findall(r"all (\w+) CUDA backends", h100_part())
    assert said and all(WORDS[w] == len(ran) for w in said), (said, sorted(ran))


def test_the_racy_control_is_described_as_the_store_has_it():
    control = [r for r in ROWS if r["device"] == "cuda" and "control: " in r.get("detail", "")]
    assert len(control) == 1
    row = control[0]
    part = h100_part()
    sentence = part[part.index("The racy control"):]
    sentence = sentence[:sentence.index("exposes it.")]
    differ = re.search(r"\((\d+) values differ\)", sentence)
    assert differ and int(differ.group(1)) == row["value"]
    if row["value"] == 0:
        assert "agree bitwise" in sentence
    err, bound = re.search(r"error vs oracle (\S+) and \S+ \(bound (\S+)\)", row["detail"]).groups()
    said = re.search(r"error is (\S+) against a bound of (\S+) ", sentence)
    assert said and (float(said.group(1)), float(said.group(2))) == (float(err), float(bound))
