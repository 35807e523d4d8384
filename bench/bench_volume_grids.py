"""What reading a Volume object's grids costs (addon/volumegrids.py, vdb41): the
temporary Geometry Nodes sampler at the voxel centres, for Mesh to Volume spheres of
growing voxel counts (one "density" grid), and the memory the lattice takes.

    .venv/bin/python bench/bench_volume_grids.py [--sizes 32,64,128,256]

Prints one row per size: the lattice's points, the sampling's wall time (scene, mesh,
node group made, evaluated, read and removed), the grid's MiB in the engine (float32).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.join(ROOT, "example_blends"))


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", default="32,64,128,256",
                   help="voxels across the sphere's diameter, comma-separated")
    args = p.parse_args(argv)
    import bpy

    import make_blends as mb
    from addon import volumegrids
    print(f"{'voxels across':>13} {'lattice points':>15} {'sample s':>9} {'MiB':>7}")
    for n in [int(x) for x in args.sizes.split(",")]:
        mb.reset()
        src = mb.sphere("src", 1.0, None, (0, 0, 0), segments=32, rings=16)
        vo = mb.mesh_to_volume("vol", src, 2.0 / n)
        dg = bpy.context.evaluated_depsgraph_get()
        ve = vo.evaluated_get(dg)
        grids = volumegrids.object_grids(ve)
        scene = bpy.context.scene
        t = time.perf_counter()
        values, _, _, stride, counts, _ = volumegrids.sample_grids(
            bpy, ve, {"density": grids["density"]}, (scene.frame_current, 0.0))
        dt = time.perf_counter() - t
        v = values["density"]
        print(f"{n:>13} {v.size:>15} {dt:>9.2f} {v.nbytes / 2 ** 20:>7.1f}"
              + (f"  (stride {stride})" if stride > 1 else ""))


if __name__ == "__main__":
    main()
