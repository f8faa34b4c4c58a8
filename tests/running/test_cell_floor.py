"""compare/running/cell_floor.py: a CUDA cell's own launch floor, driven here by a fake driver (no GPU):
the figures it gives, its time bound, the context it launches on and leaves behind, and that a
failing probe is an error string, never the cell's."""
from __future__ import annotations

import ctypes
from typing import Any

import pytest

from compare.measuring.phases import CELL_PARTS, Laps
from compare.results.record_floor import CellFloor, FloorProbe
from compare.running import cell_floor, hardware

PRIMARY, FRAMEWORK = 0x1000, 0x2000


class Clock:
    """The probe's clock in these tests: the fake driver's calls advance it by their stated cost, so
    the figures are exact whatever else the host runs (a spinning fake read a busy host's time)."""
    now = 0.0


def spin(s: float) -> None:
    Clock.now += s


@pytest.fixture(autouse=True)
def fake_clock(monkeypatch: pytest.MonkeyPatch) -> None:
    fake = type("FakeTime", (), {"perf_counter": staticmethod(lambda: Clock.now)})
    monkeypatch.setattr(cell_floor, "time", fake)
    monkeypatch.setattr(hardware, "time", fake)         # its launch loops (hardware.launch_loops)


class FakeDriver:
    """The driver functions a probe calls, with ctypes' by-reference arguments: a launch costs
    ``launch_s`` of host time and a synchronise ``sync_s``; ``fail`` names a call that returns an error."""

    def __init__(self, launch_s: float = 20e-6, sync_s: float = 30e-6, active: bool = False,
                 current: int | None = None, fail: str = "") -> None:
        self.launch_s, self.sync_s, self.fail = launch_s, sync_s, fail
        self.refs, self.current, self.loaded = int(active), current, 0
        self.launched_on: set[int | None] = set()
        self.launches = 0

    def _r(self, name: str) -> int:
        return 999 if name == self.fail else 0

    def cuInit(self, flags: int) -> int:
        return self._r("cuInit")

    def cuDeviceGet(self, ref: Any, ordinal: int) -> int:
        ref._obj.value = ordinal
        return self._r("cuDeviceGet")

    def cuCtxGetCurrent(self, ref: Any) -> int:
        ref._obj.value = self.current
        return 0

    def cuDevicePrimaryCtxGetState(self, dev: Any, flags: Any, active: Any) -> int:
        flags._obj.value, active._obj.value = 0, int(self.refs > 0)
        return 0

    def cuDevicePrimaryCtxRetain(self, ref: Any, dev: Any) -> int:
        self.refs += 1
        ref._obj.value = PRIMARY
        return 0

    def cuDevicePrimaryCtxRelease_v2(self, dev: Any) -> int:
        self.refs -= 1
        return 0

    def cuCtxSetCurrent(self, ctx: ctypes.c_void_p) -> int:
        self.current = ctx.value
        return 0

    def cuModuleLoadData(self, ref: Any, image: bytes) -> int:
        assert b".entry noop" in image            # the yardstick's own empty kernel
        if self.fail == "cuModuleLoadData":
            return 999
        self.loaded += 1
        ref._obj.value = 0x3000
        return 0

    def cuModuleGetFunction(self, ref: Any, mod: Any, name: bytes) -> int:
        ref._obj.value = 0x4000
        return 0

    def cuModuleUnload(self, mod: Any) -> int:
        self.loaded -= 1
        return 0

    def cuLaunchKernel(self, fn: Any, *args: Any) -> int:
        spin(self.launch_s)
        self.launches += 1
        self.launched_on.add(self.current)
        return self._r("cuLaunchKernel")

    def cuCtxSynchronize(self) -> int:
        spin(self.sync_s)
        return 0


def test_the_probe_measures_latency_and_pipelined_launches_on_the_primary_context() -> None:
    fake = FakeDriver()
    p = cell_floor.probe(when="before the framework's set-up, on ", keep=True, driver=lambda: fake)
    assert isinstance(p, FloorProbe) and p.error is None and p.figures
    # one launch + its synchronise: 50 µs of the fake's time
    assert p.latency_s is not None and p.latency_s == pytest.approx(50e-6)
    assert p.launches == cell_floor.LATENCY and p.latency_iqr_s is not None and p.latency_iqr_s >= 0
    # pipelined: k launches and one synchronise over k, the launch's 20 µs and a share of one sync
    assert p.k is not None and 100 <= p.k <= cell_floor.K and p.batches == cell_floor.BATCHES
    assert p.pipelined_s is not None and p.pipelined_s == pytest.approx(20e-6 + 30e-6 / p.k)
    assert p.spent_s is not None and p.spent_s < 0.2
    assert p.context == ("before the framework's set-up, on the primary context, created by the probe, "
                         "kept for the framework")
    # launched on the primary context, the thread's context put back, the module unloaded, and the
    # primary context it created kept (retained once) for the framework to take up
    assert fake.launched_on == {PRIMARY} and fake.current is None and fake.loaded == 0 and fake.refs == 1
    assert list(p) == ["latency_s", "latency_iqr_s", "pipelined_s", "launches", "k", "batches", "spent_s",
                       "context"]


