"""The only module that talks to embreex: BVH build, closest-hit and occlusion queries.

embreex does no shape checks (fewer direction rows than origins segfaults), ignores tnear
(always 0) and overwrites `dists`; this wrapper validates and copies so callers cannot
crash the process. Queries are split across threads: embreex releases the GIL.
"""
from __future__ import annotations

import copy
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .jit import kernel, register_warm_up
from .parallel import Cancelled

try:
    from embreex import rtcore_scene as _rtcs
    from embreex.mesh_construction import TriangleMesh as _TriangleMesh
except ImportError as exc:  # pragma: no cover - reported to the user by the caller
    _rtcs = None
    _IMPORT_ERROR = exc
else:
    _IMPORT_ERROR = None

MIN_PER_THREAD = 4096  # below this, threading costs more than it saves

# The BVH is built in pieces so that a cancel is noticed between them: embreex holds the
# GIL while it copies a mesh (~1.7 s per 1M triangles), so nothing else in the process runs
# meanwhile. A piece of MESH_TRIANGLES copies in ~0.1 s; the pieces are meshes of one
# Embree scene, traced as fast as one mesh. embreex also holds the GIL while Embree
# commits (builds) the BVH (~0.4 s per 1M triangles): the commit is made here through
# Embree's C API with the GIL released, on a worker thread while the caller polls
# (_free_commit). Where that is not possible (an embreex with another object layout),
# the triangles are split into Embree scenes of BLOCK_TRIANGLES (~0.2 s commit each), at
# a cost in query speed: each block is one more traversal per ray (1M triangles as 1 / 2 /
# 4 blocks traced 2.1 / 1.4 / 1.0 Mrays/s; docs/performance.md, "Large scenes").
MESH_TRIANGLES = 1 << 16
BLOCK_TRIANGLES = 1 << 19
POLL_SECONDS = 0.05

# Embree's scene flags (rtcore_scene.h). COMPACT makes Embree keep triangles as indices
# into its vertex copy instead of copying the corners into the BVH leaves, and build
# without its memory-hungry algorithms: measured on a 2M-triangle mesh, 61 B a triangle
# kept and at the peak of the build instead of 91 B kept and 123 B at the peak, the same
# hits bit for bit, closest hits 10-30 % slower (docs/performance.md, "Memory per
# triangle"). Used from COMPACT_TRIANGLES on, where memory per triangle starts to count.
# 2^18 -> 2^19 (hair39): newuser38's 3000-strand groom (288,000 tube triangles) traced its
# rays 20-26 % slower in the compact BVH (Embree 11.3 -> 9.0 s of a 16 spp render); below
# 2^19 the default BVH costs at most ~16 MB more kept, ~32 MB at the build. The two BVHs
# answered 800k test rays alike, but not every ray of a render: the groom's 128 spp film
# differs in 9 % of its pixels by noise (docs/performance.md hair39).
SCENE_FLAG_COMPACT, SCENE_FLAG_ROBUST = 2, 4
COMPACT_TRIANGLES = 1 << 19


def _embree_library():
    """Embree's C library as loaded by embreex (ctypes releases the GIL in its calls), its
    rtcCommitScene, and the offset of the RTCScene pointer in an EmbreeScene object, or
    None. The pointer precedes the public is_committed field (embreex's rtcore_scene.pxd
    declares scene_i, is_committed, device); a scene made robust must then report
    RTC_SCENE_FLAG_ROBUST through rtcGetSceneFlags."""
    try:
        import ctypes
        import glob
        import os

        import embreex
        here = os.path.dirname(embreex.__file__)
        # Where the wheels bundle it: manylinux and Windows (embreex.libs beside the
        # package), macOS (.dylibs inside it).
        names = (glob.glob(os.path.join(here, "..", "embreex.libs", "*embree4*"))
                 + glob.glob(os.path.join(here, ".dylibs", "*embree4*"))
                 + glob.glob(os.path.join(here, "*embree4*")))
        if not names:
            return None
        lib = ctypes.CDLL(names[0])
        lib.rtcCommitScene.argtypes = [ctypes.c_void_p]
        lib.rtcCommitScene.restype = None
        lib.rtcGetSceneFlags.argtypes = [ctypes.c_void_p]
        lib.rtcGetSceneFlags.restype = ctypes.c_int
        lib.rtcSetSceneFlags.argtypes = [ctypes.c_void_p, ctypes.c_int]
        lib.rtcSetSceneFlags.restype = None
        # Shared geometry buffers (_attach_shared): Embree reads our arrays, no copy.
        vp = ctypes.c_void_p
        for name, args, res in (
                ("rtcGetSceneDevice", [vp], vp), ("rtcNewGeometry", [vp, ctypes.c_int], vp),
                ("rtcSetSharedGeometryBuffer", [vp, ctypes.c_int, ctypes.c_uint, ctypes.c_int,
                                                vp, ctypes.c_size_t, ctypes.c_size_t,
                                                ctypes.c_size_t], None),
                ("rtcCommitGeometry", [vp], None), ("rtcAttachGeometry", [vp, vp], ctypes.c_uint),
                ("rtcReleaseGeometry", [vp], None), ("rtcReleaseDevice", [vp], None),
                ("rtcGetDeviceError", [vp], ctypes.c_int)):
            fn = getattr(lib, name)
            fn.argtypes, fn.restype = args, res
        probe = _rtcs.EmbreeScene(robust=True)
        size = type(probe).__basicsize__
        magic = 0x5A5A1234
        probe.is_committed = magic
        raw = bytes((ctypes.c_char * size).from_address(id(probe)))
        probe.is_committed = 0
        at = raw.find(magic.to_bytes(4, "little"))
        ptr_size = ctypes.sizeof(ctypes.c_void_p)
        # The layout embreex 4.4 compiles to: object header (2 pointers), scene_i,
        # is_committed (padded to a pointer), device. Anything else: not this layout.
        if size != 5 * ptr_size or at != 3 * ptr_size \
                or raw.find(magic.to_bytes(4, "little"), at + 1) != -1:
            return None
        offset = at - ptr_size
        ptr = ctypes.c_void_p.from_address(id(probe) + offset).value
        if not ptr or lib.rtcGetSceneFlags(ptr) != 4:  # RTC_SCENE_FLAG_ROBUST
            return None
        return lib, offset, ctypes
    except Exception:  # noqa: BLE001 - any surprise: build in blocks instead
        return None


