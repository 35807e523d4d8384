"""engine/mallocheap.py: glibc keeps a worker thread's heaps while a render runs, gives the
memory back when the last render ends, nests across threads, does nothing where another
allocator is the process's malloc, and never changes an image.

The memory checks run in child processes: mallopt settings are process-wide and outlast
the call, so each child starts from glibc's defaults."""
import os
import shutil
import subprocess
import sys
import textwrap
import threading

import numpy as np
import pytest

from engine import RenderSettings, mallocheap
from engine.api import cornell_box
from engine.render import render

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
MODULE = os.path.join(ROOT, "engine", "mallocheap.py")
GLIBC = mallocheap.glibc_malloc() is not None
needs_glibc = pytest.mark.skipif(not GLIBC, reason="the process's malloc is not glibc's")

# The module alone, without the engine package (numba and the kernels: seconds to import).
_LOAD = textwrap.dedent("""
    import importlib.util
    spec = importlib.util.spec_from_file_location("mallocheap", {path!r})
    mallocheap = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mallocheap)
""")

# A worker thread allocates 40 arrays of 4 MB (160 MB: more than one 64 MB heap of its
# arena), writes them and frees them; RSS (MB) is printed before, after the free and
# after the render_heap block ends. numpy only: no render, so the child is quick.
_CHILD = _LOAD + textwrap.dedent("""
    import threading
    import numpy as np

    def rss():
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmRSS"):
                    return int(line.split()[1]) / 1024

    def worker():
        arrays = [np.ones(1 << 19) for _ in range(40)]  # 40 x 4 MB, written
        del arrays

    def run():
        t = threading.Thread(target=worker)
        t.start()
        t.join()

    before = rss()
    if {inside}:
        with mallocheap.render_heap():
            run()
            during = rss()
        after = rss()
    else:
        run()
        during = after = rss()
    print(before, during, after)
""")


def _child(inside: bool, env=None):
    out = subprocess.run([sys.executable, "-c", _CHILD.format(path=MODULE, inside=inside)],
                         capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    return [float(x) for x in out.stdout.split()]


@needs_glibc
def test_a_worker_keeps_its_heaps_during_a_render_and_returns_them_after():
    before, during, after = _child(inside=True)
    # Inside: the worker's freed heaps stay mapped and written (no unmap, no re-fault
    # for the next chunk): most of its 160 MB is still resident.
    assert during - before > 100, (before, during, after)
    # After the last render: malloc_trim(0) gives the free pages back; at most the
    # worker arena's top (< one 64 MB heap) stays until that arena's next free.
    assert after - before < 70, (before, during, after)
    assert during - after > 90, (before, during, after)


@needs_glibc
def test_without_a_render_glibc_returns_a_workers_heaps_at_once():
    # The behaviour render_heap changes: by default glibc unmaps each emptied heap of a
    # thread's arena as soon as its arrays are freed (their pages fault in again later).
    before, during, after = _child(inside=False)
    assert during - before < 70, (before, during, after)


def test_render_heap_nests_across_threads():
    assert not mallocheap.active()
    go = threading.Barrier(4)
    seen = []

    def job():
        with mallocheap.render_heap():
            go.wait()  # all three inside at once
            go.wait()  # until the main thread has looked
        with mallocheap.render_heap():
            with mallocheap.render_heap():  # nested in one thread
                seen.append(mallocheap.active())

    threads = [threading.Thread(target=job) for _ in range(3)]
    for t in threads:
        t.start()
    go.wait()
    inside = mallocheap.active()
    go.wait()
    for t in threads:
        t.join()
    assert inside is GLIBC
    assert seen == [GLIBC] * 3
    assert not mallocheap.active()
    assert mallocheap._STATE["users"] == 0


_INTERPOSER = r"""
#include <stddef.h>
extern void *__libc_malloc(size_t);
extern void *__libc_calloc(size_t, size_t);
extern void *__libc_realloc(void *, size_t);
extern void __libc_free(void *);
void *malloc(size_t n) { return __libc_malloc(n); }
void *calloc(size_t n, size_t m) { return __libc_calloc(n, m); }
void *realloc(void *p, size_t n) { return __libc_realloc(p, n); }
void free(void *p) { __libc_free(p); }
"""


@needs_glibc
@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler to build a malloc")
def test_nothing_is_set_where_another_malloc_is_the_processs(tmp_path):
    # A preloaded malloc in front of glibc's (as jemalloc in a Blender built with it):
    # glibc_malloc() sees that the process's `malloc` is not libc's and sets nothing.
    src, lib = tmp_path / "m.c", tmp_path / "libm_interpose.so"
    src.write_text(_INTERPOSER)
    subprocess.run(["cc", "-shared", "-fPIC", "-O1", "-o", str(lib), str(src)], check=True)
    code = _LOAD.format(path=MODULE) + "print(mallocheap.glibc_malloc() is None)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=dict(os.environ, LD_PRELOAD=str(lib)), timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split()[-1] == "True"


def _film_bits(film):
    return [np.ascontiguousarray(getattr(film, k)).tobytes()
            for k in ("direct", "indirect", "caustic", "specular", "emission")]


def test_the_image_is_the_same_with_and_without_the_setting(monkeypatch):
    # Only where memory comes from changes: a two-worker render under render_heap has the
    # bits of one with the setting off (as without glibc) and of a one-worker render.
    scene = cornell_box(64, 48)  # x 16 spp: 3 camera chunks
    st = dict(photons=40000, caustic_photons=20000, spp=16, seed=5)
    two = render(scene, RenderSettings(workers=2, **st))
    one = render(scene, RenderSettings(workers=1, **st))
    monkeypatch.setitem(mallocheap._STATE, "libc", None)
    monkeypatch.setitem(mallocheap._STATE, "checked", True)
    off = render(scene, RenderSettings(workers=2, **st))
    assert _film_bits(two) == _film_bits(off) == _film_bits(one)
