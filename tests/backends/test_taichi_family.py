"""Checks that hold for Taichi and for Quadrants (Taichi's maintained fork) alike, one body each,
parametrized over both; each framework's own checks are in tests/backends/test_taichi.py and
tests/backends/test_quadrants.py, the cases and scripts in tests/taichi_family.py. A param carries its
framework's marker, so `pytest -m taichi` / `-m quadrants` select exactly that framework's checks.

1. variants: the default is IEEE (fast_math=False; the frameworks' own default is True); the
   fast-math variant runs and reports a finite error (it need not be within tolerance); an
   unknown variant is refused before the framework starts; importing the backend package does
   not import the framework;
2. precision and operation order: outputs carry the cell's dtype and agree with Warp's float32
   output to a couple of ulps (a float64 literal or a reordered expression would show);
3. autodiff: the fused rollout (one launch, step loop reversed through adstacks) against one
   launch per step, single and (through the 'per_step' variant) batched; every batch row against
   its own single-trajectory run (independent losses, per-thread adstacks), and set_input
   replaces a batch's v0 in place; the projectile's named variants against the default rollout.
Anything that initialises the framework runs in a subprocess or a worker (its init is
process-global).
"""
from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

import backends
from compare.running import cells
from conftest import ROOT, require_device, run_cell
from taichi_family import (FASTMATH, FASTMATH_SLOW, PRECISIONS, ROLLOUTS, ROWS_OWN, ROWS_OWN_EXPECTED, SMALL,
                           VS_WARP, each, run, script)


# ---- 1. variants --------------------------------------------------------------------------------
@pytest.mark.parametrize("framework,scenario,precision,device",
                         each(FASTMATH, group="cells") + each(FASTMATH_SLOW, slow=True))
def test_fastmath_variant_runs_and_reports_a_finite_error(framework, scenario, precision, device):
    if (scenario, precision, device) in FASTMATH[framework]:       # the group's cells (run)
        record, outputs = run(framework, scenario, precision, SMALL[scenario], device, variant="fastmath")
    else:                                                           # the long tier's: a process each
        record, outputs = run_cell(framework, scenario, precision, SMALL[scenario], device, variant="fastmath")
    assert record["info"]["fast_math"] is True
    assert math.isfinite(record["error"]["vs_oracle"])      # within tolerance or not: reported
    assert all(np.all(np.isfinite(v)) for v in outputs.values())


@pytest.mark.parametrize("scenario", list(SMALL))
@pytest.mark.parametrize("framework", each(group="cells"))
def test_default_variant_is_not_fast_math(framework, scenario):
    record, _ = run(framework, scenario, "float32", SMALL[scenario])
    assert record["status"] == "ok"
    assert record["info"]["fast_math"] is False


@pytest.mark.parametrize("framework", each())
def test_unknown_variant_is_refused_before_the_framework_starts(framework):
    with pytest.raises(ValueError, match="variant"):
        backends.get(framework).setup("cpu", "float32", "fast")


@pytest.mark.parametrize("framework", each())
def test_package_import_does_not_import_the_framework(framework):
    code = f"import sys, backends.{framework}; print({framework!r} in sys.modules)"
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=cells.worker_env(),
                          capture_output=True, text=True, timeout=120)
    assert proc.stdout.strip().splitlines()[-1] == "False", proc.stderr[-2000:]


# ---- 2. precision and operation order -----------------------------------------------------------
@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("scenario", list(SMALL))
@pytest.mark.parametrize("framework", each(group="cells"))
def test_outputs_have_the_cells_precision(framework, scenario, precision):
    _, outputs = run(framework, scenario, precision, SMALL[scenario])
    assert {k: v.dtype for k, v in outputs.items()} == {k: np.dtype(precision) for k in outputs}


@pytest.mark.parametrize("framework,scenario,overrides", each(VS_WARP, group="cells"))
def test_float32_agrees_with_warp_to_two_ulps(framework, scenario, overrides):
    """Same algorithm, same operation order, same precision: bitwise on x86 CPUs in practice.

    For the projectile only loss and gradient at v0: the soft contact's descent history amplifies
    one-ulp differences (see scenarios/projectile.py)."""
    require_device(backends.reference(), "cpu")
    ours = run(framework, scenario, "float32", overrides)[1]
    ref = run(framework, scenario, "float32", overrides, backend=backends.reference())[1]
    for key in (("loss", "grad") if scenario == "projectile" else ref):
        assert ours[key].dtype == np.float32, key
        np.testing.assert_array_max_ulp(ours[key], ref[key], maxulp=2, dtype=np.float32)


# ---- 3. autodiff --------------------------------------------------------------------------------
_ROLLOUTS: dict[tuple, dict] = {}
CONTACTS = ("none", "hard", "soft")
# (precision, contacts) of ROLLOUTS' runs: the long tier's float32 (the same paths and checks)
# and float64's 'none' contact (the paths of hard and soft, which the fast tier keeps, without a
# contact's code)
ROLLOUT_RUNS = [pytest.param("float64", ("hard", "soft"), id="float64"),
                pytest.param("float64", ("none",), id="float64-none", marks=pytest.mark.slow),
                pytest.param("float32", CONTACTS, id="float32", marks=pytest.mark.slow)]


