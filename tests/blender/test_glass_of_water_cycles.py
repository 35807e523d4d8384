"""A glass of water seen from above, the table under it lit by a sun through the water's
top, against Cycles (issue 14, water43: newuser42's glass of water read 27 % brighter
than Cycles seen through it).

A clear glass (an open cylinder of radius 0.4 m and height 1 m, walls and bottom 3 cm
thick: Solidify inwards; Glass BSDF, IOR 1.5) holds water (a closed cylinder of radius
0.365 m, 0.65 m deep, 1 mm above the glass's bottom; Glass BSDF, IOR 1.33), both 1 mm
above a diffuse table (0.8) so that no surface touches another (at exact contact Cycles'
image is its rounding: docs/accuracy.md, contact30). A sun 20 degrees off the vertical,
an orthographic camera straight down onto the water's top (it sees the table through
the flat caps only), black world, 16 x 16 pixels.

The table under the glass takes the sunlight only through the water and the glass
(L S+ D: our caustic photons; shadow rays are blocked by glass in both renderers). Cycles
finds it only where a diffuse bounce's ray, refracted out through the water's top, meets
the sun's disc: with a 1-degree sun about 1 sample in 14,000, so at a few thousand
samples its image is dark with fireflies (newuser42's 1-degree sun: the glass read
brighter in ours); with a 30-degree disc about 1 in 16, and it converges. There ours
matches it with flat-shaded glass, and with smooth-shaded sides (docs/accuracy.md,
water43, smoothglass43 / 44, turnednormal44).

Both renderers at Filter Glossy 0 (ours: the scene's Light Paths > Caustics > Filter
Glossy set to 0 before its render; cycles_plain sets Cycles'): the test is of the
caustic photons through smooth glass. At the scene's Filter Glossy 1 Cycles blurs every
interface after the table's diffuse bounce and the table reads 0.357 (flat) / 0.344
(smooth) of its Filter Glossy 0 mean (0.3308 / 0.3470 at 4096 spp); ours, whose
engine/glossysplit.py chains carry that light at 1, reads 1.10 / 1.13 of those at 64 spp
(docs/compatibility.md, "splitpane47").

Both renderers unclamped (ours: Clamp Indirect 0 in _ours, as cycles_plain sets
Cycles'): like with like. Before clampphoton54 ours ran at the add-on's Clamp Indirect 10
against unclamped Cycles, which its clamp on the whole estimate left unchanged (0.996 of
its unclamped image, smooth, seeds 0-2); with each caustic photon clamped as Cycles'
path (engine/photonclamp.py) the clamped pair is a test of its own
(test_clamped_glass_of_water_is_cut_as_cycles_cuts_it). Unclamped, ours over seeds 0-5
reads 0.990 (flat: 0.962-1.011) and 0.990 (smooth: 0.974-1.021) of the stored means.

Cycles' image means (4096 spp, seed 0) are stored in
tests/references/glass_of_water.json (this file run as a script writes them); the slow
test_stored_cycles_means_are_cycles_now renders them again live.
"""
import json
import math
import os

import pytest

pytestmark = pytest.mark.blender

REF_PATH = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                        "references", "glass_of_water.json")
SIZE = 16
CYCLES_SAMPLES = 4096
# The sun's disc (degrees): wide enough that Cycles' path tracing converges through the
# water (its diffuse rays meet the refracted disc 1 time in ~16).
SUN_ANGLE = 30.0
# Flat-shaded glass and water ("flat") and the same with smooth sides ("smooth": caps and
# rims flat, no sharp edges, so Blender's normals domain is POINT and both renderers shade
# the sides with vertex normals averaged with the caps': tilted up to 47 degrees from the
# faces at the rims, addon/normals.py).
SHADINGS = ("flat", "smooth")


