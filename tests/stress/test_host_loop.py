"""compare/stress/host_loop.py: a typed task crosses to a worker process as JSON and comes back
as its outcome; a failure there is an outcome with its error, never a lost run."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from conftest import require_device
from compare.stress import host_loop, projectile_tasks as T
from compare.stress.numerics import ORACLE

SCAN = T.Task("scan", ORACLE, "host", "float64", ("hard",), 600.0, scans={"s": [6.45, 6.5]})


def test_a_task_in_a_worker_gives_what_it_gives_in_this_process():
    """The process boundary changes nothing: the same scans, non-finite floats included."""
    got = host_loop.run(SCAN, timeout=300)
    here = T.execute(SCAN)
    assert got.why_not is None and got.descents == ()
    assert [(s.contact, s.scan, s.vy) for s in got.scans] == [(s.contact, s.scan, s.vy) for s in here.scans]
    for g, h in zip(got.scans, here.scans):
        np.testing.assert_array_equal(g.loss, h.loss)
        np.testing.assert_array_equal(g.grad, h.grad)


def test_an_exception_in_the_worker_is_the_outcome_error():
    bad = T.Task("optimise", ORACLE, "host", "float64", ("none",), 600.0, lrs=(0.01,), methods=("bogus",), iters=1)
    got = host_loop.run(bad, timeout=300)
    assert got.error == "ValueError: unknown optimiser 'bogus'" and got.why_not == got.error
    assert got.skipped is None and got.descents == ()


def test_a_task_that_outlives_its_timeout_is_an_error():
    got = host_loop.run(SCAN, timeout=0.01)
    assert got.error == "task timed out after 0.01 s"


def test_call_names_its_function_as_module_colon_function():
    with pytest.raises(ValueError, match="'module:function'"):
        host_loop.call({"kind": "scan"})
    assert host_loop.call(dataclasses.replace(SCAN, scans={"s": [6.5]}).to_json())["results"][0]["vy"] == [6.5]


def test_non_finite_floats_cross_as_strings_and_come_back_as_floats():
    sent = host_loop._jsonable({"h": [1.0, math.inf, np.float32(math.nan)], "n": np.int64(3)})
    assert sent == {"h": [1.0, "inf", "nan"], "n": 3}
    back = host_loop._unstr(sent["h"])
    assert back[:2] == [1.0, math.inf] and math.isnan(back[2])


@pytest.mark.parametrize("backend", [pytest.param(b, marks=getattr(pytest.mark, b))
                                     for b in ("warp", "taichi", "jax", "numba")])
def test_host_loop_scan_reuses_one_kernel_and_matches_the_oracle(backend):
    """A scan moves v0 in place (set_input); in float64 every point must match the float64 adjoint,
    so a stale v0 (the kernel not seeing the new input) fails here."""
    require_device(backend, "cpu")
    scans = {"s": [6.3, 6.45, 6.5, 6.7]}
    task = T.Task("scan", backend, "cpu", "float64", ("hard", "soft"), 600.0, scans=scans)
    got = host_loop.run(task, timeout=600)
    assert got.why_not is None and got.scans, got
    ref = T.execute(dataclasses.replace(task, backend="oracle64", device="host"))
    for g, r in zip(got.scans, ref.scans):
        assert g.contact == r.contact
        assert len(set(g.loss)) == len(scans["s"])            # every point really evaluated
        np.testing.assert_allclose(g.loss, r.loss, rtol=1e-10)
        np.testing.assert_allclose(g.grad, r.grad, rtol=1e-8, atol=1e-8)
