"""compare/running/caches.py: where a worker's kernel caches live, and what its record says of them."""
from __future__ import annotations

import os

import tempfile

from compare.running import caches, lifeline


class Caching:
    name = "fake"

    def cache_environment(self, cache):
        return {"FAKE_CACHE_DIR": str(cache / "kernels"), "FAKE_CACHE_OFF": "", "FAKE_CACHE_FLAG": "false"}


def test_cold_caches_are_empty_folders_in_the_cell_and_warm_ones_untouched(tmp_path, monkeypatch):
    """A cache folder is named empty, a cleared variable off, and a flag (JAX's
    JAX_ENABLE_COMPILATION_CACHE=false) by its value: a flag is not a folder."""
    for var in ("FAKE_CACHE_DIR", "FAKE_CACHE_OFF", "FAKE_CACHE_FLAG", lifeline.ROOT_ENV):
        monkeypatch.delenv(var, raising=False)
    assert caches.apply("warm", Caching(), tmp_path).startswith("warm: framework default caches")
    assert "FAKE_CACHE_DIR" not in os.environ
    note = caches.apply("cold", Caching(), tmp_path)
    assert note == "cold: FAKE_CACHE_DIR empty, FAKE_CACHE_OFF off, FAKE_CACHE_FLAG=false"
    assert os.environ["FAKE_CACHE_DIR"] == str(tmp_path / "cache" / "kernels") and (tmp_path / "cache" / "kernels").is_dir()
    assert os.environ["FAKE_CACHE_OFF"] == ""


def test_kept_caches_are_cold_for_the_process_that_fills_them_and_kept_for_the_next(tmp_path, monkeypatch):
    """``Cell.cache_dir`` (compare/running/repeats.py, COLD): the directory outlives the process."""
    for var in ("FAKE_CACHE_DIR", "FAKE_CACHE_OFF", "FAKE_CACHE_FLAG"):
        monkeypatch.delenv(var, raising=False)
    kept = tmp_path / "kept" / "cell-3"
    note = caches.apply("cold", Caching(), tmp_path / "a", str(kept))
    assert note == "cold: FAKE_CACHE_DIR empty, FAKE_CACHE_OFF off, FAKE_CACHE_FLAG=false"
    assert os.environ["FAKE_CACHE_DIR"] == str(kept / "kernels") and not (tmp_path / "a" / "cache").exists()
    note = caches.apply("cold", Caching(), tmp_path / "b", str(kept))
    assert note.startswith("kept: FAKE_CACHE_DIR as an earlier process left it")


def test_warm_caches_under_the_temporary_directory_outlive_the_worker(tmp_path, monkeypatch):
    """MLX keeps its compiled CPU kernels, Inductor its graphs, under the temporary directory, which
    the driver points at each worker's own folder: warm, they move to one folder of the driver's
    temporary root, shared by its workers (gone with the root); without a root nothing moves."""
    for var in ("TMPDIR", "TEMP", "TMP"):
        monkeypatch.setenv(var, str(tmp_path / "worker"))
    monkeypatch.setattr(tempfile, "tempdir", None)
    monkeypatch.delenv(lifeline.ROOT_ENV, raising=False)
    caches.apply("warm", Caching(), tmp_path)
    assert os.environ["TMPDIR"] == str(tmp_path / "worker")
    monkeypatch.setenv(lifeline.ROOT_ENV, str(tmp_path))
    caches.apply("warm", Caching(), tmp_path)
    shared = tmp_path / "warm-temp"
    assert shared.is_dir() and all(os.environ[v] == str(shared) for v in ("TMPDIR", "TEMP", "TMP"))
    assert tempfile.gettempdir() == str(shared)
    monkeypatch.setenv("TMPDIR", str(tmp_path / "worker"))
    caches.apply("cold", Caching(), tmp_path / "c")          # cold: the worker's own folder stays
    assert os.environ["TMPDIR"] == str(tmp_path / "worker")
    env = lifeline.child_environment({}, tmp_path / "batch")
    assert env[lifeline.ROOT_ENV] == str(lifeline.temp_root()) and env["TMPDIR"] == str(tmp_path / "batch")


def test_a_worker_leaves_at_once_only_when_every_cache_it_used_is_thrown_away():
    """Cold caches live in the cell's directory, deleted with it; warm and kept ones outlive the
    process, so their worker's teardown (an offline cache written at exit) runs."""
    cold, warm = {"cache": "cold", "cache_dir": ""}, {"cache": "warm", "cache_dir": ""}
    assert caches.nothing_to_keep([cold]) and caches.nothing_to_keep([cold, cold])
    assert not caches.nothing_to_keep([warm]) and not caches.nothing_to_keep([cold, warm])
    assert not caches.nothing_to_keep([{"cache": "cold", "cache_dir": "/kept/cell-3"}])
    assert not caches.nothing_to_keep([]) and not caches.nothing_to_keep(["not a cell"])
    caches.leave([warm])            # returns: this process goes on
