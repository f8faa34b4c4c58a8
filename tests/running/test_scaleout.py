"""GPU-aware scale-out (compare/running/scaleout.py): one worker per GPU, each pinned to its GPU and a
disjoint core set; CUDA cells ask for a GPU; without GPU resources, one cell at a time."""
from __future__ import annotations

import os

import pytest

from compare.running import scaleout
from compare.spec import Cell

pytestmark = pytest.mark.cli


def test_core_sets_are_disjoint_and_cover_the_cores():
    sets = scaleout.core_sets(2, list(range(16)))
    assert sets == [list(range(8)), list(range(8, 16))]
    sets = scaleout.core_sets(3, list(range(8)))
    assert [len(s) for s in sets] == [3, 3, 2] and sorted(sum(sets, [])) == list(range(8))
    assert scaleout.core_sets(4, [0, 1]) == [[0], [1]]      # never an empty set


def test_apply_cpu_set(monkeypatch):
    before = os.sched_getaffinity(0)
    first = min(before)
    monkeypatch.setenv(scaleout.CPU_SET_ENV, str(first))
    try:
        scaleout.apply_cpu_set()
        assert os.sched_getaffinity(0) == {first}
    finally:
        os.sched_setaffinity(0, before)


class FakeClient:
    """Records submissions; a GPU-declaring cluster or not."""

    def __init__(self, gpu: bool) -> None:
        self.gpu, self.submitted = gpu, []

    def scheduler_info(self):
        res = {"GPU": 1} if self.gpu else {}
        return {"workers": {"a": {"name": "gpu0", "resources": res}, "b": {"name": "gpu1", "resources": res}}}

    def submit(self, fn, spec, timeout, pure=False, resources=None):
        self.submitted.append((spec["device"], resources))

        class Done:
            def result(self_inner):
                return {"status": "ok"}, None
        return Done()


def _spec(device):
    return Cell.make("saxpy", "numpy", device, "float32", quick=True)


def test_cuda_cells_ask_for_a_gpu_and_cpu_cells_do_not():
    c = FakeClient(gpu=True)
    probes = {"numpy": {"available": {"cpu": None, "cuda": None}}}
    specs = [_spec("cuda"), _spec("cpu"), _spec("cuda")]
    scaleout.runner(c, 60, specs, probes)
    assert c.submitted == [("cuda", {"GPU": 1}), ("cpu", None), ("cuda", {"GPU": 1})]
    assert scaleout.placement(c)["gpu_workers"] == 2


def test_without_gpu_resources_cells_go_one_at_a_time():
    c = FakeClient(gpu=False)
    run = scaleout.runner(c, 60, [_spec("cpu"), _spec("cpu")], {"numpy": {"available": {"cpu": None}}})
    assert c.submitted == []               # nothing submitted ahead: each waits for the previous
    run(_spec("cpu"))
    assert c.submitted == [("cpu", None)]
    assert scaleout.placement(c)["mode"].startswith("one cell at a time")


@pytest.mark.slow
def test_local_cluster_pins_one_worker_per_gpu(monkeypatch):
    """With two GPUs (as NVML would say), two single-threaded workers, each seeing only its GPU
    and owning its own cores."""
    pytest.importorskip("distributed")
    from distributed import Client
    monkeypatch.setattr(scaleout, "visible_gpus", lambda: 2)
    monkeypatch.delenv("CUDA_VISIBLE_DEVICES", raising=False)
    with Client(scaleout.local_cluster()) as c:
        env = c.run(lambda: (os.environ.get("CUDA_VISIBLE_DEVICES"), os.environ.get(scaleout.CPU_SET_ENV)))
        info = c.scheduler_info()["workers"]
        assert sorted(v[0] for v in env.values()) == ["0", "1"]
        sets = [set(v[1].split(",")) for v in env.values()]
        assert not (sets[0] & sets[1]) if len(os.sched_getaffinity(0)) > 1 else True
        assert all(w["nthreads"] == 1 and w["resources"] == {"GPU": 1} for w in info.values())
        assert scaleout.placement(c)["gpu_workers"] == 2
