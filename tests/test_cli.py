"""The command-line contract: list, exit codes, one-line errors, results files, --save-arrays."""
from __future__ import annotations

import csv
import json
import shutil
import subprocess
import sys

import numpy as np
import pytest

import backends
from compare.running.hardware import matched_copy
from conftest import FAULTY, ROOT
from reliability_checks import run_main
from shared_runs import QUICK_RUN, numpy_quick_run, quick_all, quick_argv

pytestmark = pytest.mark.cli


def compare(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "compare", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=1200)


def test_list_names_everything(compare_list):
    p = compare_list
    assert p.returncode == 0, p.stderr
    for name in ("saxpy", "sdf", "particles", "projectile", "warp"):
        assert name in p.stdout
    assert "cuda:" in p.stdout          # every device is listed, with a reason when unavailable


@pytest.mark.parametrize("args,needle", [
    (("bogus",), "unknown scenario"),
    (("saxpy", "--set", "n=0"), "n must be"),
    (("saxpy", "--set", "n=-5"), "n must be"),
    (("saxpy", "--set", "n=1.5"), "n must be an integer"),
    (("particles", "--set", "dt=nan"), "dt must be"),
    (("particles", "--set", "dt=inf"), "dt must be"),
    (("particles", "--set", "dt=-0.01"), "dt must be"),
    (("sdf", "--set", "width=1"), "width must be"),
    (("projectile", "--set", "contact=sticky"), "contact must be one of"),
    (("all", "--set", "nope=1"), "unknown parameter"),
    (("all", "--set", "n"), "KEY=VALUE"),
    (("all", "--backends", "fortran"), "unknown backend"),
    (("all", "--devices", "tpu"), "unknown device"),
    (("all", "--precision", "float16"), "unknown precision"),
    (("all", "--repeat", "0"), "--repeat"),
    (("all", "--check-sample", "-1"), "--check-sample"),
    (("all", "--host-profile", "two"), "--host-profile"),
    (("all", "--frobnicate"), "unrecognized"),
])
def test_bad_usage_exits_2_with_one_line(args, needle, tmp_path, monkeypatch):
    # compare.cli.main in this process (an exception would fail the test); the entry point in a
    # real process: tests/test_options.py::test_entry_point_sample
    monkeypatch.chdir(tmp_path)
    rc, lines = run_main(list(args))
    assert rc == 2
    assert len(lines) == 1 and needle in lines[0], lines
    assert "Traceback" not in "\n".join(lines)


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """NumPy's cells, a run other files read too (tests/shared_runs.py); Warp's are the long
    tier's (test_warp_all_quick_keeps_the_same_contracts)."""
    return numpy_quick_run(tmp_path_factory)


@QUICK_RUN
def test_all_quick_is_ok_and_exit_0(quick_run):
    p, out = quick_run
    assert p.returncode == 0, p.stdout + p.stderr
    for scenario in ("saxpy", "sdf", "particles", "projectile"):
        assert scenario in p.stdout


@pytest.mark.slow
def test_warp_all_quick_keeps_the_same_contracts(tmp_path):
    """The quick run on Warp, the reference (every cell's kernels compiled): the results and
    --save-arrays contracts the fast tier checks on NumPy's."""
    p = quick_all(tmp_path, "warp")
    assert p.returncode == 0, p.stdout + p.stderr
    results_json_contract(tmp_path, "warp")
    save_arrays_contract(tmp_path, "warp")


@QUICK_RUN
def test_results_json_contract(quick_run):
    results_json_contract(quick_run[1], "numpy")