def test_a_slow_launch_gives_fewer_samples_within_the_time_bound() -> None:
    fake = FakeDriver(launch_s=1e-3, sync_s=1e-3)        # 2 ms a synchronised launch: 100x an H100's
    t0 = Clock.now
    p = cell_floor.probe(driver=lambda: fake)
    took = Clock.now - t0
    # the loops stop at the budget: past it by at most one synchronised launch or one batch
    assert took <= cell_floor.BUDGET_S + 2e-3 * (1 + (p.k or 0)) and p.spent_s is not None and p.spent_s <= took
    assert p.latency_s is not None and p.latency_s >= 2e-3 and p.launches is not None and p.launches < 30
    assert p.k is not None and p.k < 10 and p.pipelined_s is not None and p.pipelined_s >= 1e-3
    assert fake.refs == 0            # created for this probe alone (keep=False): released


def test_after_the_regimes_it_launches_on_the_frameworks_current_context() -> None:
    fake = FakeDriver(launch_s=1e-6, sync_s=1e-6, active=True, current=FRAMEWORK)
    p = cell_floor.probe(current=True, when="after the timed regimes, on ", driver=lambda: fake)
    assert p.figures and fake.launched_on == {FRAMEWORK} and fake.current == FRAMEWORK
    assert p.context == "after the timed regimes, on the thread's current context (the framework's): not the primary"
    assert fake.refs == 1            # the framework's hold on the primary context, no more, no less
    primary = FakeDriver(launch_s=1e-6, sync_s=1e-6, active=True, current=PRIMARY)
    assert cell_floor.probe(current=True, driver=lambda: primary).context.endswith(": the primary")
    idle = FakeDriver(launch_s=1e-6, sync_s=1e-6, active=True)        # no context current on the thread
    got = cell_floor.probe(current=True, driver=lambda: idle)
    assert got.context == "the primary context, already active" and idle.launched_on == {PRIMARY}
    assert idle.current is None and idle.refs == 1


@pytest.mark.parametrize("fail", ["cuInit", "cuModuleLoadData", "cuLaunchKernel"])
def test_a_failing_probe_is_an_error_string_and_leaves_the_thread_as_it_was(fail: str) -> None:
    fake = FakeDriver(launch_s=1e-6, sync_s=1e-6, active=True, current=FRAMEWORK, fail=fail)
    p = cell_floor.probe(driver=lambda: fake)
    assert p.error == f"OSError: {fail} failed (CUresult 999)" and not p.figures and p.latency_s is None
    assert fake.current == FRAMEWORK and fake.loaded == 0 and fake.refs == 1


def test_no_driver_library_is_an_error_string() -> None:
    def missing() -> Any:
        raise OSError("libcuda.so.1: cannot open shared object file")
    p = cell_floor.probe(driver=missing)
    assert p.error == "OSError: libcuda.so.1: cannot open shared object file" and p.spent_s is not None


def test_the_worker_probes_cuda_cells_at_its_points_and_nothing_else(monkeypatch: pytest.MonkeyPatch) -> None:
    seen: list[tuple[bool, str]] = []

    def fake_probe(current: bool = False, when: str = "", keep: bool = False, **_: Any) -> FloorProbe:
        seen.append((current, when))
        return FloorProbe.of(latency_s=1e-5, pipelined_s=5e-6, context=when)
    monkeypatch.setattr(cell_floor, "probe", fake_probe)
    cpu = cell_floor.Probes("cpu", Laps(), gated=False)
    cpu.gate_opened()
    cpu.after()
    assert cpu.fields() == {} and seen == []
    laps = Laps()
    alone = cell_floor.Probes("cuda", laps, gated=False)       # before the framework's set-up
    assert [w for _, w in seen] == ["before the framework's set-up, on "]
    alone.gate_opened()                                         # ungated: nothing more at the gate
    alone.after()
    assert seen[-1] == (True, "after the timed regimes, on ") and len(seen) == 2
    floor = alone.fields()["cell_floor"]
    assert isinstance(floor, CellFloor) and floor.before is not None and floor.after is not None
    assert floor.before.latency_s == 1e-5 and floor.how == cell_floor.HOW and list(floor) == ["before", "after", "how"]
    assert set(laps.spent) <= set(CELL_PARTS) and "floor" in laps.spent
    seen.clear()
    gated = cell_floor.Probes("cuda", Laps(), gated=True)       # overlapped: no kernel beside another window
    assert seen == []
    gated.gate_opened()
    assert seen == [(False, "at its window's opening, the framework set up, on ")]


def test_the_yardstick_measures_its_floor_by_counts_in_the_same_loops() -> None:
    """hardware.measure_cuda's launch figures come from the same loops, unbounded: 100 warm-up
    launches, 2000 timed, 6 batches of 2000 (the first left out of the median)."""
    fake = FakeDriver()
    floor = hardware.launch_loops(fake, lambda: fake.cuLaunchKernel(None), None, warmup=100, latency=2000,
                                  k=2000, batches=6)
    assert floor["launches"] == 2000 and floor["k"] == 2000 and floor["batches"] == 6
    assert floor["latency_s"] == pytest.approx(50e-6) and floor["latency_iqr_s"] == pytest.approx(0.0, abs=1e-12)
    assert floor["pipelined_s"] == pytest.approx(20e-6 + 30e-6 / 2000)
    assert fake.launches == 100 + 2000 + 6 * 2000
