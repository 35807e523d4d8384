"""render.small_pages: numpy's huge-page advice is off while any render runs and back to
what it was once the last overlapping one ends (renders in several threads at once)."""
import importlib
import threading

import numpy as np
import pytest

R = importlib.import_module("engine.render")


def _setting(setter):
    """numpy's current advice, read without changing it (a switch set and put back here
    would race with the threads of the test below)."""
    for name in ("numpy._core.multiarray", "numpy.core.multiarray"):
        try:
            get = getattr(importlib.import_module(name), "_get_madvise_hugepage", None)
        except ImportError:
            continue
        if get is not None:
            return bool(get())
    pytest.skip("numpy has no getter")


@pytest.mark.skipif(R._madvise_hugepage_setter() is None, reason="numpy has no switch")
def test_small_pages_nests_and_restores():
    setter = R._madvise_hugepage_setter()
    start = _setting(setter)
    try:
        for outer in (True, False):
            setter(outer)
            with R.small_pages():
                assert _setting(setter) is False
                with R.small_pages():  # an overlapping render
                    assert _setting(setter) is False
                assert _setting(setter) is False  # the outer one still runs
            assert _setting(setter) is outer
    finally:
        setter(start)


@pytest.mark.skipif(R._madvise_hugepage_setter() is None, reason="numpy has no switch")
def test_small_pages_from_threads():
    setter = R._madvise_hugepage_setter()
    start = _setting(setter)
    go = threading.Barrier(5)

    def job():
        with R.small_pages():
            go.wait()  # all four inside at once
            go.wait()  # until the main thread has looked

    threads = [threading.Thread(target=job) for _ in range(4)]
    for t in threads:
        t.start()
    go.wait()
    inside = _setting(setter)
    go.wait()
    for t in threads:
        t.join()
    assert inside is False
    assert _setting(setter) is start


def test_small_pages_keeps_values():
    # Only where memory comes from changes: a large array is the same either way.
    a = np.arange(1 << 20, dtype=np.float64)
    with R.small_pages():
        b = np.arange(1 << 20, dtype=np.float64)
    assert np.array_equal(a, b)