def results_json_contract(out, backend):
    data = json.loads((out / "results.json").read_text())
    assert {"format_version", "suite", "runs", "records"} <= set(data) and data["format_version"] == 2
    for key in ("python", "packages", "cpu", "git_commit", "command"):
        assert key in data["runs"][0]
    recs = data["records"]
    assert {r["scenario"] for r in recs} == {"saxpy", "sdf", "particles", "projectile"}
    for r in recs:
        for key in ("scenario", "backend", "device", "precision", "params", "status", "reason",
                    "time", "error"):
            assert key in r
        assert r["status"] == "ok"
        assert set(r["time"]) >= {"first_call_s", "median_s", "iqr_s", "min_s", "repeats"}
        # both regimes, documented keys (README); no graph capture on a CPU, with the reason
        assert set(r["time"]["latency"]) == {"median_s", "iqr_s", "min_s", "repeats"}
        thr = r["time"]["throughput"]
        if "same_as" in thr:
            # one synchronised call already lasts a batch (a slow or busy host): the latency
            # regime's figures stand for it, said so (compare.measuring.timing.pipelined)
            assert thr["same_as"] == "latency" and thr["k"] == 1 and thr["host_s"] is None
            assert thr["median_s"] == r["time"]["latency"]["median_s"]
        else:
            assert set(thr) == {"median_s", "iqr_s", "min_s", "repeats", "k", "host_s"}
            assert thr["k"] >= 1 and thr["median_s"] > 0
            # the host's issuing time is part of each batch's time (before its one synchronise),
            # so its median cannot exceed the batches' median
            assert 0 < thr["host_s"] <= thr["median_s"]
        assert "unavailable" in r["time"]["graph"] or "median_s" in r["time"]["graph"]
        assert set(r["error"]) >= {"vs_oracle", "vs_reference", "tolerance"}
        assert r["error"]["vs_oracle"] <= r["error"]["tolerance"]
        if r["scenario"] == "projectile":
            assert len(r["gradient"]["value"]) == 2
            assert r["gradient"]["method"] == backends.get(backend).gradient_method
    # the same-run hardware yardstick, and every bandwidth-bound cell's fraction of it
    hw = data["runs"][0]["hardware"]["cpu"]
    assert hw["copy_bytes_per_s"] > 0, hw
    saxpy = [r for r in recs if r["scenario"] == "saxpy"]
    for r in saxpy:
        assert r["throughput"]["floor_kind"] == "bandwidth"
        # on the CPU against the copy nearest the cell's traffic (compare.running.hardware.matched_copy)
        bw = matched_copy(hw, r["work"]["bytes"])[0]
        want = r["work"]["bytes"] / bw / r["time"]["throughput"]["median_s"]
        assert abs(r["throughput"]["hw_fraction"] - want) <= 1e-9 * want
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert len(rows) == len(recs)
    # tidy: one row per cell, plain numbers in the documented columns
    for row, r in zip(rows, recs):
        assert (row["scenario"], row["backend"], row["precision"]) == (r["scenario"], r["backend"], r["precision"])
        assert float(row["latency_median_s"]) == r["time"]["latency"]["median_s"]
        assert int(row["throughput_k"]) == r["time"]["throughput"]["k"]
        host_s = r["time"]["throughput"]["host_s"]      # None where latency stands for it: '' (empty)
        assert (row["throughput_host_s"] == "") if host_s is None else (float(row["throughput_host_s"]) == host_s)
        assert float(row["err_vs_oracle"]) == r["error"]["vs_oracle"]
        assert json.loads(row["params"]) == r["params"]
    md = (out / "results.md").read_text()
    assert "| backend" in md and "projectile" in md


@QUICK_RUN
def test_save_arrays_contract(quick_run):
    save_arrays_contract(quick_run[1], "numpy")


def save_arrays_contract(out, backend):
    want = {"saxpy": {"a", "x", "y", "out"}, "sdf": {"image"},
            "particles": {"x0", "y0", "vx0", "vy0", "x", "y", "vx", "vy"},
            "projectile": {"loss", "grad"}}
    for scenario, keys in want.items():
        for precision in ("float32", "float64"):
            with np.load(out / "arrays" / f"{scenario}-{backend}-cpu-{precision}.npz") as z:
                assert keys <= set(z.files), (scenario, z.files)
                for k in keys & {"out", "image", "x"}:
                    assert z[k].dtype == np.dtype(precision)


