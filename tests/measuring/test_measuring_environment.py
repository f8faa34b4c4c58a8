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
    monkeypatch.setattr(environment, "ROOT", repo)
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


def test_no_digest_named_or_no_git_is_unknown(copy: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("COMPARE_GIT_TREE", raising=False)
    assert environment.copy_dirty() is None
    monkeypatch.setenv("COMPARE_GIT_TREE", "0" * 64)
    shutil.rmtree(copy / ".git")
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
