"""Big cells checked on a sample (issue 31 item 4): ``scenarios.base.sample_rows`` picks row 0,
the last row, the inputs' extreme rows and a seeded random rest, and the worker's check on those
rows compares the right oracle rows with the right output rows."""
from __future__ import annotations

import numpy as np
import pytest

import scenarios
from scenarios.base import SAMPLE_SEED, Sample, sample_rows, sample_seed


def forced_rows(n: int, *arrays: np.ndarray) -> set[int]:
    """Row 0, the last row and every column's argmin and argmax, computed independently."""
    out = {0, n - 1}
    for a in arrays:
        cols = np.asarray(a).reshape(n, -1)
        for c in range(cols.shape[1]):
            out |= {int(np.argmin(cols[:, c])), int(np.argmax(cols[:, c]))}
    return out


def checked(sc, params, inputs, outputs, k):
    """What compare/running/worker.py does with a cell's outputs: sample, oracle of the sample, check."""
    s = sc.sample(params, inputs, outputs, k)
    c_in, c_out = (s.inputs, s.outputs) if s else (inputs, outputs)
    return s, sc.check(params, c_in, c_out, sc.oracle(params, c_in, "float64"), "float64")


# ---- the helper ---------------------------------------------------------------------------
def test_sample_rows_forced_rows_count_and_seed():
    rng = np.random.default_rng(7)
    n, k = 10_000, 300
    a, b = rng.normal(size=(n, 2)), rng.uniform(size=n)
    rows = sample_rows(n, k, 5, (a, b))
    assert rows.dtype == np.int64 and rows.size == k
    assert np.all(np.diff(rows) > 0) and rows[0] == 0 and rows[-1] == n - 1     # sorted, unique
    assert forced_rows(n, a, b) <= set(rows.tolist())
    assert np.array_equal(rows, sample_rows(n, k, 5, (a, b)))            # same seed: same rows
    other = sample_rows(n, k, 6, (a, b))
    assert other.size == k and not np.array_equal(rows, other)           # another seed: others
    assert forced_rows(n, a, b) <= set(other.tolist())
    # not evenly spaced: the random part's gaps vary
    assert len(set(np.diff(rows).tolist())) > 10


@pytest.mark.parametrize("n,k", [(2, 2), (7, 3), (12, 12), (1000, 4), (1 << 28, 64)])
def test_sample_rows_edges(n, k):
    """Forced rows beyond k (all kept), k = n, and a huge n (the draw never builds n rows)."""
    x = np.random.default_rng(n).permutation(n).astype(float) if n < 1 << 20 else np.zeros(0)
    ext = (x,) if x.size else ()
    rows = sample_rows(n, k, 0, ext)
    forced = forced_rows(n, *ext)
    assert forced <= set(rows.tolist()) and np.all(np.diff(rows) > 0) and rows.max() < n
    assert rows.size == min(n, max(k, len(forced)))


def test_scalars_and_other_lengths_give_no_extremes():
    rows = sample_rows(100, 2, 0, (np.float32(3.0), np.arange(7), np.zeros((0,))))
    assert rows.tolist() == [0, 99]


# ---- the default (per-item scenarios) -------------------------------------------------------
def test_default_sample_only_for_per_item_scenarios():
    sax = scenarios.get("saxpy")
    p = sax.params({"n": 1000})
    inp = sax.inputs(p, "float32")
    s = sax.sample(p, inp, {"out": inp["x"]}, 40)
    assert isinstance(s, Sample) and (s.checked, s.total, s.item, s.seed) == (40, 1000, "", p.seed)
    rows = s.rows
    assert np.array_equal(rows, sample_rows(1000, 40, sample_seed(p), (inp["x"], inp["y"], inp["x"])))
    assert s.inputs["x"].tolist() == inp["x"][rows].tolist()
    assert s.outputs["out"].tolist() == inp["x"][rows].tolist() and np.ndim(s.inputs["a"]) == 0
    assert forced_rows(1000, inp["x"], inp["y"]) <= set(rows.tolist())
    assert sax.sample(p, inp, {"out": inp["x"]}, 1000) is None     # n <= k: all
    assert sax.sample(p, inp, {"out": inp["x"]}, 0) is None        # k = 0: all
    assert s.text() == ("40 of 1000 (seeded random: row 0, last, extremes + random, seed 0)")
    part = scenarios.get("particles")
    p = part.params({"n": 10, "steps": 3, "record_every": 1})
    inp = part.inputs(p, "float32")
    assert part.sample(p, inp, {"traj_x": np.zeros((4, 10))}, 4) is None