PICTURES = {"saxpy", "sdf", "particles", "projectile", "time_vs_error"} | \
    {f"speed_{s}" for s in ("saxpy", "sdf", "particles", "projectile")}     # one framework: no speed-up


@QUICK_RUN
def test_every_scenario_draws_its_picture(quick_run):
    out = quick_run[1]
    assert {f.stem for f in (out / "plots").glob("*.png")} == PICTURES


@QUICK_RUN
def test_report_redraws_every_picture_and_its_page_links_them_and_leaves_the_source(quick_run, tmp_path):
    """One ``report --page`` into the run's own folder (a copy without its pictures): every picture
    redrawn from the saved arrays, the page linking them, results.json untouched."""
    run = tmp_path / "run"
    shutil.copytree(quick_run[1], run, ignore=shutil.ignore_patterns("plots"))
    src = (run / "results.json").read_text()
    notes = tmp_path / "notes.md"
    notes.write_text("Hand-written notes.")
    page = tmp_path / "page.md"
    # compare.cli.main in this process (no interpreter to start); the entry point in a real
    # process: tests/test_options.py::test_entry_point_sample
    rc, lines = run_main(["report", str(run / "results.json"), "--out", str(run), "--page", str(page),
                          "--title", "Quick page", "--notes", str(notes)])
    assert rc == 0, lines
    assert {f.stem for f in (run / "plots").glob("*.png")} == PICTURES     # from the saved arrays
    text = page.read_text()
    assert text.startswith("# Quick page") and "Hand-written notes." in text and "git commit" in text
    for s in ("saxpy", "sdf", "particles", "projectile", "time_vs_error"):
        link = next(line for line in text.splitlines() if line.startswith("![") and f"plots/{s}.png" in line)
        assert (page.parent / link[link.index("(") + 1:-1]).exists(), link
    assert (run / "results.json").read_text() == src
    rc, lines = run_main(["report", str(run / "results.json"), "--out", str(run), "--page", str(page),
                          "--notes", str(tmp_path / "missing.md")])
    assert rc == 2 and len(lines) == 1 and "--notes" in lines[0], lines


@pytest.mark.parametrize("fault,status,needle", [
    ("mismatch", "mismatch", "exceeds tolerance"),
    ("raise", "error", "RuntimeError: injected fault"),
    ("crash", "error", "signal SIGABRT"),
    # the long tier's: tests/running/test_cells.py::test_a_hanging_worker_is_killed_at_the_timeout
    # kills a hung worker at its timeout with the reason "timed out after N s" (3 s, not this
    # command's 8 s), and the cases here record any failing cell and exit 1 the same way
    pytest.param("hang", "error", "timed out", marks=pytest.mark.slow),
    # the long tier's: a worker out of memory raises MemoryError, recorded as any exception of the
    # worker is ('raise' above: compare/ treats no exception type apart)
    pytest.param("oom", "error", "MemoryError", marks=pytest.mark.slow),
])
def test_failing_cell_is_recorded_and_exits_1(tmp_path, monkeypatch, fault, status, needle):
    # the driver's handling is the same for every backend: the tests' faulty backend (NumPy's
    # kernels, which start without compiling) fails saxpy's cell on request
    monkeypatch.setenv("COMPARE_BACKENDS_EXTRA", str(FAULTY))
    monkeypatch.setenv("COMPARE_FAULT", f"saxpy:{fault}")
    p = compare("run", "saxpy", "sdf", "--quick", "--backends", "faulty", "--devices", "cpu", "--precision",
                "float32", "--repeat", "1", "--min-time", "0", "--timeout", "8", "--out", str(tmp_path), "--no-plots")
    assert p.returncode == 1, p.stderr
    recs = json.loads((tmp_path / "results.json").read_text())["records"]
    bad = [r for r in recs if r["scenario"] == "saxpy"]
    assert bad[0]["status"] == status and needle in bad[0]["reason"], bad[0]["reason"]
    # the other scenarios still ran
    assert all(r["status"] == "ok" for r in recs if r["scenario"] != "saxpy")


