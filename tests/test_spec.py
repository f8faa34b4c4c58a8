"""The one typed cell (compare/spec.py): built once from overrides, checked field by field, across
a process boundary as ``to_dict`` / ``from_dict`` unchanged, and named by one ``key`` that its
records share."""
from __future__ import annotations

import dataclasses
import json

import pytest

import scenarios
from backends.base import Device
from compare import spec
from compare.results.record import Record
from compare.spec import Cell, SpecError
from scenarios.base import Precision


def saxpy(**settings) -> Cell:
    return Cell.make("saxpy", "numpy", "cpu", "float32", params={"n": 1000}, **settings)


def test_a_cell_crosses_a_process_boundary_unchanged() -> None:
    cell = saxpy(variant="default", tags={"sweep": "size", "knob": {"n": 1000}}, repeat=3, min_time=0.0,
                 timer="wall", cache="warm", throughput=False, save_inputs=True)
    d = cell.to_dict()
    wire = json.loads(json.dumps(d))                  # plain JSON types only
    assert wire == d and d["device"] == "cpu" and d["precision"] == "float32" and d["params"]["n"] == 1000
    back = Cell.from_dict(wire)
    assert back == cell and back.key() == cell.key()
    assert isinstance(back.device, Device) and isinstance(back.precision, Precision)
    assert isinstance(back.params, scenarios.get("saxpy").Params)


def test_make_resolves_overrides_over_the_quick_sizes_over_the_defaults() -> None:
    sc = scenarios.get("saxpy")
    assert Cell.make("saxpy", "numpy", "cpu", "float32").params == sc.params()
    assert Cell.make("saxpy", "numpy", "cpu", "float32", quick=True).params == sc.params(quick=True)
    assert Cell.make("saxpy", "numpy", "cpu", "float32", params={"n": 77}, quick=True).params.n == 77
    # a hand-written dict (a Dask task, a test) may give overrides and quick, as make takes them
    assert Cell.from_dict({"scenario": "saxpy", "backend": "numpy", "device": "cpu", "precision": "float64",
                           "params": {"n": 77}, "quick": True}).params.n == 77


@pytest.mark.parametrize("d,needle", [
    ({"bogus": 1}, "unknown key 'bogus'"),
    ({"device": "tpu"}, "device must be one of"),
    ({"precision": "float16"}, "precision must be one of"),
    ({"backend": ""}, "backend must be a non-empty string"),
    ({"scenario": "no-such-scenario"}, "cell spec: "),
    ({"params": [1, 2]}, "params and tags must be mappings"),
    ({"repeat": 0}, "repeat must be an integer >= 1"),
    ({"min_time": float("nan")}, "min_time must be finite and >= 0"),
    ({"warmup": -1}, "warmup must be an integer >= 0"),
    ({"timer": "cycles"}, "timer must be auto|wall"),
    ({"tags": [1]}, "tags must be a mapping"),
    ({"cache_dir": 3}, "cache_dir must be a path"),
    ({"cache_dir": "/tmp/x", "cache": "warm"}, "cache_dir must be a path (with cache cold)"),
])
def test_a_malformed_cell_is_one_line_naming_its_field(d: dict, needle: str) -> None:
    good = {"scenario": "saxpy", "backend": "numpy", "device": "cpu", "precision": "float32"}
    with pytest.raises(SpecError) as exc:
        Cell.from_dict({**good, **d})
    assert needle in str(exc.value) and "\n" not in str(exc.value), str(exc.value)


def test_not_an_object_and_unresolved_params_are_refused() -> None:
    with pytest.raises(SpecError, match="must be an object, got list"):
        Cell.from_dict([])                                        # type: ignore[arg-type]
    with pytest.raises(SpecError, match="params must be a resolved"):
        Cell("saxpy", "numpy", Device("cpu"), Precision("float32"), params={"n": 10})


def test_the_key_of_a_cell_is_the_key_of_its_records() -> None:
    cell = saxpy(tags={"busy_cores": 2})
    ident = cell.identity()
    assert ident["device"] == "cpu" and ident["params"] == dataclasses.asdict(cell.params)
    rec = Record.from_json({**ident, "status": "skipped", "reason": "", "time": None, "error": None})
    assert rec.key == cell.key() == spec.key(rec.to_json()) == spec.key(ident)
    # the timing settings are not identity: the same cell timed differently is the same cell
    assert saxpy(tags={"busy_cores": 2}, repeat=50, cache="warm").key() == cell.key()
    # every identity field, the parameters and the tags are
    others = [saxpy(), saxpy(tags={"busy_cores": 3}), saxpy(variant="fastmath", tags={"busy_cores": 2}),
              Cell.make("saxpy", "numpy", "cpu", "float64", params={"n": 1000}, tags={"busy_cores": 2}),
              Cell.make("saxpy", "numpy", "cpu", "float32", params={"n": 1001}, tags={"busy_cores": 2})]
    assert len({c.key() for c in others} | {cell.key()}) == len(others) + 1


def test_a_record_without_variant_or_tags_has_the_default_cells_key() -> None:
    cell = saxpy()
    assert "tags" not in cell.identity()            # empty tags are not stored
    stored = {k: v for k, v in cell.identity().items() if k != "variant"}
    assert spec.key(stored) == cell.key() == spec.key({**stored, "tags": None})