def _cylinder(bpy, name, radius, depth, z, material, smooth_sides, open_top=False,
              shell=None):
    """A 48-sided cylinder (bottom at z); smooth_sides: its sides smooth-shaded, caps and
    rims flat, else every face flat; open_top drops the top cap, shell (m) applies a
    Solidify of that thickness inwards."""
    import bmesh
    bpy.ops.mesh.primitive_cylinder_add(vertices=48, radius=radius, depth=depth,
                                        location=(0.0, 0.0, z + depth / 2))
    ob = bpy.context.object
    ob.name = name
    if open_top:
        bm = bmesh.new()
        bm.from_mesh(ob.data)
        bmesh.ops.delete(bm, geom=[f for f in bm.faces if f.normal.z > 0.9],
                         context="FACES_ONLY")
        bm.to_mesh(ob.data)
        bm.free()
    if shell is not None:
        mod = ob.modifiers.new("Solidify", "SOLIDIFY")
        mod.thickness, mod.offset = shell, -1.0
        bpy.ops.object.modifier_apply(modifier=mod.name)
    for p in ob.data.polygons:
        p.use_smooth = smooth_sides and abs(p.normal.z) < 0.1
    ob.data.materials.append(material)
    return ob


def _scene(bpy, scene, shading, sun_angle=SUN_ANGLE, water=True):
    """The glass of water (water False: the glass alone) with its shading (SHADINGS)."""
    from blender_helpers import (black_world, glass_or_diffuse_material,
                                 looking_down_camera, sun_light)
    lift = 0.001
    smooth = shading == "smooth"
    bpy.ops.mesh.primitive_plane_add(size=4.0)
    bpy.context.object.data.materials.append(
        glass_or_diffuse_material(bpy, "Table", "diffuse", (0.8,) * 3))
    _cylinder(bpy, "Glass", 0.4, 1.0, lift, glass_or_diffuse_material(
        bpy, "Glass", "glass", (1.0,) * 3, ior=1.5), smooth, open_top=True, shell=0.03)
    if water:
        _cylinder(bpy, "Water", 0.365, 0.65, lift + 0.031, glass_or_diffuse_material(
            bpy, "Water", "glass", (1.0,) * 3, ior=1.33), smooth)
    sun_light(bpy, scene, (math.radians(20.0), 0.0, 0.0), 4.0).data.angle = math.radians(
        sun_angle)
    looking_down_camera(bpy, scene, 3.0, ortho_scale=0.4)
    black_world(bpy, scene)
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0


def _mean(bpy, scene, path, engine):
    from blender_helpers import read_rgba, render_exr
    scene.render.engine = engine
    return float(read_rgba(bpy, render_exr(bpy, scene, path))[..., :3].mean())


def _cycles_means(bpy, tmp_path):
    """Cycles' image mean per shading, rendered now: {shading: mean}."""
    from blender_helpers import cycles_plain
    out = {}
    for shading in SHADINGS:
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = bpy.context.scene
        _scene(bpy, scene, shading)
        cycles_plain(scene, CYCLES_SAMPLES, 12)
        out[shading] = _mean(bpy, scene, tmp_path / f"cycles_{shading}.exr", "CYCLES")
    return out


def _stored_means():
    with open(REF_PATH) as f:
        return json.load(f)["means"]


# Ours: 64 spp, 200k global and 100k caustic photons, the image mean over SEEDS. One
# render's spread over seeds is set by the global photons (s.d. 0.017-0.020 at 64 spp and
# 200k, 0.038 at 4 spp; 64 spp at 20k is 2-3 % lower, the density's bias): the mean over
# six seeds has s.d. ~0.008, so the bounds below stay >= 4 of it from the measured means
# on any CPU (another CPU's float bits draw other paths: flaky50 / s50).
SEEDS = range(6)


def _ours(bpy, scene, tmp_path, name, clamp=0.0):
    """ours' image mean over SEEDS of scene as set up (Filter Glossy 0), at Clamp Indirect
    `clamp` (Direct 0): unclamped by default, as the stored Cycles means (cycles_plain)."""
    from blender_helpers import cheap
    cheap(scene, spp=64, photons=200_000, caustic_photons=100_000)
    scene.cycles.blur_glossy = 0.0  # (the stored means' Filter Glossy)
    scene.cycles.sample_clamp_direct, scene.cycles.sample_clamp_indirect = 0.0, clamp
    means = []
    for seed in SEEDS:
        scene.photonmap.seed = seed
        means.append(_mean(bpy, scene, tmp_path / f"ours_{name}_{seed}.exr", "PHOTONMAP"))
    return sum(means) / len(means), means


