"""What one camera-pass thread holds at its peak (slices52, docs/performance.md "slices52"):
the engine alone renders an exported example blend on one worker (its chunks on the
calling thread, glibc's main arena), a thread samples the C heap's bytes in use
(mallinfo2: uordblks + hblkhd, numpy's arrays and the compiled kernels' alike) every
1 ms during the camera pass, and keeps the highest, the chunk it came in and where the
render thread was then. Afterwards it lists the arrays the thread keeps between its chunks
(integrator.BounceBuffers, GatherBuffers, directlight.DirectLightBuffers,
photonvisibility's read lists), class by class and the largest of each. Prints tables;
CPU s is the render's process time.

    PYTHONPATH=$PWD .venv/bin/python bench/slices52_peak.py [--blend figure6_box]
        [--size 160x120] [--spp 128]

The blend is exported once through the add-on by a child Blender (bpy) process into
$TMPDIR/film_hashes/ (bench/bench_kernels.exported, as tools/film_hashes.py does).
The sampling is coarse: a peak between two samples is missed, so repeated runs differ
by a few MB.
"""
import argparse
import ctypes
import os
import pickle
import sys
import tempfile
import threading
import time
import traceback

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "bench"))

import numpy as np  # noqa: E402

from bench_kernels import exported  # noqa: E402

MB = 1 << 20


class _MallInfo2(ctypes.Structure):
    _fields_ = [(name, ctypes.c_size_t) for name in (
        "arena", "ordblks", "smblks", "hblks", "hblkhd", "usmblks", "fsmblks", "uordblks",
        "fordblks", "keepcost")]


def heap_in_use(libc) -> int:
    """Bytes the process's malloc has handed out and not got back (every arena)."""
    m = libc.mallinfo2()
    return m.uordblks + m.hblkhd


def kept_arrays(instances, read_lists):
    """{class name: bytes} of the ndarray attributes of the buffer objects `instances`,
    plus the read lists; and the largest arrays as (class.attr, shape, dtype, bytes)."""
    total, largest = {}, []
    for obj in instances:
        name = type(obj).__name__
        for attr, value in vars(obj).items():
            if isinstance(value, np.ndarray):
                total[name] = total.get(name, 0) + value.nbytes
                largest.append((f"{name}.{attr}", value.shape, value.dtype, value.nbytes))
    if read_lists is not None:
        total["read lists"] = sum(a.nbytes for a in read_lists)
        for label, a in zip(("ids", "weights"), read_lists):
            largest.append((f"read lists.{label}", a.shape, a.dtype, a.nbytes))
    largest.sort(key=lambda row: -row[3])
    return total, largest


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--blend", default="figure6_box")
    ap.add_argument("--size", default="160x120", help="WIDTHxHEIGHT")
    ap.add_argument("--spp", type=int, default=128)
    args = ap.parse_args(argv)
    width, height = (int(v) for v in args.size.lower().split("x"))

    from engine.jit import ensure_compiled
    from engine.render import render
    from engine.settings import RenderSettings
    import engine.directlight as directlight
    import engine.integrator as integrator
    import engine.photonvisibility as photonvisibility
    ensure_compiled()
    with open(exported(args.blend, os.path.join(tempfile.gettempdir(), "film_hashes")),
              "rb") as f:
        scene = pickle.load(f)
    scene.width, scene.height = width, height

    libc = ctypes.CDLL("libc.so.6")
    libc.mallinfo2.restype = _MallInfo2
    render_thread = threading.get_ident()
    state = {"on": False, "chunk": None, "start": 0, "peak": 0, "at": None, "where": ""}
    instances = []
    for cls in (integrator.BounceBuffers, integrator.GatherBuffers,
                directlight.DirectLightBuffers):
        def counted(init, cls=cls):
            def __init__(self, *a, **k):
                init(self, *a, **k)
                instances.append(self)
            return __init__
        cls.__init__ = counted(cls.__init__)

    def sample():
        while True:
            if state["on"]:
                used = heap_in_use(libc)
                if used > state["peak"]:
                    frame = sys._current_frames().get(render_thread)
                    state.update(peak=used, at=state["chunk"], where="".join(
                        traceback.format_stack(frame, limit=14)[-7:]) if frame else "")
            time.sleep(0.001)
    threading.Thread(target=sample, daemon=True).start()

    render_chunk = integrator._render_chunk

    def chunk(ctx, region, ci, *a, **k):
        state["chunk"] = ci
        return render_chunk(ctx, region, ci, *a, **k)
    integrator._render_chunk = chunk
    render_camera = integrator.render_camera

    def camera(*a, **k):
        state.update(start=heap_in_use(libc), peak=0, on=True)
        try:
            return render_camera(*a, **k)
        finally:
            state["on"] = False
    integrator.render_camera = camera
    sys.modules["engine.render"].render_camera = camera

    t = time.process_time()
    render(scene, RenderSettings(workers=1, spp=args.spp))
    cpu = time.process_time() - t

    total, largest = kept_arrays(instances, getattr(photonvisibility._READ_BUFFERS,
                                                    "arrays", None))
    print(f"\n{args.blend} {width} x {height}, {args.spp} spp, 1 worker: CPU {cpu:.1f} s\n")
    print("| camera pass, heap in use | MB |")
    print("|---|---:|")
    print(f"| at its start (scene, maps, BVH) | {state['start'] / MB:.0f} |")
    print(f"| its peak, above the start (chunk {state['at']}) | "
          f"{(state['peak'] - state['start']) / MB:.0f} |")
    for name, size in sorted(total.items(), key=lambda kv: -kv[1]):
        print(f"| of which kept by the thread: {name} | {size / MB:.1f} |")
    print("\n| largest kept arrays | shape | dtype | MB |")
    print("|---|---|---|---:|")
    for label, shape, dtype, size in largest[:12]:
        print(f"| {label} | {shape} | {dtype} | {size / MB:.1f} |")
    print("\nwhere the render thread was at the peak:\n" + state["where"])


if __name__ == "__main__":
    main()
