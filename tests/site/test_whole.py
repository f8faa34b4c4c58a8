"""The site is written whole (issue 42, item 5; compare/site/whole.py): a rebuild over an earlier
site is built beside it and swapped in, so an interruption at any point leaves the old site or the
new one complete at --out and nothing else but a temporary that the next build removes; a folder
holding anything but a site is refused, not replaced; and each store file is read once."""
from __future__ import annotations

import contextlib
import copy
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from compare import cli
from compare.site import whole

ROOT = Path(__file__).resolve().parents[2]
STORE = ROOT / "tests" / "data" / "site" / "results.json"


def run_main(argv: list[str]) -> tuple[int, list[str]]:
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        rc = cli.main(argv)
    return rc, [ln for ln in err.getvalue().splitlines() if ln.strip()]


def tree(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (hidden ones included) and its bytes."""
    return {str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def siblings(out: Path) -> list[str]:
    return sorted(p.name for p in out.parent.iterdir() if p.name != out.name and p.name != "store")


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small run store: two records of each status and scenario (a site in a few seconds)."""
    doc = json.loads(STORE.read_text())
    seen: dict[tuple[str, str], int] = {}
    keep = []
    for r in doc["records"]:
        k = (r["status"], r["scenario"])
        seen[k] = seen.get(k, 0) + 1
        keep.append(r) if seen[k] <= 2 else None
    d = tmp_path_factory.mktemp("store") / "store"
    d.mkdir()
    (d / "results.json").write_text(json.dumps({**doc, "records": keep}))
    return d


@pytest.fixture(scope="module")
def old_site(store: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("old") / "site"
    assert run_main(["site", str(store), "--out", str(out), "--title", "old"]) == (0, [])
    return out


@pytest.fixture()
def site(old_site: Path, store: Path, tmp_path: Path) -> Path:
    """A copy of the old site, alone in its parent folder (with the store beside it)."""
    out = tmp_path / "site"
    shutil.copytree(old_site, out)
    shutil.copytree(store, tmp_path / "store")
    return out


class Stop(Exception):
    """The failure a test injects into the build."""


@pytest.mark.parametrize("where,exc", [("page", KeyboardInterrupt), ("page", Stop), ("overview", Stop),
                                       ("swap", KeyboardInterrupt)])
def test_an_interrupted_rebuild_leaves_the_old_site_whole(site: Path, monkeypatch: pytest.MonkeyPatch,
                                                         where: str, exc: type) -> None:
    """Stopped after some pages and figures of the new site were written (the third page), at its
    last picture, or in the swap itself: --out holds the old site byte for byte, and no temporary
    is left beside it."""
    from compare.site import assemble, pages
    before = tree(site)
    calls = []

    def fail_third(*args: Any) -> str:
        calls.append(1)
        if len(calls) == 3:
            assert list((site.parent).glob(".site.building-*/figures/*.png")), "no figure written yet"
            raise exc()
        return real(*args)

    def fail(*args: Any) -> None:
        raise exc()
    real = assemble.page_html
    if where == "page":
        monkeypatch.setattr(assemble, "page_html", fail_third)
    elif where == "overview":
        monkeypatch.setattr(pages, "matrix_png", fail)
    else:
        monkeypatch.setattr(whole, "swap_in", fail)
    argv = ["site", str(site.parent / "store"), "--out", str(site), "--title", "new"]
    if exc is KeyboardInterrupt:
        rc, lines = run_main(argv)
        assert rc == 130 and lines == ["interrupted"], (rc, lines)
    else:
        with pytest.raises(Stop):
            run_main(argv)
    assert tree(site) == before
    assert siblings(site) == []


def test_a_rebuild_replaces_the_old_site_whole(site: Path) -> None:
    """A figure only the old build drew goes with it; the new pages link only what is there."""
    (site / "figures" / "gone.png").write_bytes((site / "overview.png").read_bytes())
    (site / "figures" / "gone.csv").write_text("x\n1\n")
    assert run_main(["site", str(site.parent / "store"), "--out", str(site), "--title", "new"]) == (0, [])
    assert not (site / "figures" / "gone.png").exists() and not (site / ".compare.running.lock").exists()
    assert "<title>new</title>" in (site / "index.html").read_text()
    assert siblings(site) == []


def test_the_rebuilt_folder_keeps_its_permissions(site: Path) -> None:
    site.chmod(0o750)
    assert run_main(["site", str(site.parent / "store"), "--out", str(site)]) == (0, [])
    assert site.stat().st_mode & 0o777 == 0o750


def test_without_an_atomic_exchange_two_renames_replace_it(site: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(whole, "_exchange", lambda a, b: False)
    assert run_main(["site", str(site.parent / "store"), "--out", str(site), "--title", "new"]) == (0, [])
    assert "<title>new</title>" in (site / "index.html").read_text()
    assert siblings(site) == []


def test_a_ctrl_c_between_the_two_renames_waits_until_both_are_done(site: Path,
                                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Without an exchange, a Ctrl-C that arrives after the old site was renamed away is held
    until the new one is in place: --out is never left missing by it."""
    monkeypatch.setattr(whole, "_exchange", lambda a, b: False)
    real = os.rename

    def rename(a: Any, b: Any) -> None:
        real(a, b)
        if Path(a) == site:      # to this thread, handled before raise_signal returns: os.kill may
            signal.raise_signal(signal.SIGINT)      # land on another thread and be seen after the renames
    monkeypatch.setattr(os, "rename", rename)
    # Ctrl-C as a terminal's foreground process gets it: a test run started in the background of
    # a non-interactive shell (`cmd &`) inherits SIGINT ignored, and Python then keeps it ignored
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        rc, lines = run_main(["site", str(site.parent / "store"), "--out", str(site), "--title", "new"])
    finally:
        signal.signal(signal.SIGINT, before)
    assert rc == 130 and lines == ["interrupted"], (rc, lines)
    assert "<title>new</title>" in (site / "index.html").read_text()
    assert siblings(site) == []


def _dead_pid() -> int:
    pid = 4_000_000
    while True:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return pid
        except OSError:
            pass
        pid -= 1


def test_temporaries_of_dead_builds_are_removed_and_nothing_else(site: Path) -> None:
    """Exactly ``.NAME.building-<pid>`` (and its ``.old``) of a PID no longer running; a link of
    that name is unlinked, its target untouched; other names stay."""
    dead = _dead_pid()
    outside = site.parent / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_text("keep")
    for name in (f".site.building-{dead}", f".site.building-{dead}.old", f".site.building-{10**30}"):
        (site.parent / name / "figures").mkdir(parents=True)
        (site.parent / name / "index.html").write_text("half")
    (site.parent / f".site.building-{dead + 1}").symlink_to(outside)
    (site.parent / f".site.building-{os.getppid()}").mkdir()          # a live PID: another build
    for name in (".site.building-x1", ".site.building-1.tmp", ".other.building-1", "site.building-1"):
        (site.parent / name).mkdir()
    assert run_main(["site", str(site.parent / "store"), "--out", str(site)]) == (0, [])
    assert siblings(site) == sorted([".other.building-1", ".site.building-1.tmp", ".site.building-x1",
                                     f".site.building-{os.getppid()}", "outside", "site.building-1"])
    assert (outside / "keep.txt").read_text() == "keep"


def test_a_killed_build_leaves_the_old_site_and_a_temporary_the_next_build_removes(site: Path) -> None:
    """SIGKILL while the new site is being written (no clean-up can run): the old site stands
    whole; the next build removes the killed one's temporary folder."""
    before = tree(site)
    p = subprocess.Popen([sys.executable, "-m", "compare", "site", str(site.parent / "store"), "--out", str(site),
                          "--title", "new"], cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    temp = site.parent / f".site.building-{p.pid}"
    deadline = time.monotonic() + 240
    while not list(temp.glob("figures/*.png")) and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    assert p.returncode == -signal.SIGKILL, "the build finished before it could be killed"
    assert _without_lock(tree(site)) == before
    assert siblings(site) == [temp.name]
    assert run_main(["site", str(site.parent / "store"), "--out", str(site), "--title", "new"]) == (0, [])
    assert siblings(site) == [] and "<title>new</title>" in (site / "index.html").read_text()


def _without_lock(files: dict[str, bytes]) -> dict[str, bytes]:
    """A killed driver's lock file stays (the kernel drops the lock itself; the next driver takes
    the file over): everything else is compared."""
    return {k: v for k, v in files.items() if k != ".compare.running.lock"}


@pytest.mark.parametrize("setup,needle", [
    (lambda d: (d / "results.json").write_text("{}"), "holds files that are not a site (results.json"),
    (lambda d: (d / "notes.txt").write_text("mine") and (d / "site.json").write_text("{}"),
     "notes.txt in it is not a page or figure"),
    (lambda d: (d / "figures").mkdir() or (d / "figures" / "x.txt").write_text("")
     or (d / "site.json").write_text("{}"), "figures/x.txt in it is not a page or figure"),
], ids=["store-folder", "site-with-a-note", "site-with-a-foreign-figure"])
def test_a_folder_holding_anything_but_a_site_is_refused(tmp_path: Path, store: Path, setup: Any,
                                                         needle: str) -> None:
    out = tmp_path / "out"
    out.mkdir()
    setup(out)
    before = tree(tmp_path)
    rc, lines = run_main(["site", str(store), "--out", str(out)])
    assert rc == 2 and len(lines) == 1 and needle in lines[0], (rc, lines)
    assert tree(tmp_path) == before and sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_an_out_that_is_a_symbolic_link_is_refused(site: Path) -> None:
    link = site.parent / "link"
    link.symlink_to(site)
    before = tree(site)
    rc, lines = run_main(["site", str(site.parent / "store"), "--out", str(link)])
    assert rc == 2 and len(lines) == 1 and "symbolic link" in lines[0], (rc, lines)
    assert tree(site) == before and link.is_symlink()


def test_each_store_file_is_read_once(store: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """RESULTS and --against: each file is read from disk once (a 200 MB store took 28 s a read)."""
    import compare.results.store
    ref = tmp_path / "ref"
    ref.mkdir()
    doc = json.loads((store / "results.json").read_text())
    (ref / "results.json").write_text(json.dumps(copy.deepcopy(doc)))
    reads: list[Path] = []
    real = compare.results.store.read_bounded

    def counted(path: Path, *args: Any, **kwargs: Any) -> Any:
        reads.append(Path(path).resolve())
        return real(path, *args, **kwargs)
    monkeypatch.setattr(compare.results.store, "read_bounded", counted)
    out = tmp_path / "site"
    assert run_main(["site", str(store), "--out", str(out), "--against", str(ref)]) == (0, [])
    assert sorted(reads) == sorted([(store / "results.json").resolve(), (ref / "results.json").resolve()]), reads
    assert (out / "against.html").is_file()