_LIBRARY = None if _rtcs is None else _embree_library()


# ---------------------------------------------------------------- closest hits in a kernel
# Accel.intersect (_intersect_rows) and Accel.intersect_hits with output arrays
# (_intersect_packets) trace through Embree's rtcIntersect8 called from a compiled
# kernel: the Embree query embreex's run() makes per ray, without run()'s per-call output
# arrays (Ng, tfar, ids, u, v: 36 B a ray, fresh pages every call) and its Python-level
# answer. The ray-hit record is Embree 4's RTCRayHit8 (rtcore_ray.h), in 32-bit words of
# 8 lanes: org 0-2, tnear 3, dir 4-6, time 7, tfar 8, mask 9, id 10, flags 11; hit Ng
# 12-14, u 15, v 16, primID 17, geomID 18, instID 19, instPrimID 20. The rays are set up
# as embreex sets them (tnear 0, time 0, mask all, no arguments), a miss answers as
# embreex's (primID and geomID -1, u = v = 0), and _rows_agree / _packets_agree check
# that on a probe before a kernel is used.
_RAYHIT_WORDS = 24
# Rays an occlusion query traces together (rtcOccluded8): Embree's 8-wide packets are
# native on AVX2 and AVX-512 (16 lanes measured 21.4 against 23.4 ns a gather-lookup ray
# on AVX-512; 4 lanes 39.6, one ray at a time 68).
OCCLUSION_PACKET = 8
# Rays a closest-hit query traces together (rtcIntersect8): consecutive rays start near
# each other (a pixel's samples, a gather point's rays), and 8 lanes beat one ray at a
# time on every caller (Figure 6, 160x120, thread CPU ns a ray: the final gather's rays
# 121 -> 98, the camera paths' 100 -> 79, the photon pass's 153 -> 136; 4 lanes 100 /
# 81 / 138, 16 lanes 120 / 101 / 164; the same answers bit for bit:
# bench/bench_packets.py, docs/performance.md "packets").
INTERSECT_PACKET = 8
_F32_MAX = np.float32(np.finfo(np.float32).max)

try:
    from llvmlite import ir as _ir
    from numba import types as _types
    from numba.extending import intrinsic as _intrinsic
except ImportError:  # pragma: no cover - numba is a dependency of the engine
    _intrinsic = None

