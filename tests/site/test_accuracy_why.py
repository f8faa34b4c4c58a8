"""compare/site/accuracy_why.py: the accuracy page says why the error shares differ, from the
records: SAXPY's error in units of u shows one rounding of a*x + y (a fused multiply-add) or two,
and the stored machines show it (fast tier)."""
from __future__ import annotations

from pathlib import Path

import pytest

from compare.results.record import Record
from compare.site import accuracy_why, data, matrix

ROOT = Path(__file__).resolve().parents[2]
U = 2.0 ** -24
TOL = 2 * U * (1 + U) + 2 * 2.0 ** -53 * (1 + 2.0 ** -53)


def rec(backend: str, scenario: str, err: float, tol: float, **extra: float) -> Record:
    return Record(scenario=scenario, backend=backend, device="cpu", precision="float32", status="ok",
                  params=dict(data.defaults(scenario)),
                  error={"vs_oracle": err, "tolerance": tol, "metric": "m", **extra})


def saxpy(backend: str, ulps: float) -> Record:
    return rec(backend, "saxpy", ulps * U, TOL, ulps=ulps)


def test_one_rounding_and_two_are_told_apart_and_their_weight_on_the_geometric_mean_stated():
    recs = [saxpy("a", 1.0), saxpy("b", 1.5), saxpy("c", 1.5),
            rec("a", "sdf", 1e-6, 1e-5), rec("b", "sdf", 1.2e-6, 1e-5), rec("c", "sdf", 1e-6, 1e-5)]
    assert accuracy_why.roundings(recs) == {"a": 1.0, "b": 1.5, "c": 1.5}
    text = accuracy_why.paragraph(recs)
    assert "Here the errors of a fit one rounding (at most 1 u); those of b, c show two (up to 1.5 u)" in text
    assert f"over the {len(matrix.IN_ALL)} scenarios {1.5 ** (1 / len(matrix.IN_ALL)):.3g}× above" in text
    # sdf sets b 20 % apart: more than SAXPY's 1.5 ** (1 / 4) = 1.107, so SAXPY does not set the order
    assert "within 20.0 % of each other." in text and "sets the row's order" not in text


def test_saxpy_sets_the_order_only_where_the_rest_is_closer_than_its_factor():
    recs = [saxpy("a", 1.0), saxpy("b", 1.5), rec("a", "sdf", 1e-6, 1e-5), rec("b", "sdf", 1.01e-6, 1e-5)]
    assert accuracy_why.paragraph(recs).endswith("within 1.0 % of each other, so SAXPY's rounding sets the row's order.")


def test_one_way_of_rounding_everywhere_sets_nothing_apart_and_no_saxpy_says_nothing():
    assert "every framework rounded twice" in accuracy_why.paragraph([saxpy("a", 1.5), saxpy("b", 1.2)])
    assert "every framework rounded once" in accuracy_why.paragraph([saxpy("a", 1.0), saxpy("b", 0.7)])
    assert accuracy_why.paragraph([rec("a", "sdf", 1e-6, 1e-5)]) == ""
    failed = Record(scenario="saxpy", backend="a", device="cpu", precision="float32", status="mismatch",
                    params=dict(data.defaults("saxpy")), error={"vs_oracle": 1.0, "tolerance": TOL, "ulps": 9e6})
    assert accuracy_why.roundings([failed]) == {}


@pytest.mark.parametrize("store, once, twice", [
    ("cpu", {"jax"}, {"numba", "numpy", "taichi", "torch", "warp"}),
    ("h100", {"cupy", "numba", "taichi", "torch", "triton", "warp"}, {"jax", "quadrants"})])
def test_the_stored_machines_jax_fuses_on_the_cpu_and_not_on_the_h100(store, once, twice):
    """The CPU row names JAX best and the H100 puts it at 1.16×: XLA's CPU code rounds a*x + y
    once, its CUDA code twice, as the records' ulps show."""
    from compare.suites import formats
    formats.register()
    m = data.load([ROOT / "docs" / "results" / store])
    recs = [r for r in matrix.all_defaults(m, m.primary_device) if r.scenario in matrix.IN_ALL]
    got = accuracy_why.roundings(recs)
    assert once <= {f for f, u in got.items() if u <= 1} and twice <= {f for f, u in got.items() if u > 1}
    assert "jax" in accuracy_why.paragraph(recs)
