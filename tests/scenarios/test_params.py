"""Parameter validation: every scenario accepts its defaults and rejects bad values with one line."""
from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import scenarios
from scenarios.base import ParamError

pytestmark = pytest.mark.cli


@pytest.mark.parametrize("name", list(scenarios.SCENARIOS))
def test_defaults_and_quick_validate(name):
    sc = scenarios.get(name)
    sc.params()
    sc.params(quick=True)


@settings(max_examples=200, deadline=None)
@given(n=st.integers(min_value=-10**12, max_value=10**12))
def test_saxpy_n_range(n):
    sc = scenarios.get("saxpy")
    if 1 <= n <= 2**31 - 1:
        assert sc.params({"n": str(n)}).n == n
    else:
        with pytest.raises(ParamError, match=r"^n must be in"):
            sc.params({"n": str(n)})


@settings(max_examples=200, deadline=None)
@given(dt=st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=6)))
def test_dt_is_finite_positive_or_rejected(dt):
    for name in ("particles", "projectile"):
        sc = scenarios.get(name)
        try:
            p = sc.params({"dt": dt if isinstance(dt, str) else repr(dt)})
        except ParamError as exc:
            msg = str(exc)
            assert "\n" not in msg and "dt" in msg
        else:
            assert math.isfinite(p.dt) and 0 < p.dt <= 1


@settings(max_examples=100, deadline=None)
@given(key=st.text(min_size=1, max_size=12), value=st.text(max_size=8))
def test_unknown_keys_and_garbage_values_give_one_line(key, value):
    for sc in scenarios.SCENARIOS.values():
        try:
            sc.params({key: value})
        except ParamError as exc:
            assert "\n" not in str(exc)


@pytest.mark.parametrize("name,key,bad", [
    ("sdf", "width", "1"), ("sdf", "height", "0"), ("particles", "radius", "0.5"),
    ("particles", "record_every", "-1"), ("particles", "bounce", "nan"),
    ("projectile", "iters", "-1"), ("projectile", "lr", "-0.1"), ("projectile", "contact", "x"),
    ("saxpy", "inputs", "zeros"), ("saxpy", "a", "inf"),
])
def test_specific_rejections(name, key, bad):
    with pytest.raises(ParamError, match=key):
        scenarios.get(name).params({key: bad})