def test_seed_is_the_scenarios_own_or_the_stated_constant():
    copy = scenarios.get("copy")
    assert sample_seed(copy.params({"n": 100})) == SAMPLE_SEED
    part = scenarios.get("particles")
    p0, p3 = part.params({"n": 5000, "steps": 1}), part.params({"n": 5000, "steps": 1, "seed": 3})
    s0 = part.sample(p0, part.inputs(p0, "float32"), {}, 64)
    s3 = part.sample(p3, part.inputs(p3, "float32"), {}, 64)
    assert (s0.seed, s3.seed) == (0, 3) and s0.item == "particles"
    assert s3.text().startswith("64 of 5000 particles (seeded random") and s3.text().endswith("seed 3)")
    assert not np.array_equal(s0.inputs["vx0"], s3.inputs["vx0"])


# ---- the check looks at the right rows ------------------------------------------------------
def test_particles_sample_oracle_is_the_oracle_sample_and_catches_a_planted_error():
    sc = scenarios.get("particles")
    p = sc.params({"n": 3001, "steps": 40})
    inp = sc.inputs(p, "float64")
    full = sc.oracle(p, inp, "float64")
    port = {k: full[k].copy() for k in sc.outputs}       # a port that agrees with the oracle
    s, chk = checked(sc, p, inp, port, 64)
    assert chk.ok and s.checked == 64
    rows = s.rows
    assert forced_rows(p.n, inp["x0"], inp["y0"], inp["vx0"], inp["vy0"]) <= set(rows.tolist())
    sub = sc.oracle(p, s.inputs, "float64")
    for k in ("x", "y", "vx", "vy", "error_bound", "ill_conditioned"):
        assert np.array_equal(sub[k], full[k][rows]), k
    # an error in a drawn (not forced) well-conditioned row inside the sample is caught ...
    forced = forced_rows(p.n, inp["x0"], inp["y0"], inp["vx0"], inp["vy0"])
    drawn = [int(r) for r in rows if int(r) not in forced and not full["ill_conditioned"][r]]
    bad = {k: v.copy() for k, v in port.items()}
    bad["x"][drawn[len(drawn) // 2]] += 1e-3
    assert not checked(sc, p, inp, bad, 64)[1].ok
    # ... and one outside it is not looked at (what a sample gives up)
    outside = next(r for r in range(p.n) if r not in set(rows.tolist()))
    bad = {k: v.copy() for k, v in port.items()}
    bad["x"][outside] += 1e-3
    assert checked(sc, p, inp, bad, 64)[1].ok
    # a NaN a port writes into any row is always looked at: it is an extreme of its output
    bad = {k: v.copy() for k, v in port.items()}
    bad["vy"][outside] = np.nan
    s_nan, chk_nan = checked(sc, p, inp, bad, 64)
    assert outside in s_nan.rows.tolist() and not chk_nan.ok


def test_projectile_batch_sample_oracle_is_the_oracle_sample_and_catches_a_planted_error():
    sc = scenarios.get("projectile")
    p = sc.params({"batch": 150, "steps": 30, "iters": 2, "contact": "hard", "seed": 4})
    inp = sc.inputs(p, "float64")
    full = sc.oracle(p, inp, "float64")
    port = {k: np.array(full[k]) for k in sc.outputs}
    s, chk = checked(sc, p, inp, port, 16)
    assert chk.ok and (s.checked, s.total, s.item, s.seed) == (16, 150, "trajectories", 4)
    rows = s.rows
    forced = forced_rows(p.batch, inp["v0"], inp["target"])
    assert forced <= set(rows.tolist()) and len(forced) > 2
    assert np.array_equal(s.inputs["v0"], inp["v0"][rows])
    assert np.array_equal(s.outputs["loss_history"], port["loss_history"][:, rows])
    sub = sc.oracle(p, s.inputs, "float64")
    for k in ("loss", "grad", "v_final"):              # per-trajectory arithmetic: bitwise
        assert np.array_equal(sub[k], full[k][rows]), k
    assert np.array_equal(sub["loss_history"], full["loss_history"][:, rows])
    drawn = [int(r) for r in rows if int(r) not in forced]
    bad = {k: v.copy() for k, v in port.items()}
    bad["grad"][drawn[len(drawn) // 2], 1] *= 1.01
    res = checked(sc, p, inp, bad, 16)[1]
    assert not res.ok and rows[res.details["worst_trajectory"]] == drawn[len(drawn) // 2]
    assert sc.sample(p, inp, port, 150) is None              # batch <= k: every trajectory
