"""A point lamp in a narrow gap against Cycles (issue 13; docs/accuracy.md "night43",
"radius44"): bench/bench_night_room.py's night room at 48 x 36 lit by its 40 W point
lamp alone, 7 cm from the wall in the 15 cm gap behind the sofa (the rest of the room
lit only indirectly). Most of the lamp's photons pile up in the gap. The global search
radius taken from the stored photons' own spacing (auto_radius, the rule before
radius44: 0.012 m here) capped the room's estimates at discs holding a photon or two and
read the image 1.095 of Cycles (seed 0: 0.02178 against 0.01988); measured at the gather
rays' ends (render.lookup_radius: 0.33 m) it reads within 2 %.

Cycles' image mean (8192 spp, seed 0: the same number every run) is stored in
tests/references/night_room_cycles.json (this file run as a script writes it); the slow
test_stored_night_room_mean_is_cycles_now renders it again live.
"""
import os
import sys

import numpy as np
import pytest

pytestmark = pytest.mark.blender

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
REF_PATH = os.path.join(os.path.dirname(HERE), "references", "night_room_cycles.json")
SIZE = (48, 36)
CYCLES_SPP = 8192
OUR_SPP = 16
OUR_PHOTONS = 400_000  # (the default)
OUR_SEEDS = 4


def _scene(bpy):
    """The night room (bench_night_room.build_night_room, a new scene at SIZE) with its
    point lamp alone; our settings at their defaults but the samples."""
    from blender_helpers import default_photonmap
    sys.path.insert(0, os.path.join(ROOT, "bench"))
    import bench_night_room
    scene = bench_night_room.build_night_room(bpy, res=SIZE)
    for o in list(bpy.data.objects):
        if o.type == "LIGHT" and o.data.type != "POINT":
            bpy.data.objects.remove(o, do_unlink=True)
    assert [o.name for o in bpy.data.objects if o.type == "LIGHT"] == ["Point"]
    pm = default_photonmap(scene)
    pm.spp, pm.photons = OUR_SPP, OUR_PHOTONS
    return scene


def _mean(bpy, scene, path, engine):
    """The image mean (RGB mean over the pixels) of scene rendered by `engine`."""
    from blender_helpers import read_rgba, render_exr
    scene.render.engine = engine
    if engine == "CYCLES":
        scene.cycles.samples = CYCLES_SPP
    return float(read_rgba(bpy, render_exr(bpy, scene, path))[..., :3].mean())


def _cycles_means(bpy, tmp_path):
    return {"image": _mean(bpy, _scene(bpy), tmp_path / "cycles.exr", "CYCLES")}


def test_point_lamp_in_a_narrow_gap_matches_cycles(bpy_addon, tmp_path):
    """Ours (16 spp, 400k photons; seeds 0-3 averaged, ~20 CPU s) within 4 % of Cycles'
    stored mean. The photons' spacing as the radius read 1.095 and 1.084 (seeds 0 and 1;
    at 80 x 60, 64 spp, 1.084 too: docs/accuracy.md "radius43").

    One render spreads over seeds 0-11 as 0.988-1.032, mean 1.006, sd 0.013 (the 2 %
    bound of one seed before flaky50 was 1.1 sd past the mean); neither 64 spp (sd 0.010)
    nor 1.6M photons (sd 0.014) narrows it much, so four seeds are averaged (sd ~0.007):
    4 % is 5 sd past the mean and 1.084 is still 6 sd beyond it (`pytest -s
    tests/blender/seed_sweeps.py -k night`; docs/accuracy.md, "flaky50")."""
    from blender_helpers import stored_cycles_means
    scene = _scene(bpy_addon)
    each = []
    for seed in range(OUR_SEEDS):
        scene.photonmap.seed = seed
        each.append(_mean(bpy_addon, scene, tmp_path / f"ours{seed}.exr", "PHOTONMAP"))
    ours = sum(each) / len(each)
    cycles = stored_cycles_means(REF_PATH)["image"]
    print(f"night room, point lamp alone: ours {ours:.5f} / Cycles {cycles:.5f} = "
          f"{ours / cycles:.4f} (per seed {', '.join(f'{m / cycles:.4f}' for m in each)})")
    assert abs(ours / cycles - 1.0) < 0.04, (ours, cycles)


@pytest.mark.slow
def test_stored_night_room_mean_is_cycles_now(bpy_addon, tmp_path):
    """The stored mean is what this Blender's Cycles renders (8192 spp, ~70 CPU s)."""
    from blender_helpers import assert_stored_means_are_now, stored_cycles_means
    assert_stored_means_are_now(stored_cycles_means(REF_PATH),
                                _cycles_means(bpy_addon, tmp_path))


if __name__ == "__main__":  # write the stored mean: .venv/bin/python <this file>
    sys.path.insert(0, HERE)
    from blender_helpers import store_cycles_means
    store_cycles_means(REF_PATH, _cycles_means, cycles_samples=CYCLES_SPP, seed=0,
                       scene="bench/bench_night_room.py night room, point lamp alone",
                       size=list(SIZE))
