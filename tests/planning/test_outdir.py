"""Nothing overwritten silently: a run refuses an --out holding an earlier run's results unless
told (--resume keeps them, --force replaces them), a forced run leaves no picture of the earlier
one, `report` never rewrites its inputs, and results.md opens with readable text."""
from __future__ import annotations

import contextlib
import io
import json
import shutil
from pathlib import Path

import pytest

from compare import cli
from shared_runs import QUICK_RUN, numpy_quick_run

RUN = ["saxpy", "--backends", "numpy", "--devices", "cpu", "--precision", "float32", "--quick",
       "--repeat", "2", "--min-time", "0"]


def main(argv: list[str]) -> tuple[int, str]:
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        rc = cli.main(argv)
    return rc, err.getvalue()


@pytest.fixture(scope="module")
def earlier_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An earlier run's --out: the quick run of tests/shared_runs.py (each test works on its own copy)."""
    p, out = numpy_quick_run(tmp_path_factory)
    assert p.returncode == 0, p.stdout + p.stderr
    return out


def copy_of(run: Path, tmp_path: Path) -> Path:
    out = tmp_path / "results"
    shutil.copytree(run, out)
    return out


@QUICK_RUN
def test_an_earlier_run_is_kept_or_replaced_only_when_told(earlier_run: Path, tmp_path: Path) -> None:
    out = copy_of(earlier_run, tmp_path)
    first = (out / "results.json").read_bytes()
    stale = out / "plots" / "sdf.png"             # a picture only the earlier run drew
    stale.write_bytes(b"old")
    (out / "plots" / "mine.png").write_bytes(b"the user's")

    rc, err = main([*RUN, "--out", str(out)])
    assert rc == 2 and err.count("\n") == 1 and "earlier run's results" in err and "--force" in err, err
    assert (out / "results.json").read_bytes() == first

    rc, err = main([*RUN, "--out", str(out), "--resume", "--force"])
    assert rc == 2 and "give one" in err

    assert main([*RUN, "--out", str(out), "--force", "--set", "n=300"])[0] == 0
    recs = json.loads((out / "results.json").read_text())["records"]
    assert [r["params"]["n"] for r in recs] == [300]
    assert not stale.exists() and (out / "plots" / "mine.png").read_bytes() == b"the user's"
    assert (out / "plots" / "speed_saxpy.png").is_file()

    md = (out / "results.md").read_text()
    head = md.split("## saxpy")[0]
    assert "- command: `" in head and "yardstick (cpu): copy" in head
    assert "{'" not in head and max(len(line) for line in head.splitlines()) < 600, head


@QUICK_RUN
def test_report_never_rewrites_its_input(earlier_run: Path, tmp_path: Path) -> None:
    out = copy_of(earlier_run, tmp_path)
    before = (out / "results.json").read_bytes()
    rc, err = main(["report", str(out / "results.json"), "--out", str(out)])
    assert rc == 2 and "rewrite its input" in err, err
    assert (out / "results.json").read_bytes() == before
    # --no-plots: where it writes is the subject; a report drawing its pictures is
    # tests/test_cli.py::test_report_redraws_every_picture_and_its_page_links_them_and_leaves_the_source
    assert main(["report", str(out / "results.json"), "--out", str(tmp_path / "merged"), "--no-plots"])[0] == 0


def test_a_merged_report_names_its_inputs_and_each_run_in_its_header(tmp_path: Path) -> None:
    """report FILE --out DIR: results.md opens with the runs the input records (not the merge
    entry's empty fields: 'command: `None`'), and so does a report of that report."""
    store = Path(__file__).resolve().parents[1] / "data" / "site" / "results.json"
    runs = json.loads(store.read_text())["runs"]
    heads = []
    for src, out in ((store, tmp_path / "one"), (tmp_path / "one" / "results.json", tmp_path / "two")):
        # --no-plots: the header is the subject; a report drawing its pictures is
        # tests/test_cli.py::test_report_redraws_every_picture_and_its_page_links_them_and_leaves_the_source
        assert main(["report", str(src), "--out", str(out), "--no-plots"])[0] == 0
        head = (out / "results.md").read_text().split("\n## ")[0]
        assert f"- merged from: `{src}`" in head and "None" not in head, head
        for env in runs:
            assert f"- command: `{env['command']}`" in head and f"- run {env['created']} on {env['hostname']}" in head
        heads.append(head.split("\n", 3)[3])
    assert heads[0] == heads[1]          # the runs of a merge of a merge: the same lines
    from compare.site import data        # and the site's machine page lists the same runs
    assert [dict(e) for e in data.load([tmp_path / "two"]).runs] == runs


def test_a_cold_cache_creates_only_cache_directories(tmp_path, monkeypatch):
    """The cold-cache policy makes the backend's cache directories inside the cell's own folder
    and nothing else: a flag's value (JAX's JAX_ENABLE_COMPILATION_CACHE=false) is not a path to
    create in the working directory."""
    import os

    import backends
    from compare.running.caches import apply as apply_cache_policy
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(os, "environ", dict(os.environ))
    cell = tmp_path / "cell"
    note = apply_cache_policy("cold", backends.get("jax"), cell)
    assert os.environ["JAX_ENABLE_COMPILATION_CACHE"] == "false" and note.startswith("cold")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cell"] or not any(tmp_path.iterdir())
    assert not (tmp_path / "false").exists()
