"""compare/files.py: every write is whole, through a temporary and a rename (fast tier)."""
from __future__ import annotations

import errno
import os
import stat

import pytest

from compare import files


def temporaries(folder):
    return [p for p in folder.iterdir() if files.TEMP_MARK in p.name]


def test_a_write_is_whole_shared_and_leaves_no_temporary(tmp_path):
    path = tmp_path / "deep" / "er" / "a.json"
    files.atomic_write(path, "héllo")
    assert path.read_bytes() == "héllo".encode()
    files.atomic_write(path, b"\x00\x01")
    assert path.read_bytes() == b"\x00\x01"
    assert stat.S_IMODE(path.stat().st_mode) == 0o644 and not temporaries(path.parent)


def test_a_full_disk_keeps_the_previous_content_and_names_the_file(tmp_path, monkeypatch):
    path = tmp_path / "a.txt"
    files.atomic_write(path, "old")
    monkeypatch.setenv("COMPARE_FAULT_DISK", "0")
    monkeypatch.setattr(files, "_WRITES", [0])
    with pytest.raises(OSError) as exc:
        files.atomic_write(path, "new content")
    assert exc.value.errno == errno.ENOSPC and exc.value.filename == str(path)
    assert path.read_text() == "old" and not temporaries(tmp_path)


def test_a_folder_it_cannot_create_is_named_in_the_error(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(OSError) as exc:
        files.atomic_write(tmp_path / "file" / "a.txt", "x")
    assert exc.value.filename == str(tmp_path / "file" / "a.txt")


def test_a_symlink_is_replaced_never_followed(tmp_path):
    target = tmp_path / "elsewhere.txt"
    target.write_text("keep me")
    link = tmp_path / "results.json"
    link.symlink_to(target)
    files.atomic_write(link, "new")
    assert target.read_text() == "keep me"
    assert not link.is_symlink() and link.read_text() == "new"


def test_an_interrupted_write_leaves_no_temporary(tmp_path, monkeypatch):
    def interrupted(src, dst):
        raise KeyboardInterrupt
    monkeypatch.setattr(os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        files.atomic_write(tmp_path / "a.txt", "x")
    assert list(tmp_path.iterdir()) == []


def test_save_figure_writes_the_format_of_the_suffix(tmp_path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots()
    ax.plot([0, 1])
    files.save_figure(fig, tmp_path / "a.png")
    files.save_figure(fig, tmp_path / "a.svg")
    plt.close(fig)
    assert (tmp_path / "a.png").read_bytes().startswith(b"\x89PNG")
    assert b"<svg" in (tmp_path / "a.svg").read_bytes()[:500]
