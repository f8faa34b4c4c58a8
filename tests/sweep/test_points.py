"""What each scenario sweeps (compare/sweep/points/__init__.py, the registry): typed points that
resolve to the scenario's parameters and cover the ranges the modules document. Each scenario's
own module is tested in tests/sweep/points/ (test_copy, test_launch, test_points_<scenario>)."""
from __future__ import annotations

import dataclasses
import math

import pytest

import scenarios
from compare.sweep.converged import REF_FACTOR, Reference
from compare.sweep.points import NONE, SWEEPS, Knob, Point, sweeps
from compare.sweep.points import particles, projectile, saxpy, sdf

KINDS = ("bandwidth", "error", "scaling", "horizon")
WHERE = [(d, q) for d in ("cpu", "cuda") for q in (False, True)]


def all_points():
    for name, sw in SWEEPS.items():
        for kind in KINDS:
            for device, quick in WHERE:
                for pt in sw.points(kind, device, quick):
                    yield name, kind, device, quick, pt


def test_registry_holds_one_sweeps_per_module_and_none_elsewhere():
    assert set(SWEEPS) == {"launch", "copy", "saxpy", "sdf", "particles", "projectile"}
    assert all(sw.scenario == name for name, sw in SWEEPS.items())
    assert sweeps("no-such-scenario") is NONE and NONE.points("error", "cpu", False) == []


def test_every_point_is_typed_and_resolves_to_its_scenario_params():
    seen = 0
    for name, kind, device, quick, pt in all_points():
        seen += 1
        assert isinstance(pt, Point) and (pt.knob is None or isinstance(pt.knob, Knob))
        sc = scenarios.get(name)
        p = sc.params(dict(pt.params))                 # valid: the scenario accepts every value
        for k, v in pt.params.items():
            assert getattr(p, k) == v, (name, kind, k)
        if pt.knob is not None and pt.knob.value is not None:     # the knob is what it sets
            assert pt.params.get(pt.knob.name, pt.knob.value) == pt.knob.value, (name, kind, pt)
            assert pt.knob.value in pt.params.values(), (name, kind, pt)
        assert (pt.reference is not None) <= (kind == "error")    # only error points have one
        assert pt.check_sample >= 0
    assert seen > 50


def test_points_are_frozen_and_their_knob_is_stored_as_name_and_value():
    pt = Point({"n": 4}, Knob("n", 4))
    with pytest.raises(dataclasses.FrozenInstanceError):
        pt.knob = None          # type: ignore[misc]
    assert pt.knob is not None and pt.knob.to_json() == {"name": "n", "value": 4}
    assert Knob("precision").to_json() == {"name": "precision", "value": None}
    assert (pt.check_sample, pt.save_outputs) == (0, True)       # the cell spec's defaults


@pytest.mark.parametrize("device,quick", WHERE)
def test_bandwidth_sizes_are_powers_of_two_with_the_yardsticks(device, quick):
    pts = SWEEPS["saxpy"].points("bandwidth", device, quick)
    assert [pt.params["n"] for pt in pts] == [1 << e for e in saxpy.SAXPY_EXP[device, quick]]
    assert all(pt.knob == Knob("n", pt.params["n"]) and not pt.save_outputs and pt.check_sample for pt in pts)
    assert [pt.params for pt in SWEEPS["launch"].points("bandwidth", device, quick)] == [{"n": 1}]
    (copy,) = SWEEPS["copy"].points("bandwidth", device, quick)
    assert copy.params["n"] >= pts[-1].params["n"] // 4 and copy.knob is None   # far beyond the caches
    assert SWEEPS["saxpy"].points("scaling", device, quick) == []


@pytest.mark.parametrize("module,name", [(particles, "particles"), (projectile, "projectile")])
@pytest.mark.parametrize("quick", [False, True])
def test_dt_points_reach_the_same_simulated_time_and_a_finer_reference(module, name, quick):
    dts = module.PARTICLES_DT if name == "particles" else module.PROJECTILE_DT
    t = module.PARTICLES_T if name == "particles" else module.PROJECTILE_T
    pts = SWEEPS[name].points("error", "cpu", quick)
    assert [pt.knob for pt in pts] == [Knob("dt", dt) for dt in dts[quick]]
    assert all(a / b == 2 for a, b in zip(dts[quick], dts[quick][1:]))         # dt halves down the list
    for pt in pts:
        assert math.isclose(pt.params["steps"] * pt.params["dt"], t)           # every dt divides t
        assert pt.reference == Reference(dt=min(dts[quick]) / REF_FACTOR)
    assert SWEEPS[name].points("error", "cuda", quick) == pts                  # the same on every device


def test_particles_scale_over_n_with_sampled_checks_and_sdf_over_resolution():
    for (device, quick), ns in particles.PARTICLES_N.items():
        pts = SWEEPS["particles"].points("scaling", device, quick)
        assert [pt.params["n"] for pt in pts] == list(ns) and list(ns) == sorted(ns)
        assert all(pt.params["record_every"] == 0 and pt.check_sample == particles.SCALING_CHECKED for pt in pts)
    for (device, quick), res in sdf.SDF_RES.items():
        pts = SWEEPS["sdf"].points("error", device, quick)
        assert [(pt.params["width"], pt.params["height"]) for pt in pts] == [(r, r) for r in res]
        assert [pt.knob for pt in pts] == [Knob("resolution", r) for r in res]


