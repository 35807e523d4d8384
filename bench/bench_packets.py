"""Closest-hit queries one ray at a time against Embree's ray packets, on a render's rays.

Renders an example blend (default settings, 1 worker) and, at every call of the engine's
two closest-hit kernels, traces the same rays again through kernels built here for each
packet width: rtcIntersect1 one ray at a time, rtcIntersect4 / 8 / 16 on consecutive
rays. Prints ns a ray per caller (the final gather's rays, the photon pass's rays, the
camera paths' rays) and whether every width gives the same answers bit for bit; the
engine's own kernels are what this table chose (engine/accel.py, INTERSECT_PACKET).

    PYTHONPATH=$PWD .venv/bin/python bench/bench_packets.py [--blend figure6_box]
        [--width 160 --height 120]

Thread CPU time of each call (time.thread_time_ns), so other jobs on the machine count
little; the widths run back to back on the same rays, in the same order each call.
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from llvmlite import ir  # noqa: E402
from numba import njit, types  # noqa: E402
from numba.extending import intrinsic  # noqa: E402

from engine import accel  # noqa: E402
from engine.jit import ensure_compiled  # noqa: E402

WIDTHS = (1, 4, 8, 16)


@intrinsic
def _call_c3(typingctx, fn, a, b):
    """fn(a, b, NULL) for the C function at address fn: rtcIntersect1 (scene, rayhit,
    args), which the engine no longer calls (accel._call_c4 calls the packet functions)."""
    sig = types.void(types.intp, types.intp, types.intp)

    def codegen(context, builder, signature, args):
        f, x, y = args
        vp = ir.IntType(8).as_pointer()
        fnty = ir.FunctionType(ir.VoidType(), [vp, vp, vp])
        builder.call(builder.inttoptr(f, fnty.as_pointer()),
                     [builder.inttoptr(x, vp), builder.inttoptr(y, vp), ir.Constant(vp, None)])
        return context.get_dummy_value()
    return sig, codegen


def _packet_kernel(w: int):
    """A closest-hit kernel of w lanes (rtcIntersect{w}; w = 1: RTCRayHit one ray at a
    time, the same record with lanes of one), answering as accel._intersect_packets
    does, on the engine's packet record (accel._packet_record, _fill_packet)."""
    call = accel._call_c4 if w > 1 else _call_c3
    lanes = w

    @njit(nogil=True)
    def trace(fn, scene, o32, d32, tfar32, geom, prim, u, v):
        r, ri, at, valid, vat = accel._packet_record(lanes)
        n = o32.shape[0]
        for s in range(0, n, lanes):
            e = accel._fill_packet(r, ri, valid, lanes, s, o32, d32, tfar32, True)
            if lanes == 1:
                call(fn, scene, at)
            else:
                call(fn, vat, scene, at)
            for lane in range(e - s):
                i = s + lane
                tfar32[i] = r[8 * lanes + lane]
                geom[i] = np.int32(ri[18 * lanes + lane])
                prim[i] = np.int32(ri[17 * lanes + lane])
                u[i] = r[15 * lanes + lane]
                v[i] = r[16 * lanes + lane]
    return trace


def _caller():
    """The engine function (file:name) whose rays these are."""
    fr = sys._getframe(2)
    skip = ("accel.py", "parallel.py", "bench_packets.py", "threading.py")
    while fr is not None and os.path.basename(fr.f_code.co_filename) in skip:
        fr = fr.f_back
    return f"{os.path.basename(fr.f_code.co_filename)}:{fr.f_code.co_name}" if fr else "?"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blend", default="figure6_box")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    args = ap.parse_args(argv)
    ensure_compiled()
    if accel._LIBRARY is None:
        sys.exit("bench_packets: Embree's library is not reachable from kernels here")
    lib, _, ctypes = accel._LIBRARY
    kernels = {w: (_packet_kernel(w), ctypes.cast(getattr(lib, f"rtcIntersect{w}"),
                                                  ctypes.c_void_p).value) for w in WIDTHS}
    z3, z1, zi = np.zeros((0, 3), np.float32), np.zeros(0, np.float32), np.zeros(0, np.int32)
    for k, _ in kernels.values():
        k(0, 0, z3, z3, z1, zi, zi, z1, z1)
    table: dict = {}
    mismatches = [0]

    def measure(scene, o32, d32, tfar32, caller):
        row = table.setdefault(caller, {"rays": 0, **{w: 0 for w in WIDTHS}})
        row["rays"] += len(o32)
        answers = []
        for w, (k, fn) in kernels.items():
            tf = tfar32.copy()
            out = (np.empty(len(o32), np.int32), np.empty(len(o32), np.int32),
                   np.empty(len(o32), np.float32), np.empty(len(o32), np.float32))
            t0 = time.thread_time_ns()
            k(fn, scene, o32, d32, tf, *out)
            row[w] += time.thread_time_ns() - t0
            answers.append([a.view(np.uint8) for a in (tf, *out)])
        mismatches[0] += sum(any(not np.array_equal(a, b) for a, b in zip(answers[0], x))
                             for x in answers[1:])

    packets, rows = accel._intersect_packets, accel._intersect_rows

    def traced_packets(fn, scene, o32, d32, tfar32, geom, prim, u, v):
        measure(scene, o32, d32, tfar32.copy(), _caller())
        packets(fn, scene, o32, d32, tfar32, geom, prim, u, v)

    def traced_rows(fn, scene, o, d, tmax, starts, t, prim, u, v):
        tf = np.full(len(o), accel._F32_MAX, np.float32) if not len(tmax) else \
            np.nan_to_num(tmax.astype(np.float32), nan=0.0, posinf=accel._F32_MAX)
        measure(scene, o.astype(np.float32), d.astype(np.float32), tf, _caller())
        rows(fn, scene, o, d, tmax, starts, t, prim, u, v)

    accel._intersect_packets, accel._intersect_rows = traced_packets, traced_rows
    import pickle
    import tempfile

    from engine.render import render
    from engine.settings import RenderSettings
    sys.path.insert(0, os.path.join(ROOT, "bench"))
    from bench_kernels import exported
    where = os.path.join(tempfile.gettempdir(), "bench_packets")
    os.makedirs(where, exist_ok=True)
    with open(exported(args.blend, where), "rb") as f:
        scene = pickle.load(f)
    scene.width, scene.height = args.width, args.height
    render(scene, RenderSettings(workers=1))
    print(f"{args.blend} {args.width}x{args.height}, default settings, 1 worker: ns a ray "
          f"(thread CPU) by packet width")
    print("| caller | rays | " + " | ".join(f"{w} lane{'s' if w > 1 else ''}" for w in WIDTHS)
          + " |")
    print("|---|---:|" + "---:|" * len(WIDTHS))
    for caller, row in sorted(table.items(), key=lambda kv: -kv[1]["rays"]):
        n = max(row["rays"], 1)
        print(f"| {caller} | {row['rays']:,} | "
              + " | ".join(f"{row[w] / n:.1f}" for w in WIDTHS) + " |")
    print(f"answers differing from one ray at a time: {mismatches[0]} calls")


if __name__ == "__main__":
    main()