if _intrinsic is not None:
    @_intrinsic
    def _call_c4(typingctx, fn, a, b, c):
        """fn(a, b, c, NULL) for the C function void fn(void*, void*, void*, void*) at
        address fn (a, b, c addresses): how a kernel calls rtcOccluded8 / rtcIntersect8
        (valid, scene, ray packet, args)."""
        sig = _types.void(_types.intp, _types.intp, _types.intp, _types.intp)

        def codegen(context, builder, signature, args):
            f, x, y, z = args
            vp = _ir.IntType(8).as_pointer()
            fnty = _ir.FunctionType(_ir.VoidType(), [vp, vp, vp, vp])
            builder.call(builder.inttoptr(f, fnty.as_pointer()),
                         [builder.inttoptr(x, vp), builder.inttoptr(y, vp),
                          builder.inttoptr(z, vp), _ir.Constant(vp, None)])
            return context.get_dummy_value()
        return sig, codegen

    @kernel
    def _packet_record(w):
        """A ray packet of w lanes for rtcOccluded{w} / rtcIntersect{w} (RTCRayHit{w}: 21
        fields of w 32-bit words, 64-byte aligned, which 8 and 16 lanes need) and its
        valid mask: (r (21 w,) float32, ri the same words as uint32, r's address, valid
        (w,) int32, valid's address). The views keep their buffers alive."""
        buf = np.empty(21 * w + 16, np.float32)
        start = buf.ctypes.data
        skip = ((start + 63) & ~63) - start
        r = buf[skip // 4:skip // 4 + 21 * w]
        vbuf = np.empty(w + 16, np.int32)
        vstart = vbuf.ctypes.data
        vskip = ((vstart + 63) & ~63) - vstart
        return r, r.view(np.uint32), start + skip, vbuf[vskip // 4:vskip // 4 + w], \
            vstart + vskip

    @kernel
    def _set_lane(r, ri, w, lane, ox, oy, oz, dx, dy, dz, tfar, hit):
        """Lane `lane` of packet r / ri (_packet_record) set up as embreex's run() sets up
        its one ray: origin, direction and tfar (each stored as float32), tnear 0, time 0,
        mask all, id 0, flags 0; with hit (an intersect query) the hit's u = v = 0 and its
        ids -1 (RTC_INVALID_GEOMETRY_ID), as a miss answers."""
        none = np.uint32(0xFFFFFFFF)
        r[lane], r[w + lane], r[2 * w + lane] = ox, oy, oz
        r[3 * w + lane] = 0.0
        r[4 * w + lane], r[5 * w + lane], r[6 * w + lane] = dx, dy, dz
        r[7 * w + lane] = 0.0
        r[8 * w + lane] = tfar
        ri[9 * w + lane], ri[10 * w + lane], ri[11 * w + lane] = none, 0, 0
        if hit:
            r[15 * w + lane], r[16 * w + lane] = 0.0, 0.0
            for f in range(17, 21):
                ri[f * w + lane] = none

    @kernel
    def _fill_packet(r, ri, valid, w, s, o32, d32, tfar32, hit):
        """Packet r / ri (_packet_record) set up with rays s, s + 1, ... of o32, d32 (N,3)
        float32 and tfar32 (N,) float32 (_set_lane), at most w of them; the lanes past the
        last ray marked invalid in valid (w,) int32. Returns the end of the rays taken."""
        e = min(s + w, o32.shape[0])
        for lane in range(w):
            i = s + lane
            if i < e:
                valid[lane] = -1
                _set_lane(r, ri, w, lane, o32[i, 0], o32[i, 1], o32[i, 2], d32[i, 0],
                          d32[i, 1], d32[i, 2], tfar32[i], hit)
            else:
                valid[lane] = 0
        return e

    @kernel
    def _occluded_packets(fn, scene, o32, d32, tfar32, blocked):
        """Occlusion of rays o32, d32 (N,3) float32 within [0, tfar32] ((N,) float32, not
        written) through rtcOccluded8 at address fn on the RTCScene at address scene,
        OCCLUSION_PACKET consecutive rays a call (the last call's missing lanes invalid);
        blocked (N,) bool receives the answers (Embree sets a blocked lane's tfar to
        -inf). Each lane is set up as embreex's run() sets up its one ray (tnear 0, time
        0, mask all, id 0, flags 0). Consecutive rays that start and end near each other
        (the gather lookup's, in Morton order; the direct light's per pixel) traverse the
        BVH together: 24-25 ns a ray against 62-82 ns one by one (docs/performance.md,
        "gathercand")."""
        w = OCCLUSION_PACKET
        ray, rayi, at, valid, vat = _packet_record(w)
        n = o32.shape[0]
        for s in range(0, n, w):
            e = _fill_packet(ray, rayi, valid, w, s, o32, d32, tfar32, False)
            _call_c4(fn, vat, scene, at)
            for lane in range(e - s):
                blocked[s + lane] = ray[8 * w + lane] < 0.0

    @kernel
    def _intersect_packets(fn, scene, o32, d32, tfar32, geom, prim, u, v):
        """Closest hits of rays o32, d32 (N,3) float32 up to tfar32 (N,) (overwritten with
        the hit distance, as embreex does) through rtcIntersect8 at address fn on the
        RTCScene at address scene, INTERSECT_PACKET consecutive rays a call (the last
        call's missing lanes invalid); writes geom, prim (N,) int32 and u, v (N,) float32
        as embreex's run() answers them. Each lane is set up as run() sets up its one ray
        (tnear 0, time 0, mask all, id 0, flags 0; hit ids -1, u = v = 0). RTCRayHit8
        (rtcore_ray.h) in 32-bit words, w lanes each: org 0-2, tnear 3, dir 4-6, time 7,
        tfar 8, mask 9, id 10, flags 11, Ng 12-14, u 15, v 16, primID 17, geomID 18,
        instID 19, instPrimID 20."""
        w = INTERSECT_PACKET
        r, ri, at, valid, vat = _packet_record(w)
        n = o32.shape[0]
        for s in range(0, n, w):
            e = _fill_packet(r, ri, valid, w, s, o32, d32, tfar32, True)
            _call_c4(fn, vat, scene, at)
            for lane in range(e - s):
                i = s + lane
                tfar32[i] = r[8 * w + lane]
                geom[i] = np.int32(ri[18 * w + lane])
                prim[i] = np.int32(ri[17 * w + lane])
                u[i] = r[15 * w + lane]
                v[i] = r[16 * w + lane]

    @kernel
    def _intersect_rows(fn, scene, o, d, tmax, starts, t, prim, u, v):
        """Accel.intersect's answer for one Embree scene, traced through rtcIntersect8 at
        address fn on the RTCScene at address scene, INTERSECT_PACKET consecutive rays a
        call (lanes as in _intersect_packets): rays o, d (N,3) float64, rounded to float32
        as Embree takes them; tmax (N,) float64 each ray's tmax, rounded to float32 (NaN ->
        0, above float32's max -> its max), or (0,): unbounded (float32's max); starts (G,)
        int64 each geometry's first triangle row. Writes t (N,) float64 the hit distance
        (inf: a miss), prim (N,) int64 the hit triangle's row (-1: a miss), u, v (N,)
        float64 the float32 barycentrics (0 on a miss): what embreex's run() gives and
        Accel._intersect_run turns into these arrays, without its float32 copies of the
        rays, its per-call answer arrays and the numpy passes over them (~18 ns a
        camera-path ray, docs/performance.md "fig8speed")."""
        w = INTERSECT_PACKET
        r, ri, at, valid, vat = _packet_record(w)
        none = np.uint32(0xFFFFFFFF)
        bounded = tmax.shape[0] > 0
        n = o.shape[0]
        for s in range(0, n, w):
            e = min(s + w, n)
            for lane in range(w):
                i = s + lane
                if i < e:
                    valid[lane] = -1
                    tf = _F32_MAX
                    if bounded:
                        tf = np.float32(tmax[i])
                        if tf != tf:
                            tf = np.float32(0.0)
                        elif tf > _F32_MAX:
                            tf = _F32_MAX
                    # o, d float64: rounded to float32 as they are stored
                    _set_lane(r, ri, w, lane, o[i, 0], o[i, 1], o[i, 2], d[i, 0], d[i, 1],
                              d[i, 2], tf, True)
                else:
                    valid[lane] = 0
            _call_c4(fn, vat, scene, at)
            for lane in range(e - s):
                i = s + lane
                geom = ri[18 * w + lane]
                if geom != none:
                    prim[i] = starts[geom] + np.int64(ri[17 * w + lane])
                    t[i] = np.float64(r[8 * w + lane])
                else:
                    prim[i] = -1
                    t[i] = np.inf
                u[i] = np.float64(r[15 * w + lane])
                v[i] = np.float64(r[16 * w + lane])

    @register_warm_up
    def _warm_up():
        """Compile (or load) the trace kernels (no rays: nothing is called)."""
        z3, z1 = np.zeros((0, 3), np.float32), np.zeros(0, np.float32)
        ids = np.zeros(0, np.int32)
        _intersect_packets(0, 0, z3, z3, z1, ids, ids, z1, z1)
        _occluded_packets(0, 0, z3, z3, z1, np.zeros(0, np.bool_))
        e3, e1 = np.zeros((0, 3)), np.zeros(0)
        # tmax read-only too: np.broadcast_to's view of one ray's tmax stays read-only
        # through ascontiguousarray (a one-row array is contiguous whatever its stride).
        frozen = np.zeros(0)
        frozen.flags.writeable = False
        for tmax in (e1, frozen):
            _intersect_rows(0, 0, e3, e3, tmax, np.zeros(1, np.int64), e1,
                            np.zeros(0, np.int64), e1, e1)


_UNBOUNDED = np.zeros(0)  # _intersect_rows' tmax: every ray to float32's max


def _scene_address(scene) -> int:
    """The RTCScene pointer inside an embreex EmbreeScene (_embree_library's offset)."""
    lib, offset, ctypes = _LIBRARY
    return ctypes.c_void_p.from_address(id(scene) + offset).value


_KERNEL_ADDRESSES: dict = {}  # (Embree symbol, probe) -> its address once the probe agreed, 0 if not


def _kernel_address(symbol: str, agrees) -> int:
    """The address of Embree's `symbol` when agrees(address) -> bool finds the kernel that
    calls it answering as embreex's run() on a probe, else 0 (the caller asks run()
    instead); probed once a process, any surprise counting as disagreement."""
    key = (symbol, agrees.__name__)  # one Embree function may serve two kernels
    if key not in _KERNEL_ADDRESSES:
        address = 0
        if _LIBRARY is not None and _intrinsic is not None:
            lib, _, ctypes = _LIBRARY
            try:
                fn = ctypes.cast(getattr(lib, symbol), ctypes.c_void_p).value
                address = fn if agrees(fn) else 0
            except Exception:  # noqa: BLE001 - any surprise: run()'s answer instead
                address = 0
        _KERNEL_ADDRESSES[key] = address
    return _KERNEL_ADDRESSES[key]


def _probe_rays(seed: int, n: int, short_every: int):
    """A probe: (acc, o, d, tf) a random 40-triangle Accel and n float32 rays from in and
    around it, every short_every-th stopped short (tfar 0.05), the rest unbounded."""
    rng = np.random.default_rng(seed)
    acc = Accel(rng.random((30, 3)).astype(np.float32), rng.integers(0, 30, (40, 3)))
    o = (rng.random((n, 3)) * 1.4 - 0.2).astype(np.float32)
    d = rng.normal(size=(n, 3)).astype(np.float32)
    tf = np.full(n, np.finfo(np.float32).max, np.float32)
    tf[::short_every] = 0.05
    return acc, o, d, tf


def _kernel_hits_address() -> int:
    """rtcIntersect8's address when the trace kernel (_intersect_rows) answers as
    embreex's run() on a probe (hits, misses, a ray stopped short by tmax, a last packet
    with missing lanes), else 0 (Accel.intersect then asks run())."""
    return _kernel_address("rtcIntersect8", _rows_agree)


def _rows_agree(fn) -> bool:
    acc, o, d, tf = _probe_rays(5, 8 * 32 + 5, 7)
    tmax = tf.astype(np.float64)
    want = acc._intersect_run(o, d, tmax)
    n = len(o)
    got = (np.empty(n), np.empty(n, np.int64), np.empty(n), np.empty(n))
    _intersect_rows(fn, _scene_address(acc._scene), o.astype(np.float64),
                    d.astype(np.float64), tmax, acc._blocks[0].starts, *got)
    same = all(np.array_equal(a.view(np.uint8), b.view(np.uint8)) for a, b in zip(got, want))
    return same and (want[1] >= 0).any() and (want[1] < 0).any()


def _kernel_packets_address() -> int:
    """rtcIntersect8's address when the packet kernel (_intersect_packets) answers as
    embreex's run() on a probe (hits, misses, rays stopped short by tfar, a last packet
    with missing lanes), else 0 (intersect_hits then copies run()'s answer into the
    output arrays)."""
    return _kernel_address("rtcIntersect8", _packets_agree)


def _packets_agree(fn) -> bool:
    n = 8 * 32 + 5
    acc, o, d, tf = _probe_rays(5, n, 7)
    res = acc._scene.run(o, d, dists=tf.copy(), output=True)
    want = (res["geomID"], res["primID"], res["u"], res["v"], res["tfar"])
    got = (np.empty(n, np.int32), np.empty(n, np.int32), np.empty(n, np.float32),
           np.empty(n, np.float32), tf.copy())
    _intersect_packets(fn, _scene_address(acc._scene), o, d, got[4], *got[:4])
    same = all(np.array_equal(np.asarray(a).view(np.uint8), np.asarray(b).view(np.uint8))
               for a, b in zip(got, want))
    return same and (want[0] >= 0).any() and (want[0] < 0).any()


def _kernel_occluded_address() -> int:
    """rtcOccluded8's address when the packet kernel (_occluded_packets) answers as
    embreex's run(query="OCCLUDED") on a probe (blocked and clear rays, rays stopped
    short by tfar, a last packet with missing lanes), else 0 (_occluded then asks run())."""
    return _kernel_address("rtcOccluded8", _occluded8_agrees)


def _occluded8_agrees(fn) -> bool:
    n = 8 * 64 + 5
    acc, o, d, tf = _probe_rays(6, n, 3)
    want = np.asarray(acc._scene.run(o, d, dists=tf.copy(), query="OCCLUDED")) == 0
    got = np.empty(n, np.bool_)
    _occluded_packets(fn, _scene_address(acc._scene), o, d, tf.copy(), got)
    return bool(np.array_equal(got, want) and want.any() and not want.all())


def _free_commit(scene, should_cancel, compact=False, shared=()):
    """Commit `scene` (build its BVH) with the GIL released: on a worker thread while the
    calling thread asks should_cancel() every POLL_SECONDS (raises Cancelled; the commit
    finishes in the background and the scene is dropped after it). compact: build
    Embree's compact BVH (SCENE_FLAG_COMPACT), robust as before. shared: the arrays
    Embree reads in place, kept alive until a cancelled commit has finished."""
    lib, offset, ctypes = _LIBRARY
    ptr = ctypes.c_void_p.from_address(id(scene) + offset).value
    if compact:
        lib.rtcSetSceneFlags(ptr, SCENE_FLAG_ROBUST | SCENE_FLAG_COMPACT)

    def commit(keep=(scene, shared)):  # alive until Embree is done with them
        lib.rtcCommitScene(ptr)

    if should_cancel is None:
        commit()
    else:
        # Not a daemon: the interpreter waits for a cancelled commit at exit (Embree
        # aborts the process when its threads are torn down mid-build).
        worker = threading.Thread(target=commit, name="embree-commit")
        worker.start()
        while worker.is_alive():
            worker.join(POLL_SECONDS)
            if worker.is_alive() and should_cancel():
                raise Cancelled()
    scene.is_committed = 1  # run() would commit again otherwise


# Embree 4 enums (rtcore_common.h, rtcore_geometry.h, rtcore_buffer.h).
_GEOMETRY_TRIANGLE, _BUFFER_INDEX, _BUFFER_VERTEX = 0, 0, 1
_FORMAT_UINT3, _FORMAT_FLOAT3 = 0x5003, 0x9003


def padded_vertices(vertices) -> np.ndarray:
    """vertices as a C-contiguous float32 (V,3) array that Embree may read 4 bytes past
    the end of (it loads the last vertex with a 16-byte load; rtcSetSharedGeometryBuffer):
    `vertices` itself when its buffer extends that far (engine/geometry.prepare allocates
    one spare row), else a padded copy."""
    v = np.asarray(vertices)
    if v.dtype == np.float32 and v.flags.c_contiguous and v.base is not None:
        base = v
        while isinstance(base.base, np.ndarray):
            base = base.base
        if np.byte_bounds(base)[1] - np.byte_bounds(v)[1] >= 4:
            return v
    buf = np.zeros((len(v) + 1, 3), np.float32)
    buf[:len(v)] = v
    return buf[:len(v)]


def _attach_shared(scene, vertices, faces):
    """Attach the triangles faces (n,3) uint32-compatible int32 over vertices (V,3)
    float32 (padded_vertices) to `scene` as one Embree geometry reading both arrays in
    place (no copy: the caller keeps them alive as long as the scene). Returns the geomID.
    Raises RuntimeError when Embree reports an error."""
    lib, offset, ctypes = _LIBRARY
    ptr = ctypes.c_void_p.from_address(id(scene) + offset).value
    device = lib.rtcGetSceneDevice(ptr)
    try:
        geom = lib.rtcNewGeometry(device, _GEOMETRY_TRIANGLE)
        lib.rtcSetSharedGeometryBuffer(geom, _BUFFER_VERTEX, 0, _FORMAT_FLOAT3,
                                       vertices.ctypes.data, 0, 12, len(vertices))
        lib.rtcSetSharedGeometryBuffer(geom, _BUFFER_INDEX, 0, _FORMAT_UINT3,
                                       faces.ctypes.data, 0, 12, len(faces))
        lib.rtcCommitGeometry(geom)
        gid = lib.rtcAttachGeometry(ptr, geom)
        lib.rtcReleaseGeometry(geom)
        err = lib.rtcGetDeviceError(device)
    finally:
        lib.rtcReleaseDevice(device)
    if err:
        raise RuntimeError(f"Accel: Embree refused the shared geometry (error {err})")
    return gid


class _Block:
    """One Embree scene over the triangles [start, start + count) of the whole table,
    added as pieces (embreex meshes) whose first triangles are `starts` (geomID order)."""

    __slots__ = ("scene", "starts", "shared")

    def __init__(self, scene, starts, shared=()):
        self.scene = scene
        self.starts = starts
        self.shared = shared  # arrays Embree reads in place (as long as the scene lives)


def rows_as_hits(rows: np.ndarray):
    """Triangle rows (N,) (< 0: a miss) in Accel.intersect_hits' layout: (geom, prim (N,)
    int32, starts (1,) int64), one geometry starting at row 0, so starts[geom] + prim is
    the row again and geom < 0 marks the misses."""
    ok = rows >= 0
    return (np.where(ok, 0, -1).astype(np.int32), np.where(ok, rows, 0).astype(np.int32),
            np.zeros(1, np.int64))


class Accel:
    """Closest-hit and occlusion queries over triangles `faces` (F,3) int indexing
    `vertices` (V,3) (converted to float32; shared or unshared corners). Prim ids of the
    answers index `faces`. should_cancel() is asked between the pieces of the build:
    raises engine.parallel.Cancelled when it returns True, ValueError for bad arrays.
    The Accel keeps no reference to the arrays: Embree holds its own copy (float32
    vertices and int32 indices of each piece, 6 + 12 B per triangle of a closed mesh) and
    the BVH (~60-75 B per triangle; from COMPACT_TRIANGLES on Embree's compact BVH, copy
    and BVH ~61 B in all, docs/performance.md "Memory per triangle"). `compact` tells
    which was built."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, threads: int = 1,
                 should_cancel=None):
        if _rtcs is None:
            raise RuntimeError(f"embreex is not available: {_IMPORT_ERROR}")
        vertices = np.asarray(vertices)
        faces = np.asarray(faces)
        if vertices.ndim != 2 or vertices.shape[1] != 3 or faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError("Accel: vertices must be (V,3) and faces (F,3)")
        if len(faces) and (faces.min() < 0 or faces.max() >= len(vertices)):
            raise ValueError("Accel: face index out of range")
        if not np.isfinite(vertices).all():
            raise ValueError("Accel: vertices must be finite")
        self.threads = max(1, int(threads))
        self.count = len(faces)
        # Compact only where it saves memory that matters (docs/performance.md).
        self.compact = _LIBRARY is not None and self.count >= COMPACT_TRIANGLES
        self._pool = ThreadPoolExecutor(self.threads) if self.threads > 1 else None
        self._blocks = []
        stop = should_cancel if should_cancel is not None else (lambda: False)
        one = np.zeros((1, 3), np.float32)
        block = self.count if _LIBRARY is not None else BLOCK_TRIANGLES
        shared = ()
        if _LIBRARY is not None and self.count:
            # Embree reads our float32 vertices and int32 indices in place (shared
            # buffers): no copy of ~18 B a triangle, and no GIL held while copying.
            shared = (padded_vertices(vertices), np.ascontiguousarray(faces, dtype=np.int32))
        for start in range(0, self.count, max(1, block)):
            end = min(self.count, start + block)
            scene = _rtcs.EmbreeScene(robust=True)
            starts = []
            for a in range(start, end, MESH_TRIANGLES):
                if stop():
                    raise Cancelled()
                b = min(end, a + MESH_TRIANGLES)
                if shared:
                    _attach_shared(scene, shared[0], shared[1][a:b])
                else:
                    # Only the vertices this piece uses: embreex copies the whole array.
                    used, local = np.unique(faces[a:b], return_inverse=True)
                    _TriangleMesh(scene, np.ascontiguousarray(vertices[used], dtype=np.float32),
                                  local.reshape(-1, 3).astype(np.int32))
                starts.append(a)
            if stop():
                raise Cancelled()
            # Commit the BVH now, before threads share the scene.
            if _LIBRARY is not None:
                _free_commit(scene, should_cancel, compact=self.compact, shared=shared)
            scene.run(one, np.array([[0, 0, 1]], np.float32), dists=np.ones(1, np.float32))
            self._blocks.append(_Block(scene, np.array(starts, np.int64), shared))
        # The first block's Embree scene (the whole BVH, except in the block fallback):
        # bench/ replays queries on it directly.
        self._scene = self._blocks[0].scene if self._blocks else None

    def serial(self) -> "Accel":
        """A view of the same BVH that answers on the calling thread: for work that is
        already split over threads chunk by chunk (engine/parallel.py)."""
        view = copy.copy(self)
        view.threads = 1
        view._pool = None
        return view

    def close(self, wait: bool = False):
        """Shut the query threads down; wait=True returns after they have ended."""
        if getattr(self, "_pool", None) is not None:  # None too when __init__ refused
            self._pool.shutdown(wait=wait)
            self._pool = None

    def __del__(self):
        self.close()

    @staticmethod
    def _prepare(origins, directions, tmax):
        o = np.ascontiguousarray(origins, dtype=np.float32)
        d = np.ascontiguousarray(directions, dtype=np.float32)
        if o.ndim != 2 or o.shape[1] != 3 or d.shape != o.shape:
            raise ValueError(f"Accel: origins {o.shape} and directions {d.shape} must both be (N,3)")
        n = len(o)
        if tmax is None:
            t = np.full(n, np.finfo(np.float32).max, np.float32)
        else:
            # Clipped to float32's max before the cast (the same values; no overflow warning).
            t = np.broadcast_to(np.asarray(tmax, np.float64), (n,))
            t = np.where(np.isnan(t), 0.0, np.minimum(t, np.finfo(np.float32).max)).astype(np.float32)
        return o, d, t

    def _split(self, n):
        parts = min(self.threads, max(1, n // MIN_PER_THREAD))
        return [(n * i // parts, n * (i + 1) // parts) for i in range(parts)]

    def intersect(self, origins, directions, tmax=None):
        """Closest hits. Returns (t, prim, u, v); prim = -1 where the ray misses.
        Directions should be unit length: t is in units of |direction|.
        One Embree scene: traced by a compiled kernel through rtcIntersect8 where the
        probe allows (_intersect_rows), the same arrays bit for bit as embreex's run()
        (_intersect_run, the fallback)."""
        # (_LIBRARY read here too: the scene's address comes through it.)
        fn = _kernel_hits_address() if len(self._blocks) == 1 and _LIBRARY is not None else 0
        if not fn:
            return self._intersect_run(origins, directions, tmax)
        o = np.ascontiguousarray(origins, dtype=np.float64)
        d = np.ascontiguousarray(directions, dtype=np.float64)
        if o.ndim != 2 or o.shape[1] != 3 or d.shape != o.shape:
            raise ValueError(f"Accel: origins {o.shape} and directions {d.shape} must both "
                             f"be (N,3)")
        n = len(o)
        tm = _UNBOUNDED if tmax is None else np.ascontiguousarray(
            np.broadcast_to(np.asarray(tmax, np.float64), (n,)))
        t, prim, u, v = np.empty(n), np.empty(n, np.int64), np.empty(n), np.empty(n)
        if n == 0:
            return t, prim, u, v
        block = self._blocks[0]
        scene, starts = _scene_address(block.scene), block.starts

        def work(a, b):
            _intersect_rows(fn, scene, o[a:b], d[a:b], tm[a:b] if len(tm) else tm, starts,
                            t[a:b], prim[a:b], u[a:b], v[a:b])

        self._run(work, n)
        return t, prim, u, v

    def _intersect_run(self, origins, directions, tmax=None):
        """intersect through embreex's run() (Embree scenes in blocks, or no kernel)."""
        o, d, tf = self._prepare(origins, directions, tmax)
        n = len(o)
        blocks = self._blocks
        if len(blocks) == 1:  # every row is written below
            t, prim, u, v = np.empty(n), np.empty(n, np.int64), np.empty(n), np.empty(n)
        else:
            t, prim, u, v = np.full(n, np.inf), np.full(n, -1, np.int64), np.zeros(n), np.zeros(n)
        if not blocks or n == 0:
            return t, prim, u, v

        def work(a, b):
            if len(blocks) == 1:
                # tf is this call's own copy (_prepare): Embree may write into it.
                block = blocks[0]
                res = block.scene.run(o[a:b], d[a:b], dists=tf[a:b], output=True)
                geom = res["geomID"]
                hit = geom >= 0
                pid = res["primID"]
                if len(block.starts) > 1:  # pieces: prim = first triangle + primID
                    pid = np.take(block.starts, np.where(hit, geom, 0)) + pid
                prim[a:b] = np.where(hit, pid, -1)
                t[a:b] = np.where(hit, res["tfar"], np.inf)
                u[a:b] = res["u"]
                v[a:b] = res["v"]
                return
            far = tf[a:b].copy()
            for block in blocks:
                # Each block is traced only up to the nearest hit found so far: a hit it
                # returns is nearer (an exact tie goes to the later block).
                res = block.scene.run(o[a:b], d[a:b], dists=far.copy(), output=True)
                geom = res["geomID"]
                hit = geom >= 0
                rows = np.nonzero(hit)[0]
                if not len(rows):
                    continue
                prim[a + rows] = block.starts[geom[rows]] + res["primID"][rows]
                t[a + rows] = res["tfar"][rows]
                u[a + rows] = res["u"][rows]
                v[a + rows] = res["v"][rows]
                far[rows] = res["tfar"][rows]

        self._run(work, n)
        return t, prim, u, v

    def intersect_hits(self, o32, d32, tfar32, out=None):
        """Closest hits of rays already in Embree's layout (written by a kernel), as Embree
        answers them, without intersect's conversions (np.where on the ids, float64
        copies of t, u, v: ~5 % of the photon pass): o32, d32 (N,3) C-contiguous float32,
        tfar32 (N,) float32 each ray's tmax (finite or float32 max; Embree overwrites it
        with the hit distance). Returns (geom, prim, u, v, starts): geom, prim (N,) int32,
        geom < 0 where the ray misses, else the hit triangle's row in `faces` is
        starts[geom] + prim; u, v (N,) float32 barycentrics (intersect's u, v are these
        values as float64); starts (G,) int64. out: (geom, prim, u, v) C-contiguous
        arrays of those types and (N,) shape to write the answer into (a caller's
        reused buffers), returned; traced by a compiled kernel through rtcIntersect8
        where the probe allows (_kernel_packets_address), the same values bit for bit.
        Raises ValueError on other shapes or types (embreex does not check)."""
        n = len(o32)
        for name, a, shape in (("origins", o32, (n, 3)), ("directions", d32, (n, 3)),
                               ("tfar", tfar32, (n,))):
            if a.dtype != np.float32 or a.shape != shape or not a.flags.c_contiguous:
                raise ValueError(f"Accel.intersect_hits: {name} must be C-contiguous float32 "
                                 f"{shape}, got {a.dtype} {a.shape}")
        if out is not None:
            return self._hits_into(o32, d32, tfar32, out)
        blocks = self._blocks
        if len(blocks) == 1:
            block = blocks[0]
            chunks = self._split(n)
            if self._pool is None or len(chunks) == 1:
                res = block.scene.run(o32, d32, dists=tfar32, output=True)
                return res["geomID"], res["primID"], res["u"], res["v"], block.starts
            geom, prim = np.empty(n, np.int32), np.empty(n, np.int32)
            u, v = np.empty(n, np.float32), np.empty(n, np.float32)

            def work(a, b):
                res = block.scene.run(o32[a:b], d32[a:b], dists=tfar32[a:b], output=True)
                geom[a:b], prim[a:b] = res["geomID"], res["primID"]
                u[a:b], v[a:b] = res["u"], res["v"]

            self._run(work, n)
            return geom, prim, u, v, block.starts
        # No blocks, or Embree scenes in blocks (no shared-buffer commit): intersect's
        # answer in this layout (its u, v are float32 values, so the same bits).
        _, hit, u, v = self.intersect(o32, d32, tfar32)
        geom, prim, starts = rows_as_hits(hit)
        return geom, prim, u.astype(np.float32), v.astype(np.float32), starts

    def _hits_into(self, o32, d32, tfar32, out):
        """intersect_hits(o32, d32, tfar32, out) (shapes of the rays checked)."""
        n = len(o32)
        geom, prim, u, v = out
        for name, a, dtype in (("geom", geom, np.int32), ("prim", prim, np.int32),
                               ("u", u, np.float32), ("v", v, np.float32)):
            if a.dtype != dtype or a.shape != (n,) or not a.flags.c_contiguous:
                raise ValueError(f"Accel.intersect_hits: out {name} must be C-contiguous "
                                 f"{np.dtype(dtype)} ({n},), got {a.dtype} {a.shape}")
        fn = _kernel_packets_address() if len(self._blocks) == 1 else 0
        if not fn:
            answer = self.intersect_hits(o32, d32, tfar32)
            for dst, src in zip(out, answer):
                dst[:] = src
            return (*out, answer[4])
        block = self._blocks[0]
        scene = _scene_address(block.scene)

        def work(a, b):
            _intersect_packets(fn, scene, o32[a:b], d32[a:b], tfar32[a:b], geom[a:b],
                               prim[a:b], u[a:b], v[a:b])

        self._run(work, n)
        return (*out, block.starts)

    def occluded(self, origins, directions, tmax=None) -> np.ndarray:
        """True where something lies between the origin and distance tmax."""
        o, d, tf = self._prepare(origins, directions, tmax)
        n = len(o)
        out = np.zeros(n, bool)
        if not self._blocks or n == 0:
            return out

        def work(a, b):
            out[a:b] = self._occluded(o[a:b], d[a:b], tf[a:b])  # tf: this call's own

        self._run(work, n)
        return out

    def _occluded(self, o, d, tf):
        """(N,) bool blocked, block after block for the rays still clear. tf is overwritten."""
        # OCCLUDED must be called without output (docs/design.md, Embree (embreex)
        # facts): 0 = blocked, -1 = clear.
        if len(self._blocks) == 1:
            return self._occluded_block(self._blocks[0], o, d, tf)
        blocked = np.zeros(len(o), bool)
        rows = np.arange(len(o))
        for block in self._blocks:
            hit = self._occluded_block(block, np.ascontiguousarray(o[rows]),
                                       np.ascontiguousarray(d[rows]), tf[rows])
            blocked[rows[hit]] = True
            rows = rows[~hit]
            if not len(rows):
                break
        return blocked

    @staticmethod
    def _occluded_block(block, o, d, tf):
        """(N,) bool blocked by one block's scene: o, d (N,3), tf (N,) C-contiguous
        float32 (tf may be overwritten). Traced in packets by _occluded_packets where the
        probe allows (the same answers as run(), which is the fallback)."""
        fn = _kernel_occluded_address() if _LIBRARY is not None else 0
        if fn and o.flags.c_contiguous and d.flags.c_contiguous:
            blocked = np.empty(len(o), np.bool_)
            _occluded_packets(fn, _scene_address(block.scene), o, d,
                              np.ascontiguousarray(tf), blocked)
            return blocked
        return np.asarray(block.scene.run(o, d, dists=tf, query="OCCLUDED")) == 0

    def occluded_into(self, o32, d32, tmax32, blocked) -> np.ndarray:
        """Accel.occluded for rays already in Embree's layout, written by a kernel: o32,
        d32 (N,3) and tmax32 (N,) C-contiguous float32 (tmax finite, >= 0; Embree
        overwrites it), blocked (N,) bool receives the answer (and is returned). Raises
        ValueError on other shapes or types (embreex does not check: a short array crashes
        the process)."""
        n = len(o32)
        for name, a, shape in (("origins", o32, (n, 3)), ("directions", d32, (n, 3)),
                               ("tmax", tmax32, (n,))):
            if a.dtype != np.float32 or a.shape != shape or not a.flags.c_contiguous:
                raise ValueError(f"Accel.occluded_into: {name} must be C-contiguous float32 "
                                 f"{shape}, got {a.dtype} {a.shape}")
        if blocked.dtype != np.bool_ or blocked.shape != (n,):
            raise ValueError(f"Accel.occluded_into: blocked must be bool ({n},), got "
                             f"{blocked.dtype} {blocked.shape}")
        if not self._blocks or n == 0:
            blocked[:] = False
            return blocked

        def work(a, b):
            blocked[a:b] = self._occluded(o32[a:b], d32[a:b], tmax32[a:b])

        self._run(work, n)
        return blocked

    def _run(self, work, n):
        chunks = self._split(n)
        if self._pool is None or len(chunks) == 1:
            for a, b in chunks:
                work(a, b)
        else:
            list(self._pool.map(lambda ab: work(*ab), chunks))
