"""glibc malloc's heap settings while a render runs: worker threads keep their heaps.

Why (docs/performance.md, "workers35"): glibc gives every thread that allocates its own
malloc arena, built of heaps of at most 64 MB (HEAP_MAX_SIZE, fixed when glibc is built).
A camera chunk's arrays (131,072 samples: tens of arrays of 1-3 MB live at once) outgrow
one heap, so a worker's arena maps new heaps, and glibc unmaps each heap again as soon as
it is empty (heap_trim keeps only M_TOP_PAD bytes, 128 KB by default); an array that does
not fit the heap's free top is mapped on its own (at or above the dynamic mmap threshold)
and unmapped when freed. Either way the next chunk's arrays land on fresh pages that the
kernel faults in and zeroes page by page: on Figure 6 at 160x120 a process's first
two-worker render mapped and unmapped ~120 heaps (strace), and two-worker camera stages
took 1.5-6x the minor faults of one-worker ones, whose chunks run on the main thread's brk
heap (it keeps its free top up to the trim threshold). Measured with this module: CPU
time the same within the noise of a loaded machine, the fault / system-time tail of a
first render capped, a process's RSS after a render about halved.

What (render_heap, for as long as any render runs): M_TOP_PAD = 64 MB, so heap_trim
neither unmaps nor shrinks a worker's heap (it keeps at least the pad, and a heap is at
most 64 MB: arenas keep the heaps a render grew), and M_MMAP_THRESHOLD = 32 MB (glibc's
largest), so arrays below it come from the arena's heaps instead of a mapping of their
own. When the last overlapping render ends: M_TOP_PAD back to glibc's default (128 KB)
and malloc_trim(0), which hands every free page in every arena's free lists back to the
system (the top of a thread's arena is left to its next free).

How far "restored" goes: glibc has no getter for these parameters, and setting any of
them with mallopt turns its dynamic mmap threshold off for the rest of the process. The
dynamic threshold only ever rises (to the size of the largest mapped block freed so far,
up to 32 MB, with the trim threshold at twice that): after one default render it stood at
23.8 MB here. So after the first render this module leaves M_MMAP_THRESHOLD = 32 MB and
M_TRIM_THRESHOLD = 64 MB, the dynamic threshold's own ceiling, and top pad at glibc's
default. Values are never changed: only where memory comes from (images stay bitwise).

Only where glibc's malloc is the process's malloc (Linux with glibc, e.g. Python and the
bpy wheel). Where a program replaces malloc (jemalloc, as a Blender built with
WITH_MEM_JEMALLOC links; musl; macOS; Windows) nothing is set: those allocators keep
their own per-thread caches.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import sys
import threading
from contextlib import contextmanager

# mallopt parameters (glibc's <malloc.h>).
M_TRIM_THRESHOLD = -1
M_TOP_PAD = -2
M_MMAP_THRESHOLD = -3

MB = 1 << 20
# During a render: at least one heap's size (HEAP_MAX_SIZE = 2 x DEFAULT_MMAP_THRESHOLD_MAX
# = 64 MB on 64-bit glibc), so heap_trim keeps every heap of a worker's arena.
RENDER_TOP_PAD = 64 * MB
# glibc's largest mmap threshold (DEFAULT_MMAP_THRESHOLD_MAX on 64-bit; mallopt refuses
# more): arrays below it come from the arenas, and it is where the dynamic threshold ends.
MMAP_THRESHOLD = 32 * MB
# Twice the mmap threshold, as glibc's dynamic rule sets it (free: trim = 2 x mmap).
TRIM_THRESHOLD = 2 * MMAP_THRESHOLD
# glibc's default top pad (DEFAULT_TOP_PAD in sysdeps/generic/malloc-machine.h).
DEFAULT_TOP_PAD = 128 * 1024

_LOCK = threading.Lock()
_STATE = {"users": 0, "libc": None, "checked": False}


def glibc_malloc():
    """The C library (ctypes.CDLL) when the process's malloc is glibc's, else None: on
    Linux with glibc, and only if no other allocator was linked or preloaded in front of
    it (the process's `malloc` symbol is libc's own)."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        version = libc.gnu_get_libc_version  # glibc only (not musl)
        version.restype = ctypes.c_char_p
        version()
        process = ctypes.CDLL(None)  # the symbols the process resolves first
        ours = ctypes.cast(process.malloc, ctypes.c_void_p).value
        theirs = ctypes.cast(libc.malloc, ctypes.c_void_p).value
        for name in ("mallopt", "malloc_trim"):
            getattr(libc, name).argtypes = ([ctypes.c_int, ctypes.c_int]
                                            if name == "mallopt" else [ctypes.c_size_t])
            getattr(libc, name).restype = ctypes.c_int
    except (OSError, AttributeError):
        return None
    return libc if ours == theirs else None


def _libc():
    if not _STATE["checked"]:
        _STATE["libc"] = glibc_malloc()
        _STATE["checked"] = True
    return _STATE["libc"]


def active() -> bool:
    """True while a render holds the render settings (render_heap)."""
    with _LOCK:
        return _STATE["users"] > 0 and _STATE["libc"] is not None


@contextmanager
def render_heap():
    """Within: glibc keeps worker threads' heaps (module docstring). Nests and overlaps
    across threads (several renders at once): set when the first enters, restored and
    trimmed when the last leaves. A no-op where glibc's malloc is not the process's."""
    with _LOCK:
        libc = _libc()
        if libc is not None and _STATE["users"] == 0:
            libc.mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)
            libc.mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD)
            libc.mallopt(M_TOP_PAD, RENDER_TOP_PAD)
        _STATE["users"] += 1
    try:
        yield
    finally:
        with _LOCK:
            _STATE["users"] -= 1
            if libc is not None and _STATE["users"] == 0:
                libc.mallopt(M_TOP_PAD, DEFAULT_TOP_PAD)
                libc.malloc_trim(0)