def _ratio(bpy, scene, tmp_path, shading):
    """ours (_ours) / Cycles' stored mean."""
    _scene(bpy, scene, shading)
    ours, means = _ours(bpy, scene, tmp_path, shading)
    want = _stored_means()[shading]
    print(f"glass of water ({shading}), the table seen through the water: ours {ours:.4f}, "
          f"Cycles {want:.4f}, ratio {ours / want:.4f} (per seed "
          f"{[round(m / want, 3) for m in means]})")
    assert want > 0.5  # lit through the water
    return ours / want


def test_table_under_a_glass_of_water_matches_cycles(fresh_scene, bpy_addon, tmp_path):
    """Flat-shaded glass and water: ours within 4 % of Cycles' 4096-spp mean (Cycles at
    16384 spp reads it to 0.03 %). One render (_ours' settings) reads 0.963-1.011 over
    seeds 0-7, mean 0.990, s.d. 0.017, since the camera's four refractions at normal
    incidence through the caps count as transmission bounces (glasswater50; at 4 spp and
    20k global photons 0.975 / 0.949 / 0.974 / 0.983 / 0.971 at seeds 0-4, and 1.015 /
    0.999 / 1.006 / 1.027 / 1.016 when they were passes, which left the table 4 bounces
    more)."""
    assert _ratio(bpy_addon, fresh_scene, tmp_path, "flat") == pytest.approx(1.0, abs=0.04)


def test_smooth_sided_glass_of_water_matches_cycles(fresh_scene, bpy_addon, tmp_path):
    """The same glass and water with smooth sides (SHADINGS): Cycles 1.009 (flat 0.928).
    The camera's path to the table crosses only the flat caps; the table's light comes
    through the glass's bent sides, most of it in Cycles by reflections at the normal its
    glass closure turns per ray (ensure_valid_specular_reflection), which no photon can
    take: final-gather chains find those (engine/turnedlight.py: their escapes into the
    sun's disc, and Cycles' turned normal, not the guard's Ng, where a gather ray meets
    the inner side from below its bent normal); photons take the rest
    (engine/glassadjoint.py). One render (_ours' settings) reads 0.952-1.012 of Cycles
    over seeds 0-7, mean 0.981, s.d. 0.018: ~2 % short, the shortfall glasswater50 found
    once the caps' refractions counted as transmission bounces (as Cycles counts them),
    so the bound is 5 % (glasswater51: seeds 0-5 0.983 here, and 0.975-0.985 at Max
    Bounces 10-64 now that the gather chains go on to the limits; its growth with Max
    Bounces, 0.93 at 16, was their old cap of 8 continuations). At 4 spp and
    20k global photons seeds 0-4 read 1.010 / 0.936 / 0.975 / 0.960 / 0.966; 0.949 at
    seed 0 with the escapes counted from past their last refraction; 1.023 / 0.984 /
    0.982 / 0.972 / 1.002 when the caps' refractions were passes; 0.680 before
    turnednormal44, 0.651 before smoothglass43 (docs/accuracy.md, turnednormal44;
    docs/compatibility.md, glasswater50)."""
    assert _ratio(bpy_addon, fresh_scene, tmp_path, "smooth") == pytest.approx(1.0, abs=0.05)


# Cycles' image mean of the smooth glass of water at Light Paths > Max Bounces 10 (4096
# spp, seed 0, Filter Glossy 0, Blender 5.0.1: _scene(bpy, scene, "smooth") with
# cycles_plain(scene, 4096, 10); docs/compatibility.md "### glasswater50"). The camera's
# path reaches the table after 4
# transmission bounces (the caps, at normal incidence) and its light after 4-6 more.
CYCLES_SMOOTH_MAX_BOUNCES_10 = 0.8442


