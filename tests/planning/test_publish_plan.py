"""compare/planning/publish_plan.py: the parts a publish runs, planned without starting a process
(fast tier; the CUDA plan's test moved here from tests/suites/test_publish.py)."""
from __future__ import annotations

import json

import pytest

from compare.options import UsageError
from compare.planning import publish_plan
from conftest import ROOT

H100 = {"cpu": 120 * 2**30, "cuda": 79 * 2**30}


def names(parts):
    return [p.name for p in parts]


def test_cuda_plan_measures_what_the_h100_store_holds():
    parts, notes = publish_plan.plan("results/h100", ["cuda"], "all", have=H100)
    assert not notes
    order = names(parts)
    assert order[:9] == ["all", "float64", "large-cuda-saxpy26", "large-cuda-saxpy28", "large-cuda-particles24",
                         "bandwidth", "scaling", "error", "horizon"]
    by = {p.name: p.argv for p in parts}
    assert "--variants" in by["all"] and by["all"][by["all"].index("--variants") + 1] == "all"
    assert all("--resume" in by[n] for n in order[:9])
    # the matrix part is float32 in repeated processes; float64 (no row ranks it) once, apart
    assert by["all"][by["all"].index("--precision") + 1] == "float32" and "--processes" in by["all"]
    assert by["float64"][by["float64"].index("--precision") + 1] == "float64" and "--processes" not in by["float64"]
    for n in ("all", *order[2:5]):      # what the rows read: repeated, and one sitting each
        argv = by[n]
        assert argv[argv.index("--processes") + 1] == "auto" and argv[argv.index("--overlap") + 1] == "auto"
        assert float(argv[argv.index("--sitting") + 1]) == publish_plan.SITTING_S == 1500
    for n in ("float64", *order[5:9]):  # every other part that runs cells: set-ups overlapped, one process
        argv = by[n]
        assert argv[argv.index("--overlap") + 1] == "auto" and "--processes" not in argv and "--sitting" not in argv
    store = json.loads((ROOT / "docs/results/h100/results.json").read_text())
    held = {(r["scenario"], r["params"].get("n"), r["variant"]) for r in store["records"]}
    for n in order[2:5]:
        argv = by[n]
        size = int(argv[argv.index("--set") + 1].split("=")[1])
        for v in argv[argv.index("--variants") + 1].split(","):
            assert (argv[1], size, v) in held, (n, v)
    assert "--check-sample" in by["large-cuda-particles24"]
    stress = [p for p in parts if p.name.startswith("stress-") and p.name != "stress-merge"]
    assert stress and all("--quick" not in p.argv for p in stress)      # full where CUDA is
    assert by["stress-ulps"][by["stress-ulps"].index("--devices") + 1] == "cpu,cuda"
    small, notes = publish_plan.plan("r", ["cuda"], "all", have={"cpu": 16 * 2**30, "cuda": 8 * 2**30})
    assert "large-cuda-saxpy28" not in names(small) and "large-cuda-saxpy28: left out" in notes[0]
    cpu, _ = publish_plan.plan("r", ["cpu"], "all", have={"cpu": 20 * 2**30})
    assert [n for n in names(cpu) if n.startswith("large-")] == \
        ["large-cpu-saxpy24", "large-cpu-saxpy26", "large-cpu-particles20"]
    assert all("--quick" in p.argv for p in cpu if p.name.startswith("stress-") and p.name != "stress-merge")


def test_a_quick_cpu_plan_stages_each_experiment_and_ends_with_the_merge_and_the_site():
    parts, notes = publish_plan.plan("out", ["cpu"], "numpy", quick=True, timeout=30, have={"cpu": 64 * 2**30})
    assert not notes
    order = names(parts)
    assert order[:2] == ["all", "float64"] and order[-2:] == ["stress-merge", "site"]
    by = {p.name: p for p in parts}
    assert "--quick" in by["all"].argv and "--processes" not in by["all"].argv       # quick: one process
    assert not [n for n, part in by.items() if "--overlap" in part.argv]          # ... and the host's default
    assert by["all"].argv[-2:] == ("--timeout", "30") and all(p.resumes for p in parts[:2])
    stress = [p for p in parts if p.name.startswith("stress-") and p.name != "stress-merge"]
    for p in stress:
        exp = p.name[len("stress-"):]
        assert not p.resumes and p.argv[p.argv.index("--out") + 1] == f"out/{publish_plan.STAGED}/{exp}-numpy"
    assert by["stress-merge"].reads == tuple(p.name for p in stress)
    assert set(by["site"].reads) == set(order[:-1]) and by["site"].argv == ("site", "out", "--out", "out/report")


def test_sizes_that_do_not_fit_are_left_out_with_a_line_each():
    parts, notes = publish_plan.plan("o", ["cpu"], "numpy", quick=True, have={"cpu": 1.0})
    assert not [n for n in names(parts) if n.startswith("large-")]
    assert notes and all(": left out, needs " in n and "of host memory" in n for n in notes)


def test_an_unknown_backend_is_refused():
    with pytest.raises(UsageError):
        publish_plan.plan("o", ["cpu"], "fortran", have=H100)
