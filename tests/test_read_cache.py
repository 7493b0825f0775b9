"""The scene's read cache: each file decoded once, read-only arrays, a bound on what it holds."""

import pickle
import threading

import numpy as np
import pytest

from edgedog.scenes import load_scene
from edgedog.scenes.read_cache import ReadCache


class CountingRead:
    """A read function that counts its calls and returns a fresh (n,) float32 array each time."""

    def __init__(self, n: int = 4):
        self.n, self.calls = n, 0

    def __call__(self):
        self.calls += 1
        return np.zeros(self.n, np.float32)


def test_a_key_is_read_once_and_handed_out_read_only():
    cache, read = ReadCache(), CountingRead()
    first = cache.get("a", read)
    assert cache.get("a", read) is first and read.calls == 1
    with pytest.raises(ValueError):
        first[0] = 1.0
    assert cache.get("none", lambda: None) is None and cache.get("none", CountingRead()) is None


def test_the_least_recently_used_go_first_beyond_the_bound():
    cache = ReadCache(max_bytes=3 * 16)  # three arrays of four float32
    reads = {key: CountingRead() for key in "abcd"}
    for key in "abc":
        cache.get(key, reads[key])
    cache.get("a", reads["a"])  # 'a' used again: 'b' is now the oldest
    cache.get("d", reads["d"])
    assert cache.nbytes == 3 * 16
    cache.get("b", reads["b"])
    cache.get("a", reads["a"])
    assert reads["b"].calls == 2 and reads["a"].calls == 1


def test_an_array_larger_than_the_bound_is_not_kept():
    cache, read = ReadCache(max_bytes=8), CountingRead(4)
    cache.get("big", read)
    cache.get("big", read)
    assert read.calls == 2 and cache.nbytes == 0


def test_threads_asking_at_once_get_one_array():
    cache, read = ReadCache(), CountingRead()
    seen, start = [], threading.Barrier(8)

    def ask():
        start.wait()
        seen.append(cache.get("k", read))

    threads = [threading.Thread(target=ask) for _ in range(8)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len({id(array) for array in seen}) == 1 and cache.nbytes == 16


def test_a_cached_scene_reads_each_file_once_and_gives_the_same_arrays(builtin_scene_dir, monkeypatch):
    plain = load_scene(builtin_scene_dir)
    cached = plain.with_read_cache()
    reads = []
    original = type(plain)._read
    monkeypatch.setattr(type(plain), "_read",
                        lambda self, path, index: reads.append(path) or original(self, path, index))
    for _ in range(3):
        edge, coverage = cached.load_edge_map(1), cached.load_coverage(1)
        assert cached.load_mask(1).dtype == bool
    assert len(reads) == 2
    assert np.array_equal(edge, plain.load_edge_map(1)) and np.array_equal(coverage, plain.load_coverage(1))
    assert plain.read_cache is None and len(reads) == 4  # the scene it came from reads its files
    assert plain.load_edge_map(1).flags.writeable
    assert pickle.loads(pickle.dumps(cached.read_cache)).nbytes == 0