def test_smooth_glass_of_water_at_max_bounces_10_matches_cycles(fresh_scene, bpy_addon,
                                                                tmp_path):
    """The smooth glass of water at Max Bounces 10, where a path's bounce count decides
    much of the table's light: the gather chains' turned reflections that escape into the
    sun count if the vertex they leave is within the limits (Cycles' kernel limit is the
    setting + 1: the last scatter's ray still collects the light it hits). One render
    (_ours' settings) reads 0.956-1.013 of Cycles over seeds 0-7, mean 0.981, s.d. 0.020
    (at 4 spp and 20k photons 0.994 / 0.940 / 1.015 at seeds 0-2); 0.87 when an escape counted its last
    refraction against the limit (glasswater50). glasswater51 measured one render's s.d.
    0.030 over seeds 0-5 (mean 0.977): the six-seed mean's s.d. ~0.012, so the bound is
    the ~2.3 % bias plus > 4 s.d.: 8 %, which still fails the 0.87."""
    bpy, scene = bpy_addon, fresh_scene
    _scene(bpy, scene, "smooth")
    scene.cycles.max_bounces = 10
    ours, means = _ours(bpy, scene, tmp_path, "smooth_10")
    ratio = ours / CYCLES_SMOOTH_MAX_BOUNCES_10
    print(f"glass of water (smooth, Max Bounces 10): ours {ours:.4f}, Cycles "
          f"{CYCLES_SMOOTH_MAX_BOUNCES_10:.4f}, ratio {ratio:.4f} (per seed "
          f"{[round(m / CYCLES_SMOOTH_MAX_BOUNCES_10, 3) for m in means]})")
    assert ratio == pytest.approx(1.0, abs=0.08)


# Cycles' image mean of the smooth glass of water at Max Bounces 64, Transmission 64
# (Glossy and Diffuse 4; 8192 spp, seed 0, Filter Glossy 0, no clamping, Blender 5.0.1:
# _scene(bpy, scene, "smooth") with cycles_plain(scene, 8192, 64) and
# scene.cycles.transmission_bounces = 64; docs/accuracy.md "### glasswater51").
CYCLES_SMOOTH_MAX_BOUNCES_64 = 1.1323


def test_smooth_glass_of_water_at_max_bounces_64_matches_cycles(fresh_scene, bpy_addon,
                                                                tmp_path):
    """The smooth glass of water at Max Bounces 64 (Transmission 64), ours unclamped as
    Cycles: the table's light through long chains of refractions and reflections in the
    glass and water. The final-gather chains go on to the Light Paths limits
    (glasswater51): one render (_ours' settings, clamp off) reads 0.951-1.022 of Cycles
    over seeds 0-5, mean 0.985, s.d. 0.025 (the six seeds' mean: s.d. ~0.010), so the
    bound is 6 %; with the chains' old cap of 8 continuations of their own seeds 0-3
    read 0.966 (now 0.997 on the same seeds), ~0.955 over six: within this bound too,
    so tests/test_bounce_limits.py's IOR 1 slabs are the test that tells them apart."""
    bpy, scene = bpy_addon, fresh_scene
    _scene(bpy, scene, "smooth")
    scene.cycles.max_bounces = scene.cycles.transmission_bounces = 64
    scene.cycles.sample_clamp_direct = scene.cycles.sample_clamp_indirect = 0.0
    ours, means = _ours(bpy, scene, tmp_path, "smooth_64")
    ratio = ours / CYCLES_SMOOTH_MAX_BOUNCES_64
    print(f"glass of water (smooth, Max Bounces 64): ours {ours:.4f}, Cycles "
          f"{CYCLES_SMOOTH_MAX_BOUNCES_64:.4f}, ratio {ratio:.4f} (per seed "
          f"{[round(m / CYCLES_SMOOTH_MAX_BOUNCES_64, 3) for m in means]})")
    assert ratio == pytest.approx(1.0, abs=0.06)


