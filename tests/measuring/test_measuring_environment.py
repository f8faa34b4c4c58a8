"""compare/measuring/environment.py: the content digest that checks a copied tree against the
commit it claims (COMPARE_GIT_COMMIT / COMPARE_GIT_TREE), so a lent machine's run says clean only
where its files are that commit's."""
from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

from compare.measuring import environment

pytestmark = pytest.mark.skipif(shutil.which("git") is None, reason="needs git (apt-get install git)")


def _git(cwd: Path, *args: str) -> str:
    env = {**os.environ, "GIT_AUTHOR_NAME": "t", "GIT_AUTHOR_EMAIL": "t@t", "GIT_COMMITTER_NAME": "t",
           "GIT_COMMITTER_EMAIL": "t@t"}
    return subprocess.run(["git", *args], cwd=cwd, env=env, check=True, capture_output=True, text=True).stdout


@pytest.fixture
def copy(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """A checkout with one commit, whose later history the copy does not have (a stale .git is
    the same case: the commit's digest comes from where the commit lives)."""
    repo = tmp_path / "repo"
    (repo / "pkg").mkdir(parents=True)
    (repo / "pkg" / "a.py").write_text("x = 1\n")
    (repo / "run.sh").write_text("echo\n")
    (repo / "run.sh").chmod(0o755)
    (repo / ".gitignore").write_text("__pycache__/\n")
    _git(repo, "init", "-q")
    _git(repo, "add", "-A")
    _git(repo, "commit", "-qm", "one")
    (repo / "notes.md").write_text("not code\n")
    _git(repo, "add", "-A")
    _git(repo, "commit", "-qm", "notes")
    monkeypatch.setattr(environment, "ROOT", repo)
    monkeypatch.setattr(environment, "CODE_PATHS", ("pkg", "run.sh"))
    return repo


def test_a_copy_of_the_commit_matches_its_digest_and_any_change_does_not(copy: Path,
                                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    want = environment.files_digest("HEAD")
    assert len(want) == 64 and environment.files_digest() == want
    monkeypatch.setenv("COMPARE_GIT_TREE", want)
    assert environment.copy_dirty() is False
    (copy / "run.sh").chmod(0o644)                     # a copy that dropped an executable bit: same files
    (copy / "pkg" / "__pycache__").mkdir()
    (copy / "pkg" / "__pycache__" / "a.pyc").write_bytes(b"\0")   # ignored: not part of the tree
    assert environment.copy_dirty() is False
    (copy / "pkg" / "a.py").write_text("x = 2\n")       # an edit
    assert environment.copy_dirty() is True
    (copy / "pkg" / "a.py").write_text("x = 1\n")
    (copy / "pkg" / "b.py").write_text("")             # an untracked file the run could import
    assert environment.copy_dirty() is True
    (copy / "pkg" / "b.py").unlink()
    (copy / "run.sh").unlink()                         # a file missing from the copy
    assert environment.copy_dirty() is True


def test_a_copy_is_checked_on_its_code_alone(copy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A lent machine's copy may leave the stores and docs behind (its transfer limit): files
    outside CODE_PATHS, missing or changed, do not make it differ from the commit; code does."""
    monkeypatch.setenv("COMPARE_GIT_TREE", environment.files_digest("HEAD"))
    (copy / "notes.md").unlink()
    assert environment.copy_dirty() is False
    (copy / "pkg" / "a.py").write_text("x = 5\n")
    assert environment.copy_dirty() is True


def test_no_digest_named_is_unknown_and_a_copy_without_git_is_still_checked(copy: Path,
                                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """A ``git archive`` copy has no .git: its files are hashed through a throwaway repository."""
    monkeypatch.delenv("COMPARE_GIT_TREE", raising=False)
    assert environment.copy_dirty() is None
    want = environment.files_digest("HEAD")
    shutil.rmtree(copy / ".git")
    assert not environment.own_repository() and environment.files_digest() == want
    monkeypatch.setenv("COMPARE_GIT_TREE", want)
    assert environment.copy_dirty() is False
    monkeypatch.setenv("COMPARE_GIT_TREE", "0" * 64)
    assert environment.copy_dirty() is True
    monkeypatch.setattr(environment, "ROOT", copy / "not-there")        # git cannot tell: unknown
    assert environment.files_digest() == "" and environment.copy_dirty() is None


def test_a_run_on_a_copied_tree_says_clean_only_when_checked(copy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("COMPARE_GIT_COMMIT", "abc1234")
    monkeypatch.delenv("COMPARE_GIT_TREE", raising=False)
    assert environment.collect([])["git_dirty"] is None           # taken on its word: unknown
    monkeypatch.setenv("COMPARE_GIT_TREE", environment.files_digest("HEAD"))
    env = environment.collect([])
    assert env["git_commit"] == "abc1234" and env["git_dirty"] is False
    (copy / "pkg" / "a.py").write_text("x = 3\n")
    assert environment.collect([])["git_dirty"] is True


# ---- provenance from this project's own repository only (issue 57 item 6) ------------------------
def test_this_projects_own_checkout_records_its_commit_and_state(copy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("COMPARE_GIT_COMMIT", raising=False)
    head = _git(copy, "rev-parse", "--short", "HEAD").strip()
    assert environment.own_repository()
    env = environment.collect([])
    assert env["git_commit"] == head and env["git_dirty"] is False
    (copy / "pkg" / "a.py").write_text("x = 4\n")
    env = environment.collect([])
    assert env["git_dirty"] is True and env["git_dirty_paths"] == ["pkg/a.py"]


def test_a_copy_inside_another_checkout_records_no_commit(copy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The tree without its .git inside another clean checkout: that checkout's HEAD is not the
    project's commit (it was recorded, clean); unknown instead, unless COMPARE_GIT_COMMIT names
    one, and then the copy's files are checked without writing into the other repository."""
    want = environment.files_digest("HEAD")
    shutil.rmtree(copy / ".git")
    outer = copy.parent / "outer"
    (outer / "vendor").mkdir(parents=True)
    (outer / "README").write_text("another project\n")
    _git(outer, "init", "-q")
    _git(outer, "add", "-A")
    _git(outer, "commit", "-qm", "theirs")
    inside = shutil.copytree(copy, outer / "vendor" / "project")
    monkeypatch.setattr(environment, "ROOT", inside)
    monkeypatch.delenv("COMPARE_GIT_COMMIT", raising=False)
    monkeypatch.delenv("COMPARE_GIT_TREE", raising=False)
    assert not environment.own_repository()
    (outer / "README").write_text("their uncommitted change\n")
    env = environment.collect([])
    assert env["git_commit"] == "" and env["git_dirty"] is None and "git_dirty_paths" not in env, env
    assert environment.dirty_paths() == []          # publish's check: their changes are not ours
    assert environment.run_stamp(env)["commit"] is None
    objects = sorted(p.name for p in (outer / ".git" / "objects").rglob("*"))
    monkeypatch.setenv("COMPARE_GIT_COMMIT", "abc1234")
    monkeypatch.setenv("COMPARE_GIT_TREE", want)
    env = environment.collect([])
    assert env["git_commit"] == "abc1234" and env["git_dirty"] is False
    (inside / "pkg" / "a.py").write_text("x = 5\n")
    assert environment.collect([])["git_dirty"] is True
    assert sorted(p.name for p in (outer / ".git" / "objects").rglob("*")) == objects     # nothing written there


def test_the_projects_tree_copied_into_another_repository_names_no_commit(tmp_path: Path) -> None:
    """End to end, ROOT from the module's own place: the packages the environment needs, copied
    without .git into a subfolder of another repository's clean checkout, run from there."""
    import json
    import sys
    from conftest import ROOT
    outer = tmp_path / "theirs"
    outer.mkdir()
    (outer / "README").write_text("another project\n")
    _git(outer, "init", "-q")
    _git(outer, "add", "-A")
    _git(outer, "commit", "-qm", "theirs")
    tree = outer / "copy"
    for pkg in ("compare", "backends", "scenarios"):
        shutil.copytree(ROOT / pkg, tree / pkg, ignore=shutil.ignore_patterns("__pycache__"))
    code = ("import json; from compare.measuring import environment as e; env = e.collect([]); "
            "print(json.dumps([str(e.ROOT), env['git_commit'], env['git_dirty']]))")
    env = {k: v for k, v in os.environ.items() if k not in ("COMPARE_GIT_COMMIT", "COMPARE_GIT_TREE", "PYTHONPATH")}
    done = subprocess.run([sys.executable, "-c", code], cwd=tree, env=env, capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    root, commit, dirty = json.loads(done.stdout.splitlines()[-1])
    assert Path(root).resolve() == tree.resolve(), root        # the copy's own modules ran
    assert commit == "" and dirty is None, (commit, dirty, _git(outer, "rev-parse", "--short", "HEAD"))


def test_cpu_id_reads_x86_and_arm_processors(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every CPU run since 2026-12-02 records it (tests/results/test_environment.py); an Arm host
    (a Grace CPU) names no family, model or stepping, and had none."""
    x86 = {"cpu family": "25", "model": "17", "stepping": "1", "model name": "AMD EPYC"}
    arm = {"CPU implementer": "0x41", "CPU architecture": "8", "CPU variant": "0x0", "CPU part": "0xd4f",
           "CPU revision": "0"}
    monkeypatch.setattr(environment, "cpuinfo", lambda: x86)
    assert environment.cpu_id() == "family 25, model 17, stepping 1"
    monkeypatch.setattr(environment, "cpuinfo", lambda: arm)
    assert environment.cpu_id() == "implementer 0x41, part 0xd4f, variant 0x0, revision 0"
    monkeypatch.setattr(environment, "cpuinfo", lambda: {"model name": "x"})
    assert environment.cpu_id() == ""
