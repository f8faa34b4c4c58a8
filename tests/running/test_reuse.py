"""compare/running/reuse.py: the oracle's outputs kept across the tests' workers."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import scenarios
from compare.running import lifeline, reuse


@dataclasses.dataclass
class Counting:
    """A scenario's oracle that counts its calls (the real one's outputs)."""
    name: str = "projectile"
    calls: int = 0
    plain: bool = True

    def oracle(self, params, inputs, precision):
        self.calls += 1
        out = scenarios.get(self.name).oracle(params, inputs, precision)
        return out if self.plain else {**out, "note": 1.0}


def _question(**overrides):
    # two descent iterations: what is kept is the subject, not the oracle's work
    sc = scenarios.get("projectile")
    p = sc.params({"contact": "hard", "batch": 3, "iters": 2, **overrides}, quick=True)
    return p, sc.inputs(p, "float64")


def test_without_the_folder_every_call_computes(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(reuse.ENV, raising=False)
    monkeypatch.delenv(lifeline.ROOT_ENV, raising=False)
    sc, (p, i) = Counting(), _question()
    reuse.oracle(sc, p, i, "float64")
    reuse.oracle(sc, p, i, "float64")
    assert sc.calls == 2


def test_a_question_asked_again_is_read_back_bit_for_bit(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv(reuse.ENV, str(tmp_path))
    sc, (p, i) = Counting(), _question()
    first = reuse.oracle(sc, p, i, "float64")
    again = reuse.oracle(sc, p, i, "float64")
    assert sc.calls == 1 and list(again) == list(first)
    assert all(again[k].dtype == first[k].dtype and again[k].tobytes() == first[k].tobytes() for k in first)
    # other inputs, parameters or precision: another question, computed
    i2 = dict(i, v0=i["v0"] * 0.5)
    assert not np.array_equal(reuse.oracle(sc, p, i2, "float64")["grad"], first["grad"])
    reuse.oracle(sc, dataclasses.replace(p, iters=p.iters + 1), i, "float64")
    reuse.oracle(sc, p, i, "float32")
    assert sc.calls == 4 and not list(tmp_path.glob("*.tmp*"))


def test_outputs_that_are_not_plain_arrays_are_not_kept(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv(reuse.ENV, str(tmp_path))
    sc, (p, i) = Counting(plain=False), _question()
    assert reuse.oracle(sc, p, i, "float64")["note"] == 1.0
    assert reuse.oracle(sc, p, i, "float64")["note"] == 1.0
    assert sc.calls == 2 and not list(tmp_path.iterdir())


def test_a_drivers_workers_keep_it_in_its_temporary_root(monkeypatch, tmp_path) -> None:
    """No folder named: a worker of a driver (its root in the environment) keeps the oracle in the
    root's ``oracles``, so the run's other cells of the question read it back."""
    monkeypatch.delenv(reuse.ENV, raising=False)
    monkeypatch.setenv(lifeline.ROOT_ENV, str(tmp_path))
    sc, (p, i) = Counting(), _question()
    first = reuse.oracle(sc, p, i, "float64")
    again = reuse.oracle(sc, p, i, "float64")
    assert sc.calls == 1 and all(again[k].tobytes() == first[k].tobytes() for k in first)
    assert len(list((tmp_path / "oracles").glob("oracle-*.npz"))) == 1
    monkeypatch.setenv(lifeline.ROOT_ENV, str(tmp_path / "gone"))      # a root that is not there: computed
    reuse.oracle(sc, p, i, "float64")
    assert sc.calls == 2 and not (tmp_path / "gone").exists()


def test_an_oracle_over_the_limit_is_not_kept(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv(reuse.ENV, str(tmp_path))
    monkeypatch.setattr(reuse, "KEPT_BYTES", 8)
    sc, (p, i) = Counting(), _question()
    reuse.oracle(sc, p, i, "float64")
    reuse.oracle(sc, p, i, "float64")
    assert sc.calls == 2 and not list(tmp_path.iterdir())
