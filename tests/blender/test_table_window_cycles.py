"""newuser44's table by a window (bench/newuser44_table.py) against stored Cycles means
(issue 14; docs/accuracy.md "tableroom45").

Cycles' default Filter Glossy 1 widens the Principled floor's, table's and mug's specular
lobes after a diffuse bounce and dims the sun's glow they throw onto the walls by 1.2-1.9 %
(Cycles' own FG 1 / FG 0). Ours renders the scene's Filter Glossy too (the add-on passes
it: engine/glossysplit.py, docs/compatibility.md "fgsplit46"), so each side renders at
the scene's default, 1. The stored means are Cycles 1024 spp, clamping off in both,
160 x 120 (per object, Rec. 709 luminance over the pixels whose centre sees it), made by
the bench's build with `--no-clamp` at `scene.cycles.blur_glossy` 0 and 1. Ours at 16 spp
(~20 CPU s).
"""
import os
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "bench"))

pytestmark = [pytest.mark.blender, pytest.mark.slow]

LUM = np.array([0.2126, 0.7152, 0.0722])
# Cycles 1024 spp, clamp off, at its default Filter Glossy 1 (at 0, 1.2-1.9 % higher:
# back wall 0.5464, right wall c 0.4360, floor 0.1567, curtain 1.5964).
CYCLES_FG1 = {"BackWall": 0.5398, "RightWall_c": 0.4277, "Floor": 0.1548, "Curtain": 1.5876}


def test_window_lit_walls_match_cycles_at_the_scenes_filter_glossy(bpy_addon, tmp_path):
    bpy = bpy_addon
    import newuser44_table as T
    from newuser26_compare import read_exr
    from newuser26_scenes import object_masks
    scene = T.table_scene("sky")
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = 160, 120, 100
    ids, names = object_masks(scene, 160, 120)
    c = scene.cycles
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    # (each side at the scene's Filter Glossy, Cycles' default: ours reads it)
    assert c.blur_glossy == 1.0
    r.engine = "PHOTONMAP"
    scene.photonmap.spp = 16
    fmt = r.image_settings
    fmt.media_type = "IMAGE"
    fmt.file_format, fmt.color_depth = "OPEN_EXR", "32"
    r.filepath, r.use_file_extension = str(tmp_path / "ours.exr"), False
    bpy.ops.render.render(write_still=True)
    img = read_exr(str(tmp_path / "ours.exr"))
    for name, ref in CYCLES_FG1.items():
        m = ids == names.index(name)
        ratio = float((img[m] @ LUM).mean()) / ref
        print(name, round(ratio, 4))
        # 128 spp, seeds 0 / 1: 0.995-1.003 on these; 16 spp adds its own noise.
        assert abs(ratio - 1.0) < 0.02, (name, ratio)