def _rollouts(framework: str, device: str, precision: str, contacts: tuple[str, ...]) -> dict:
    """ROLLOUTS' results, one process for the three tests that read them (xdist_group
    <framework>-rollouts): the rows' batch and single kernels are the variants' and the paths'."""
    if (framework, device, precision, contacts) not in _ROLLOUTS:
        variants = [v for v in backends.get(framework).scenario_variants["projectile"] if v != "checkpoint"]
        rows = device == "cpu" and precision == "float64" and {"hard", "soft"} <= set(contacts)
        _ROLLOUTS[framework, device, precision, contacts] = script(
            framework, ROWS_OWN[framework] + ROLLOUTS, device, PRECISION=precision, VARIANTS=variants,
            CONTACTS=contacts, ROWS=rows)
    return _ROLLOUTS[framework, device, precision, contacts]


@pytest.mark.parametrize("precision,contacts", ROLLOUT_RUNS)
@pytest.mark.parametrize("device", backends.DEVICES)
@pytest.mark.parametrize("framework", each(group="rollouts", early=("taichi",)))
def test_fused_rollout_equals_one_launch_per_step(framework, device, precision, contacts):
    """The fused backward pass (adstacks; Taichi's exp linearised around the primal's stored
    value, Quadrants' plain exp and mutating-if contact) gives the gradients, losses and iterates
    of the plain per-step differentiation for one trajectory: bitwise on the CPU; on CUDA, where
    the compiler contracts products and sums into FMAs kernel by kernel, to a few roundings (both
    also within the oracle's bounds). A batch of 37 (more trajectories than CPU threads, not a
    warp multiple), every contact, fused against per step at the same bounds:
    test_projectile_variants_equal_the_default_rollout."""
    r = _rollouts(framework, device, precision, contacts)["paths"]
    assert sorted(r) == sorted(f"{precision}-{c}" for c in contacts)
    for case, v in r.items():
        assert v["ok"] == [True, True], case
        assert v["fused_flags"] == [True, False], case
        assert v["shapes"] == {"loss": [[], []], "grad": [[2]] * 2,
                               "loss_history": [[4]] * 2, "v_final": [[2]] * 2}, case
        if device == "cpu":
            assert v["identical"], case
        else:
            assert v["rel"] <= (1e-12 if precision == "float64" else 1e-4), case


@pytest.mark.parametrize("framework", each(group="rollouts", early=("taichi",)))
def test_each_batch_row_is_its_own_single_trajectory(framework):
    """Trajectories do not interact: each row of a batch (rows past row 0, whose inputs are the
    seed case: tests/backends/test_parity.py::test_batch_row0_is_the_single_trajectory) equals a
    single-trajectory run at that row's v0 and target bit for bit. A shared
    loss seed, a gradient summed over rows, an adstack or exp store shared between threads, or a
    row/column mix-up in the (steps + 1, B) layout would break it. set_input replaces a batch's v0
    in place; the framework's own entries (ROWS_OWN) hold as ROWS_OWN_EXPECTED says."""
    r = _rollouts(framework, "cpu", "float64", ("hard", "soft"))["rows"]
    assert sorted(r) == ["hard", "soft"]
    for contact, v in r.items():
        assert v["rows"] == {"17": True, "36": True}, contact
        assert v["distinct"] == 37, contact          # the rows really are different problems
        assert v["set_input"] and v["set_input_changed"], contact
        assert v["wrong_shape_refused"], contact
        assert v["own"] == ROWS_OWN_EXPECTED[framework], contact


# the rollout each named variant must report, and its launches per descent iteration at 24 steps
VARIANT_PATHS = {"default": ("fused", 3), "per_step": ("per_step", 2 * 24 + 5)}


@pytest.mark.parametrize("precision,contacts", ROLLOUT_RUNS)
@pytest.mark.parametrize("device", backends.DEVICES)
@pytest.mark.parametrize("framework", each(group="rollouts", early=("taichi",)))
def test_projectile_variants_equal_the_default_rollout(framework, device, precision, contacts):
    """The variants the driver times beside the default ('per_step': one launch per step, no
    adstack) take the path they name, built as the driver builds them, and give the default's
    outputs: bitwise on the CPU (the same arithmetic), to a few roundings on CUDA (FMA
    contraction differs kernel by kernel); every one within the oracle's bounds."""
    variants = [v for v in backends.get(framework).scenario_variants["projectile"] if v != "checkpoint"]
    assert variants == ["per_step"]
    r = _rollouts(framework, device, precision, contacts)["variants"]
    assert sorted(r) == sorted(f"{c}-{v}" for c in contacts for v in ["default"] + variants)
    for case, v in r.items():
        variant = case.split("-", 1)[1]
        assert v["ok"], case
        assert (v["rollout"], v["launches"]) == VARIANT_PATHS[variant], case
        assert v["design_state"] == 4 * 25 * 37 * 2 * (8 if precision == "float64" else 4), case
        if device == "cpu":
            assert v["identical"], case
        else:
            assert v["rel"] <= (1e-12 if precision == "float64" else 1e-4), case
