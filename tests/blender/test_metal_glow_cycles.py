"""Light off a rough metal onto the floor beside it against Cycles (issue 14, glow36).

A new user's metal Suzanne and cube (Principled, Metallic 1, Roughness 0.4) on a diffuse
floor under a point light read 1.11-1.17x Cycles on the floor in contact with and in
front of the metal (s35 trial). That light (light -> metal -> floor, L S D) comes from the
caustic map's glow photons here; Cycles finds it by a diffuse bounce at the floor that
meets the metal and samples the light there. Cycles' Light Paths > Caustics > Filter
Glossy (default 1.0) widens every glossy lobe met after a diffuse bounce to GGX alpha
0.41-0.5 (surface_shader_prepare_closures), which spreads the metal's reflection and
dims it beside the metal. With Filter Glossy 0 Cycles renders what ours renders.

The scene: a 1.2 m metal cube (roughness 0.4) turned 30 degrees on a 12 m Lambert floor
(0.8), a 1000 W point light of radius 0, no world light, 64 x 48, 1-pixel box filter, no
clamping, Cycles' default bounces. Measured (4 x 4-pixel blocks, luminance, the 144
blocks brighter than 0.2 x the mean): ours at 32 spp, seeds 0-3, against Cycles 1024 spp
with Filter Glossy 0: 0.949-1.035 (Cycles 1024 / 4096 spp: 0.989-1.006). In the 7 blocks
beside the metal that Filter Glossy changes (Cycles 1.0 / 0: 0.82-0.95): ours / Cycles
0 0.949-1.030, ours / Cycles 1.0 1.035-1.228 (the trial's symptom). Ours now renders the
scene's Filter Glossy (engine/glossysplit.py, fgsplit46): each side is compared at the
same setting, 1 and 0."""
import math
import os
import sys

import numpy as np
import pytest

from blender_helpers import (BLENDS, cycles_plain, default_photonmap, luminance, read_rgba,
                             render_exr)

pytestmark = [pytest.mark.blender, pytest.mark.slow]  # (12-29 s: two Cycles renders and ours)

W, H, BLOCK = 64, 48, 4


def _scene(bpy):
    sys.path.insert(0, BLENDS)
    import make_blends as mb
    sc = mb.reset()  # (clamping off in Cycles' settings and ours)
    sc.render.resolution_x, sc.render.resolution_y = W, H
    floor = mb.material("Floor", "diffuse", (0.8, 0.8, 0.8))
    metal = mb.material("Metal", "principled", (0.9, 0.88, 0.85), roughness=0.4,
                        metallic=1.0)
    mb.plane("Floor", 12, 12, floor)
    mb.box("Block", 1.2, 1.2, 1.2, metal, (0, 0, 0.6), (0, 0, math.radians(30)))
    mb.light("Light", "POINT", (2.5, 1.0, 4.0), 1000.0, shadow_soft_size=0.0)
    mb.camera((3.5, -5.0, 3.0), (0.0, 0.0, 0.3), fov_deg=45)
    sc.cycles.pixel_filter_type, sc.cycles.filter_width = "BOX", 1.0
    return sc


def _blocks(lum):
    return lum.reshape(H // BLOCK, BLOCK, W // BLOCK, BLOCK).mean(axis=(1, 3))


def _cycles(bpy, sc, path, filter_glossy):
    sc.render.engine = "CYCLES"
    c = cycles_plain(sc, 1024, 12)
    c.diffuse_bounces, c.glossy_bounces, c.transmission_bounces = 4, 4, 12
    c.blur_glossy = filter_glossy
    try:
        img = read_rgba(bpy, render_exr(bpy, sc, path))
    finally:
        sc.render.engine = "PHOTONMAP"
    return _blocks(luminance(img[..., :3]))


def test_floor_beside_rough_metal_matches_cycles_at_each_filter_glossy(bpy_addon, tmp_path):
    """Each side at the same Filter Glossy: ours as the add-on renders the scene at Cycles'
    default 1.0 (the glow blurred: engine/glossysplit.py) against Cycles at 1.0, and ours
    at 0 against Cycles at 0."""
    bpy = bpy_addon
    import engine
    from addon import export
    from engine import RenderSettings
    from engine.render import render
    sc = _scene(bpy)
    unblurred = _cycles(bpy, sc, os.path.join(tmp_path, "fg0.exr"), 0.0)
    blurred = _cycles(bpy, sc, os.path.join(tmp_path, "fg1.exr"), 1.0)
    assert sc.cycles.blur_glossy == 1.0
    default_photonmap(sc).spp = 32
    pm_scene, _ = export.export_scene(engine, bpy.context.evaluated_depsgraph_get())
    kw = sc.photonmap.to_settings_kwargs(False)
    assert kw["cycles_filter_glossy"] == 1.0
    films = {fg: render(pm_scene, RenderSettings(**dict(kw, seed=1, cycles_filter_glossy=fg)))
             for fg in (1.0, 0.0)}
    lit = unblurred > 0.2 * unblurred.mean()
    glow = lit & (blurred < 0.95 * unblurred)  # beside the metal: what the filter changes
    assert lit.sum() > 120 and 3 <= glow.sum() <= 20, (lit.sum(), glow.sum())
    for fg, cycles in ((1.0, blurred), (0.0, unblurred)):
        ours = _blocks(luminance(films[fg].combined.astype(np.float64)[..., :3]))
        # Every lit block within 6 % of Cycles at the same Filter Glossy (at 0:
        # 0.949-1.035 over seeds 0-3), the glow blocks among them.
        r = ours[lit] / cycles[lit]
        assert np.all(np.abs(r - 1) < 0.06), (fg, r.min(), r.max())
    # The report says ours blurs that light as Cycles does.
    line = next(x for x in films[1.0].stats["effects"] if x.startswith("glossy blur"))
    assert "Filter Glossy is 1: Cycles widens" in line and "'Block'" in line, line
    assert "so does ours" in line, line