@QUICK_RUN
def test_resume_runs_only_missing_cells(quick_run, tmp_path):
    """The quick run cut off before its sdf cells (a copy of it without their records and
    arrays): --resume runs those and keeps every other record as it was."""
    out = tmp_path / "run"
    shutil.copytree(quick_run[1], out)
    data = json.loads((out / "results.json").read_text())
    first = [r for r in data["records"] if r["scenario"] != "sdf"]
    (out / "results.json").write_text(json.dumps({**data, "records": first}))
    for f in (out / "arrays").glob("sdf-*.npz"):
        f.unlink()
    rc, lines = run_main([*quick_argv(out, "numpy"), "--resume", "--no-plots"])     # compare.cli.main here
    assert rc == 0, lines
    assert not any(f"{s}/numpy" in ln for ln in lines for s in ("saxpy", "particles", "projectile"))
    recs = json.loads((out / "results.json").read_text())["records"]
    assert [r for r in recs if r["scenario"] != "sdf"] == first         # not rerun
    assert sorted(r["precision"] for r in recs if r["scenario"] == "sdf" and r["status"] == "ok") == \
        ["float32", "float64"]
    assert {r["scenario"] for r in recs} == {"saxpy", "sdf", "particles", "projectile"}


def test_host_profile_sample_check_and_variant_skips(tmp_path):
    """--host-profile keeps where the host's time per call goes; --check-sample checks that many
    items; a variant the device lacks (JAX's graph variant on a CPU) is a skip with the reason.
    NumPy beside JAX: a second framework without a kernel to compile cold; no minimum time: the
    profile keeps its own count of calls."""
    p = compare("run", "particles", "--backends", "numpy,jax", "--devices", "cpu", "--precision",
                "float32", "--variants", "default,graph", "--set", "n=600", "--set", "steps=20",
                "--check-sample", "50", "--host-profile", "5", "--repeat", "2", "--min-time", "0",
                "--out", str(tmp_path), "--no-plots")
    assert p.returncode == 0, p.stdout + p.stderr
    recs = json.loads((tmp_path / "results.json").read_text())["records"]
    by = {(r["backend"], r["variant"]): r for r in recs}
    assert set(by) == {("numpy", "default"), ("jax", "default"), ("jax", "graph")}
    skip = by["jax", "graph"]
    assert skip["status"] == "skipped" and "CUDA only" in skip["reason"]
    for key in (("numpy", "default"), ("jax", "default")):
        r = by[key]
        assert r["status"] == "ok", r["reason"]
        assert r["error"]["checked_items"].startswith("50 of 600"), r["error"]
        prof = r["time"]["host_profile"]
        assert prof["calls"] >= 20 and 0 < len(prof["top"]) <= 5
        own = [row["own_s"] for row in prof["top"]]
        assert own == sorted(own, reverse=True) and all(row["calls"] > 0 for row in prof["top"])
        # the top functions are part of all profiled time, which is part of the issuing time
        assert sum(own) <= prof["profiled_s"] * (1 + 1e-9) <= prof["host_s"] * 1.05


@pytest.mark.slow
def test_dask_local_cluster_gives_the_same_records(tmp_path):
    pytest.importorskip("distributed", reason="distributed not installed")
    common = ("--backends", "warp", "--devices", "cpu", "--quick", "--repeat", "1", "--no-plots")
    a = compare("all", *common, "--out", str(tmp_path / "local"))
    b = compare("all", *common, "--out", str(tmp_path / "dask"), "--scheduler", "local")
    assert a.returncode == 0 and b.returncode == 0, b.stderr
    ra = json.loads((tmp_path / "local" / "results.json").read_text())["records"]
    rb = json.loads((tmp_path / "dask" / "results.json").read_text())["records"]
    strip = lambda r: (r["scenario"], r["device"], r["precision"], r["status"], r["params"],  # noqa
                       r["error"] and {k: v for k, v in r["error"].items()},
                       r.get("gradient", {}).get("value"))
    # bitwise: same outputs on CPU (in any order: a local run on a small host overlaps set-ups,
    # so its records are saved as the cells finish)
    assert sorted(map(repr, map(strip, ra))) == sorted(map(repr, map(strip, rb)))


