"""compare/running/caches.py: where a worker's kernel caches live, and what its record says of them."""
from __future__ import annotations

import os

from compare.running import caches


class Caching:
    name = "fake"

    def cache_environment(self, cache):
        return {"FAKE_CACHE_DIR": str(cache / "kernels"), "FAKE_CACHE_OFF": "", "FAKE_CACHE_FLAG": "false"}


def test_cold_caches_are_empty_folders_in_the_cell_and_warm_ones_untouched(tmp_path, monkeypatch):
    """A cache folder is named empty, a cleared variable off, and a flag (JAX's
    JAX_ENABLE_COMPILATION_CACHE=false) by its value: a flag is not a folder."""
    for var in ("FAKE_CACHE_DIR", "FAKE_CACHE_OFF", "FAKE_CACHE_FLAG"):
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
    assert note.startswith("kept: FAKE_CACHE_DIR as an earlier process of this cell left it")
