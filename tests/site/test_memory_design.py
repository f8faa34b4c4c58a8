"""compare/site/memory_design.py: the gradients page's memory cells beside their ports' predicted
bytes (fast tier): which NVML figure each shows, the design's sum, and "—" where a port predicts none."""
from __future__ import annotations

from compare.results.record import Record
from compare.site import memory_design
from compare.site.render import Table
from compare.site.topics import projectile

MiB = 1 << 20


def rec(backend: str, memory: dict | None, info: dict | None = None, method: str = "ad") -> Record:
    return Record(scenario="projectile", backend=backend, device="cuda", precision="float32", status="ok",
                  memory=memory, info=info, gradient={"method": method})


def test_measured_beside_predicted_and_which_figure_it_is():
    sampled = rec("drjit", {"device_bytes": 300 * MiB, "device_bytes_sampled": 300 * MiB,
                            "device_bytes_milestones": 200 * MiB, "device_peak_bytes": 290 * MiB},
                  {"design_bytes": {"inputs": 16 * MiB, "loss_history": 84 * MiB, "flag": True}})
    old = rec("taichi", {"device_bytes": 21 << 30})                       # before the sampling thread
    hand = rec("warp", {"device_bytes": 50 * MiB, "device_bytes_sampled": 40 * MiB,
                        "device_bytes_milestones": 50 * MiB}, method="adjoint")
    unmeasured = rec("jax", None, {"design_bytes": {"inputs": 1}})
    blocks = memory_design.table([old, hand, unmeasured, sampled], projectile.hand_adjoint)
    [t] = [b for b in blocks if isinstance(b, Table)]
    rows = {r[0]: r for r in t.rows}
    assert [r[0] for r in t.rows] == ["drjit", "taichi", "warp ✎"]          # AD by memory, adjoints last
    assert rows["drjit"][2:7] == ("300 MiB", "sampled peak (milestones: 200 MiB)", "290 MiB", "100 MiB", "3.00×")
    assert rows["drjit"][7] == "inputs 16 MiB, loss_history 84 MiB"        # a flag is no byte count
    assert rows["taichi"][3] == "milestones only (no sampling thread)" and rows["taichi"][4:] == ("—",) * 4
    assert rows["warp ✎"][3] == "a milestone (above every sample)"


def test_no_device_figure_no_table():
    assert memory_design.table([rec("numpy", {"host_bytes": 5})], projectile.hand_adjoint) == []


def test_the_memory_row_says_what_its_figure_is():
    text = projectile.RULES[1].text
    assert "NVML peak of the process" not in text and "sampled every 2 ms" in text and "milestone" in text


def test_a_port_that_gives_one_sum_is_predicted_as_its_total():
    one = rec("warp", {"device_bytes": 132 * MiB, "device_bytes_sampled": 132 * MiB,
                       "device_bytes_milestones": 132 * MiB}, {"design_bytes": 136 * MiB})
    assert memory_design.design_bytes(one) == {"total": float(136 * MiB)}
    assert memory_design.design_bytes(rec("warp", None, {"design_bytes": True})) is None