def test_scenario_help_lists_its_parameters_with_defaults_and_ranges():
    import contextlib
    import io
    from compare import cli
    import scenarios
    for sc in scenarios.SCENARIOS.values():
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf), pytest.raises(SystemExit):
            cli.main([sc.name, "--help"])
        text = buf.getvalue()
        for name, default, rule in sc.param_rules():
            assert f"  {name} (default {default!r}): must be" in text, (sc.name, name, text[-800:])
    rules = dict((n, r) for n, _, r in scenarios.get("saxpy").param_rules())
    assert rules["n"] == "must be in [1, 2^31-1]" and rules["inputs"] == "must be one of linspace, random"


# ---- the end-of-run summary ranks only what the figures can tell apart -------------------------
def _cell(backend: str, median: float, iqr: float = 0.0, noisy: bool = False,
          ci: tuple[float, float] | None = None):
    """A projectile CPU float32 record timed in the throughput regime."""
    from compare.results.record import Record
    t: dict = {"median_s": median, "iqr_s": iqr, "repeats": 50,
               "throughput": {"median_s": median, "iqr_s": iqr, "repeats": 5, "k": 10}}
    if noisy:
        t["noise"] = {"noisy": True, "reasons": [{"regime": "throughput", "why": "host busy: 1.2 other cores"}]}
    if ci:
        t["processes"] = {"throughput": {"median_s": median, "ci_lo_s": ci[0], "ci_hi_s": ci[1]}}
    return Record(scenario="projectile", backend=backend, device="cpu", precision="float32",
                  status="ok", params={"batch": 1}, time=t)


def _ranking(*cells) -> str:
    from compare.render import report
    lines = report.summary_lines(list(cells))
    return " ".join(x.strip() for x in lines if "projectile cpu float32" in x or x.startswith("      "))


@pytest.mark.parametrize("cells, says, never", [
    # a clear lead, both figures clean: the ranking as before
    ((_cell("jax", 1e-4, 1e-6), _cell("numba", 2e-4, 1e-6)), "fastest jax (100 µs a call), 2x ahead of numba", "tie"),
    # the loaded 2-core run: numba's cell noisy, so no lead of 97.9x is claimed
    ((_cell("jax", 1e-4, 1e-6), _cell("numba", 9.79e-3, 1e-5, noisy=True)), "noisy: rerun numba", "ahead"),
    ((_cell("jax", 1e-4, 1e-6, noisy=True), _cell("numba", 9.79e-3, 1e-5)), "noisy: rerun jax", "ahead"),
    # quartile ranges overlap (1.0 ± 0.045 against 1.08 ± 0.045), each spread under the noise limit
    ((_cell("jax", 1.0, 0.09), _cell("numba", 1.08, 0.09)), "tie: jax, numba", "ahead"),
    # apart by their quartiles but within 5 %
    ((_cell("jax", 1.0, 1e-4), _cell("numba", 1.04, 1e-4)), "tie: jax, numba", "ahead"),
    # the cross-process interval, where there is one, decides instead of the quartiles
    ((_cell("jax", 1.0, 1e-4, ci=(0.9, 1.3)), _cell("numba", 1.2, 1e-4, ci=(1.1, 1.4))), "tie: jax, numba", "ahead"),
    ((_cell("jax", 1.0, 0.09, ci=(0.99, 1.01)), _cell("numba", 1.07, 0.09, ci=(1.06, 1.08))),
     "1.07x ahead of numba", "tie"),
])
def test_summary_never_ranks_a_noisy_cell_or_an_overlapping_pair(cells, says, never):
    line = _ranking(*cells)
    assert says in line and never not in line, line
