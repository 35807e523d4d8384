"""Embree's curve primitives against the triangle tubes hair renders as: the cost of a ray
(docs/performance.md, hair39).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_hair_curves.py [--strands 3000] [--rays 400000]

The groom of bench/bench_hair.py (newuser38's: `--strands` strands of 4 keys, radius 8 ->
3 mm, on a 0.8 m sphere; the strands alone here) built five ways in Embree 4 (the library
embreex loads, through its C API as engine/accel.py reaches it): the engine's tubes
(engine/hair.py tube_mesh: 8 sides, 2 pieces a key interval, in engine.accel.Accel as a
render builds them), the same triangles in a plain robust scene, round and flat linear
curves through the tubes' spline points (6 segments a strand), and round and flat
Catmull-Rom curves through the keys (3 segments a strand: what Cycles builds,
RTC_GEOMETRY_TYPE_ROUND / FLAT_CATMULL_ROM_CURVE). Rays traced by the engine's own packet
kernels (accel._intersect_packets, _occluded_packets: rtcIntersect8 / rtcOccluded8), one
thread, CPU ns a ray (best of 3): "camera" rays from the camera of bench_hair.py to random
points of the groom's box, "scattered" rays from random points in the box in random
directions (a gather or shadow ray among strands). Also the primitives, the BVH's build
time and the share of rays that hit (the shapes' coverage agrees within a few %).
Curves give no triangles to shade: the engine would need a curve hit's surface (position,
normal across the strand, u along it) in bsdf.surface_hit, its photons and its lookups;
this measures what the ray itself would cost.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from engine import accel  # noqa: E402
from engine.hair import catmull_rom, tube_mesh  # noqa: E402

# rtcore_geometry.h / rtcore_common.h (Embree 4)
TRIANGLE, ROUND_LINEAR, FLAT_LINEAR = 0, 16, 17
ROUND_CATMULL_ROM, FLAT_CATMULL_ROM = 58, 59
BUFFER_INDEX, BUFFER_VERTEX = 0, 1
FORMAT_UINT, FORMAT_UINT3, FORMAT_FLOAT3, FORMAT_FLOAT4 = 0x5001, 0x5003, 0x9003, 0x9004
SCENE_ROBUST = 4


def groom(n, keys=4, seed=1):
    """bench_hair.py's strands: (keys (n, keys, 3), radii (n, keys))."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    s = np.linspace(0, 1, keys)
    pos = (np.array([0, 0, 1.0]) + d[:, None] * (0.8 + 0.35 * s[None, :, None])
           + np.array([0, 0, -0.15]) * (s * s)[None, :, None])
    return pos, np.tile(np.linspace(0.008, 0.003, keys), (n, 1))


class EmbreeScene:
    """A robust Embree scene of one geometry built through the C API; address: its
    RTCScene pointer for the packet kernels. Keeps its buffers alive (shared, not
    copied: Embree reads past the last element, so each has a padding row)."""

    def __init__(self, gtype, index, index_format, index_size, vertex, vertex_format):
        lib, _, ct = accel._LIBRARY
        vp = ct.c_void_p
        for name, args, res in (("rtcNewScene", [vp], vp), ("rtcReleaseScene", [vp], None)):
            getattr(lib, name).argtypes, getattr(lib, name).restype = args, res
        self.lib = lib
        self._probe = accel.Accel(np.eye(3, dtype=np.float32), np.array([[0, 1, 2]]))
        device = lib.rtcGetSceneDevice(accel._scene_address(self._probe._scene))
        self.index = np.ascontiguousarray(np.r_[index.reshape(-1), np.zeros(4)], np.uint32)
        self.vertex = np.ascontiguousarray(np.r_[vertex, np.zeros((1, vertex.shape[1]))],
                                           np.float32)
        t0 = time.perf_counter()
        self.address = lib.rtcNewScene(device)
        lib.rtcSetSceneFlags(self.address, SCENE_ROBUST)
        geom = lib.rtcNewGeometry(device, gtype)
        count = len(index)
        lib.rtcSetSharedGeometryBuffer(geom, BUFFER_INDEX, 0, index_format,
                                       self.index.ctypes.data, 0, 4 * index_size, count)
        lib.rtcSetSharedGeometryBuffer(geom, BUFFER_VERTEX, 0, vertex_format,
                                       self.vertex.ctypes.data, 0, 4 * vertex.shape[1],
                                       len(vertex))
        lib.rtcCommitGeometry(geom)
        lib.rtcAttachGeometry(self.address, geom)
        lib.rtcReleaseGeometry(geom)
        lib.rtcCommitScene(self.address)
        self.build_s = time.perf_counter() - t0
        if lib.rtcGetDeviceError(device):
            raise RuntimeError("Embree reported an error building the scene")
        self.primitives = count

    def close(self):
        self.lib.rtcReleaseScene(self.address)