# Cycles' image means at Light Paths > Clamping > Indirect 10 (Blender's default; Direct
# 0): 4096 spp, seed 0, Filter Glossy 0, Blender 5.0.1, _scene(bpy, scene, shading) with
# cycles_plain(scene, 4096, 12) and then scene.cycles.sample_clamp_indirect = 10 (seed 1:
# 0.4959 / 0.5404; docs/accuracy.md "### clampphoton54"). Unclamped (the stored means)
# 0.9281 / 1.0087: Cycles' clamp keeps 0.53 of the table's light.
CYCLES_CLAMP_10 = {"flat": 0.4948, "smooth": 0.5397}
# ours at Clamp Indirect 10 over CYCLES_CLAMP_10: within this of 1 (roulette54's six-seed
# means 1.012 / 1.009; one render's s.d. ~0.02 over Cycles, ~0.009 for the six-seed
# mean: 5 s.d.).
CLAMPED_TOLERANCE = 0.05


@pytest.mark.parametrize("shading", SHADINGS)
def test_clamped_glass_of_water_is_cut_as_cycles_cuts_it(fresh_scene, bpy_addon, tmp_path,
                                                        shading):
    """ours and Cycles both at Clamp Indirect 10 (the tests above compare both unclamped):
    the table's light comes by paths far over the limit in Cycles (a diffuse bounce's ray
    refracted out to the 30-degree sun: tp x albedo x Le = 0.8 x 57 W sr^-1 m^-2 summed
    over RGB, over the limit of 30), which ours clamps per caustic photon
    (engine/photonclamp.py) at the limit x the share Cycles' Russian roulette leaves it
    (roulette_share: 0.8^(15/16) = 0.81 through the four faces of glass and water, the
    table read through the glass: past the camera's first hit no face is spared) and,
    in the smooth glass, per gather ray (integrator.CLAMP_PER_GATHER_RAY: its
    turned-normal chains' light). Cycles with its roulette off (Min Light Bounces 64)
    reads 0.6249 / 0.6796: the roulette is a fifth of its cut. Ours over seeds 0-5:
    1.012 (flat) / 1.009 (smooth) of clamped Cycles (per seed 0.981-1.035 /
    0.996-1.035); 1.251 / 1.136 with the whole limit (clampphoton54), 1.86 / 1.84 when
    the estimates were clamped as a whole (docs/accuracy.md "### roulette54")."""
    bpy, scene = bpy_addon, fresh_scene
    _scene(bpy, scene, shading)
    ours, means = _ours(bpy, scene, tmp_path, f"{shading}_clamp10", clamp=10.0)
    ratio = ours / CYCLES_CLAMP_10[shading]
    print(f"glass of water ({shading}, Clamp Indirect 10): ours {ours:.4f}, Cycles "
          f"{CYCLES_CLAMP_10[shading]:.4f}, ratio {ratio:.4f} (per seed "
          f"{[round(m / CYCLES_CLAMP_10[shading], 3) for m in means]})")
    assert ratio == pytest.approx(1.0, abs=CLAMPED_TOLERANCE)


@pytest.mark.slow
def test_stored_cycles_means_are_cycles_now(bpy_addon, tmp_path):
    """The stored means are what this Blender's Cycles renders (2 renders at 4096 spp,
    16 x 16, ~10 CPU s; seed 0: the same numbers up to float summation order)."""
    stored, now = _stored_means(), _cycles_means(bpy_addon, tmp_path)
    assert set(now) == set(stored)
    for k, v in now.items():
        assert abs(v / stored[k] - 1.0) < 1e-3, (k, v, stored[k])


if __name__ == "__main__":  # write the stored means: .venv/bin/python <this file>
    import sys
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from blender_helpers import store_cycles_means
    store_cycles_means(REF_PATH, _cycles_means, cycles_samples=CYCLES_SAMPLES, seed=0,
                       sun_angle=SUN_ANGLE)
