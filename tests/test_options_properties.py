"""Property-based bad input (docs/reliability.md), derandomized with hypothesis: seconds, repeat
counts, float parameters not representable in float32, duplicated names, extra words and junk
option values, each a one-line refusal that writes nothing (reliability_checks.assert_refused);
and any JSON document through Store.read, read or refused in one line naming the file."""
from __future__ import annotations

import contextlib
import json

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import adversarial
from compare import options
from compare.suites import run as run_suite
from compare.results.store import Store, StoreError
from reliability_checks import FIGURES, GOOD_RECORD, assert_refused, working_directory

pytestmark = pytest.mark.cli


@pytest.fixture()
def work(tmp_path, monkeypatch):
    return working_directory(tmp_path, monkeypatch)


# ---- property-based ------------------------------------------------------------------------------
# derandomized: the same examples every run, so the figures in docs/reliability.md reproduce
HYPO = settings(max_examples=40, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.function_scoped_fixture])
bad_seconds = st.one_of(st.sampled_from(["inf", "-inf", "nan", "-0.5", "0x", "", "1e999", "-1e-9"]),
                        st.floats(max_value=-1e-12).map(repr),
                        st.text(alphabet="abcxyz!?%", min_size=1, max_size=6))


@HYPO
@given(opt=st.sampled_from(["--timeout", "--min-time"]), value=bad_seconds)
def test_property_bad_seconds(work, opt, value):
    assert_refused(["saxpy", f"{opt}={value}", "--out", str(work / "out")], work)


@HYPO
@given(value=st.one_of(st.integers(max_value=0).map(str), st.floats(allow_nan=True).filter(
    lambda f: not (f == f and f.is_integer() and f >= 1)).map(repr), st.text(alphabet="ab.-e", min_size=1, max_size=5)))
def test_property_bad_repeat(work, value):
    assert_refused(["saxpy", f"--repeat={value}", "--out", str(work / "out")], work)


def _float_fields():
    import dataclasses
    out = []
    for sc in run_suite.scenarios.SCENARIOS.values():
        if not sc.in_all:
            continue
        for f in dataclasses.fields(sc.Params):
            if f.type in (float, "float"):
                out.append((sc.name, f.name))
    return out


@HYPO
@given(field=st.sampled_from(_float_fields()),
       value=st.one_of(st.floats(min_value=3.5e38, max_value=1.7e308), st.floats(min_value=-1.7e308, max_value=-3.5e38),
                       st.floats(min_value=1e-320, max_value=1e-46)))
def test_property_not_representable_in_float32(work, field, value):
    """Every float parameter of every scenario: a value float32 cannot hold is refused for a
    float32 run (by the scenario's range check or the precision check), never run."""
    scenario, name = field
    assert_refused([scenario, "--precision", "float32", "--set", f"{name}={value!r}", "--out", str(work / "out")], work)


@HYPO
@given(opt=st.sampled_from(["--backends", "--devices", "--precision"]), data=st.data())
def test_property_duplicated_names(work, opt, data):
    import backends
    allowed = {"--backends": list(backends.BACKENDS), "--devices": list(backends.DEVICES),
               "--precision": ["float32", "float64"]}[opt]
    items = data.draw(st.lists(st.sampled_from(allowed), min_size=1, max_size=3))
    items = data.draw(st.permutations(items + [items[0]]))
    assert_refused(["saxpy", opt, ",".join(items), "--out", str(work / "out")], work, "twice")


@HYPO
@given(word=st.text(alphabet="abcdefghijklmnopqrstuvwxyz0123456789_.", min_size=1, max_size=12),
       command=st.sampled_from(["saxpy", "all", "list", "stress"]))
def test_property_extra_words(work, word, command):
    assert_refused([command, word, "--out", str(work / "out")] if command != "list" else [command, word], work)


@HYPO
@given(opt=st.sampled_from(["--backends", "--devices", "--precision", "--variants", "--set", "--only", "--jobs",
                            "--scenarios"]),
       value=st.text(alphabet="!#%&*()0123456789=,:;.+-~ ", max_size=8))
def test_property_junk_option_values(work, opt, value):
    """Junk for any list, name or parameter option (never a valid name): refused in one line."""
    command = {"--only": ["stress"], "--jobs": ["stress"], "--scenarios": ["sweep", "error"]}.get(opt, ["saxpy"])
    if opt == "--jobs":
        with contextlib.suppress(Exception):
            options.positive_int(value)
            return                                       # a valid job count
    assert_refused([*command, f"{opt}={value}", "--out", str(work / "out")], work)


def _nested(children):
    return st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=8), children, max_size=4)


json_values = st.recursive(st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=5),
                           _nested, max_leaves=12)
record_like = st.fixed_dictionaries({}, optional={k: json_values for k in (
    "scenario", "backend", "device", "precision", "variant", "status", "reason", "params", "time", "error",
    "memory", "work", "throughput", "info", "gradient", "tags")}).map(
    lambda d: {**GOOD_RECORD, **d})


@settings(max_examples=150, deadline=None, derandomize=True, database=None)
@given(data=st.one_of(json_values, st.builds(lambda recs: {"format_version": 2, "suite": "run", "runs": [{}],
                                                           "records": recs}, st.lists(record_like, max_size=3))))
def test_property_store_read_validates_or_refuses(tmp_path_factory, data):
    """Any JSON: Store.read gives a store or a one-line StoreError naming the file, never another
    exception; a record it accepts renders (tables) without an exception."""
    from compare.render import report
    f = tmp_path_factory.mktemp("json") / "results.json"
    f.write_text(json.dumps(data))
    FIGURES["json_fuzzed"] += 1
    adversarial.case()
    try:
        store = Store.read(f)
    except StoreError as exc:
        assert "\n" not in str(exc) and str(f) in str(exc)
        FIGURES["json_clean"] += 1
        return
    if store.suite == "run":
        report.tables(store.records)
    FIGURES["json_clean"] += 1