def scenes(pos, rad):
    """(name, scene address, primitives, build s, keep-alive) for each shape."""
    n, keys, _ = pos.shape
    offsets = np.arange(n + 1) * keys
    v, f, _, _ = tube_mesh(pos.reshape(-1, 3), rad.reshape(-1), offsets)
    t0 = time.perf_counter()
    acc = accel.Accel(v.astype(np.float32), f)
    build = time.perf_counter() - t0
    out = [("tubes, engine's Accel", accel._scene_address(acc._scene), len(f), build, acc)]
    tri = EmbreeScene(TRIANGLE, f, FORMAT_UINT3, 3, v, FORMAT_FLOAT3)
    out.append(("tubes, plain robust scene", tri.address, len(f), tri.build_s, tri))
    # Linear curves through the tubes' own spline points (the rings' centres).
    pts, _, _ = catmull_rom(pos, 2)
    m = pts.shape[1]
    # The radius along the spline: the keys' radii linear in the parameter.
    rs = np.interp(np.linspace(0, keys - 1, m), np.arange(keys), rad[0])
    lin_v = np.concatenate([pts, np.broadcast_to(rs, (n, m))[..., None]], axis=2).reshape(-1, 4)
    lin_i = (np.arange(n)[:, None] * m + np.arange(m - 1)[None, :]).reshape(-1)
    for name, gtype in (("round linear curves", ROUND_LINEAR),
                        ("flat linear curves (ribbons)", FLAT_LINEAR)):
        s = EmbreeScene(gtype, lin_i, FORMAT_UINT, 1, lin_v, FORMAT_FLOAT4)
        out.append((name, s.address, s.primitives, s.build_s, s))
    # Catmull-Rom through the keys, the end keys repeated as their own neighbours.
    cr = np.concatenate([pos[:, :1], pos, pos[:, -1:]], axis=1)
    cr_r = np.concatenate([rad[:, :1], rad, rad[:, -1:]], axis=1)
    cr_v = np.concatenate([cr, cr_r[..., None]], axis=2).reshape(-1, 4)
    k2 = keys + 2
    cr_i = (np.arange(n)[:, None] * k2 + np.arange(keys - 1)[None, :]).reshape(-1)
    for name, gtype in (("round Catmull-Rom curves", ROUND_CATMULL_ROM),
                        ("flat Catmull-Rom curves (Cycles' Ribbons)", FLAT_CATMULL_ROM)):
        s = EmbreeScene(gtype, cr_i, FORMAT_UINT, 1, cr_v, FORMAT_FLOAT4)
        out.append((name, s.address, s.primitives, s.build_s, s))
    return out


def rays(pos, n, seed=2):
    """{kind: (o32, d32)}: camera rays and scattered rays in the groom's box."""
    rng = np.random.default_rng(seed)
    lo, hi = pos.reshape(-1, 3).min(axis=0), pos.reshape(-1, 3).max(axis=0)
    target = lo + (hi - lo) * rng.random((n, 3))
    cam = np.array([0.0, -4.5, 1.6])
    d = target - cam
    o2 = lo + (hi - lo) * rng.random((n, 3))
    d2 = rng.normal(size=(n, 3))
    f = np.float32
    return {"camera": (np.broadcast_to(cam, (n, 3)).astype(f),
                       (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(f)),
            "scattered": (o2.astype(f),
                          (d2 / np.linalg.norm(d2, axis=1, keepdims=True)).astype(f))}


def cpu_ns(fn, n, repeat=3):
    best = 1e30
    for _ in range(repeat):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best / n * 1e9


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--strands", type=int, default=3000)
    ap.add_argument("--rays", type=int, default=400_000)
    args = ap.parse_args()
    if accel._LIBRARY is None:
        sys.exit("Embree's C library is not reachable through embreex here")
    fi, fo = accel._kernel_packets_address(), accel._kernel_occluded_address()
    pos, rad = groom(args.strands)
    built = scenes(pos, rad)
    todo = rays(pos, args.rays)
    n = args.rays
    print(f"\n{args.strands} strands, {n} rays a kind, 1 thread, CPU ns a ray (best of 3)\n")
    print("| shape | primitives | build s | camera: closest / occluded ns, hit | "
          "scattered: closest / occluded ns, hit |")
    print("|---|---:|---:|---|---|")
    for name, address, prims, build, _ in built:
        cells = []
        for kind, (o32, d32) in todo.items():
            geom = np.empty(n, np.int32)
            prim = np.empty(n, np.int32)
            u = np.empty(n, np.float32)
            v = np.empty(n, np.float32)
            inf = np.full(n, np.finfo(np.float32).max, np.float32)
            blocked = np.empty(n, np.bool_)
            ti = cpu_ns(lambda: accel._intersect_packets(fi, address, o32, d32, inf.copy(),
                                                         geom, prim, u, v), n)
            to = cpu_ns(lambda: accel._occluded_packets(fo, address, o32, d32, inf, blocked),
                        n)
            cells.append(f"{ti:.0f} / {to:.0f}, {np.mean(geom >= 0):.3f}")
        print(f"| {name} | {prims} | {build:.2f} | {cells[0]} | {cells[1]} |", flush=True)


if __name__ == "__main__":
    main()
