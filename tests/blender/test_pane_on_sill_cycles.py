"""A glass pane standing on a window sill, lit by a sun, against live Cycles (issue 14,
streak41: newuser40's room showed a bright line on its ceiling beside the lamp).

A 2 m x 1.2 m pane of glass 1 cm thick (Glass BSDF, IOR 1.5) stands on a sill (diffuse
0.8; the pane's bottom face in the sill's top plane), a sun 40 degrees high (15 degree
disc: Cycles finds it through the glass only by path tracing) shines through it towards a
ceiling (diffuse 0.8, z = 3 m), a black world, an orthographic camera under the ceiling
looking up. The sunlight entering the pane within 4.7 mm of its bottom meets the bottom
face inside past the critical angle. Raised by a gap, the pane reflects it up and out
onto the ceiling (a band there, in both renderers); standing on the sill, the reflected
ray starts on the sill's plane and Cycles meets the sill (its ray origins are not
offset): no band. Ours reflected it as with a gap (the band's rows 1.55x Cycles, the
image 1.10x); the photons reflected back inside there now go into the sill
(engine/coincident.py, reflected_inside).
"""
import math

import numpy as np
import pytest
from blender_helpers import black_world, glass_or_diffuse_material

pytestmark = pytest.mark.blender

SIZE = 48
# The image rows where the raised pane's band lies (ours and Cycles; the camera 3 m wide
# over 48 rows, centred 8 cm from the band's centre line).
BAND = slice(12, 28)


def _box(bpy, name, location, scale, material):
    bpy.ops.mesh.primitive_cube_add(size=1, location=location)
    box = bpy.context.object
    box.name = name
    box.scale = scale
    bpy.ops.object.transform_apply(scale=True)
    box.data.materials.append(material)


def _scene(bpy, scene):
    _box(bpy, "Sill", (0.0, 0.0, 0.95), (2.4, 0.3, 0.1),
         glass_or_diffuse_material(bpy, "Sill", "diffuse", (0.8,) * 3))
    _box(bpy, "Pane", (0.0, 0.0, 1.6), (2.0, 0.01, 1.2),
         glass_or_diffuse_material(bpy, "Glass", "glass", (1.0,) * 3))
    bpy.ops.mesh.primitive_plane_add(size=1, location=(0.0, -2.3, 3.0), rotation=(math.pi, 0, 0))
    ceiling = bpy.context.object
    ceiling.name, ceiling.scale = "Ceiling", (4.0, 3.4, 1.0)
    ceiling.data.materials.append(glass_or_diffuse_material(bpy, "White", "diffuse", (0.8,) * 3))
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy, sun.data.angle = 100.0, math.radians(15.0)
    sun.rotation_euler = (math.radians(-50.0), 0.0, 0.0)
    scene.collection.objects.link(sun)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.type, cam.data.ortho_scale = "ORTHO", 3.0
    cam.location, cam.rotation_euler = (0.0, -2.3, 1.5), (math.pi, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    black_world(bpy, scene)
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0


@pytest.mark.slow
def test_ceiling_over_a_pane_standing_on_a_sill_matches_cycles(fresh_scene, bpy_addon,
                                                                 tmp_path):
    """The ceiling's band rows and the whole image within 5 % of Cycles 4096 spp
    (measured: band 1.000, image 0.978; before, main b71c843: 1.546 and 1.102). Both at
    the scene's Filter Glossy 1 (splitpane47: Cycles' image 0.1287, 0.864 of its 0.1490
    at 0; ours band 0.958, image 0.959 of Cycles at 1: the pane is window glass, whose
    passage the chains leave to the shadow rays, which miss the light the blurred pane
    sends up to the ceiling; 1.012 / 0.978 where the chains took that light too, and the
    image 0.845 of Cycles at 0)."""
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    bpy = bpy_addon
    scene = fresh_scene
    _scene(bpy, scene)
    scene.render.engine = "PHOTONMAP"
    cheap(scene, spp=64, photons=100_000, caustic_photons=100_000)
    ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "ours.exr"))[..., :3].mean(axis=2)
    scene.render.engine = "CYCLES"
    cycles_plain(scene, 4096, 12).blur_glossy = 1.0  # (the scene's, ours' too)
    ref = read_rgba(bpy, render_exr(bpy, scene, tmp_path / "cycles.exr"))[..., :3].mean(axis=2)
    band = float(ours[BAND].mean() / ref[BAND].mean())
    image = float(ours.mean() / ref.mean())
    print(f"pane on a sill, ceiling: ours / Cycles band rows {band:.4f}, image {image:.4f} "
          f"(Cycles band {float(ref[BAND].mean()):.4f}, image {float(ref.mean()):.4f})")
    assert ref[BAND].mean() > 0.03
    assert band == pytest.approx(1.0, abs=0.05)
    assert image == pytest.approx(1.0, abs=0.05)
