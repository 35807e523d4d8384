"""A Shade Smooth lathed drinking glass standing on a table, against live Cycles (issue 14,
smoothglass48: cleanuser47's kitchen glass read 1.64x Cycles).

cleanuser47's glass made 10x larger (bench/smoothglass48_cylinder.py): a lathed shell of
one ring of faces per wall, its base a 5 cm disc, Glass BSDF (IOR 1.5, roughness 0),
Shade Smooth (vertex normals up to ~45 degrees off the faces), its base lying on a white
table top (a box: coincident faces), a white World, no other light, the Light Paths out
of the way (32 bounces of every kind). Camera rays seen head-on through the walls are
turned down by the bent normals, trapped in the wall by total internal reflection and
guided to the base; Cycles meets the table wherever a ray leaves the base's bottom face
(it skips only the primitive a ray leaves), so what reaches the contact is lost in the
table: the glass reads 0.21 of the World where it reads 0.81 raised 1 mm. Ours went on
inside the glass as through a gap (3.77x Cycles); with Cycles' contact
(engine/coincident.py CYCLES_CONTACT) 1.00x.
"""
import math

import numpy as np
import pytest

pytestmark = pytest.mark.blender

W, H = 48, 36
PROFILE = [(0.3, 0.0), (0.4, 1.1), (0.37, 1.1), (0.27, 0.05)]  # (r, z): outer up, inner down


def _scene(bpy, scene, elev=0.0):
    import bmesh
    from blender_helpers import node_material, world_color
    m, nt, out = node_material(bpy, "Glass")
    g = nt.nodes.new("ShaderNodeBsdfGlass")
    g.inputs["Roughness"].default_value = 0.0
    g.inputs["IOR"].default_value = 1.5
    nt.links.new(g.outputs[0], out.inputs["Surface"])
    me = bpy.data.meshes.new("Glass")
    bm = bmesh.new()
    rings = [[bm.verts.new((r * math.cos(2 * math.pi * k / 32), r * math.sin(2 * math.pi * k / 32),
                            z)) for k in range(32)] for r, z in PROFILE]
    for a, b in zip(rings[:-1], rings[1:]):
        for k in range(32):
            bm.faces.new((a[k], a[(k + 1) % 32], b[(k + 1) % 32], b[k]))
    bm.faces.new(list(reversed(rings[0])))
    bm.faces.new(rings[-1])
    bmesh.ops.recalc_face_normals(bm, faces=bm.faces)
    bm.to_mesh(me)
    bm.free()
    for p in me.polygons:
        p.use_smooth = True  # Shade Smooth
    me.materials.append(m)
    scene.collection.objects.link(bpy.data.objects.new("Glass", me))
    top, nt, out = node_material(bpy, "Top")
    d = nt.nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    nt.links.new(d.outputs[0], out.inputs["Surface"])
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0.0, 0.5, -0.02), scale=(3.0, 3.0, 0.04))
    bpy.context.object.data.materials.append(top)
    world_color(bpy, scene, (1.0, 1.0, 1.0), 1.0)
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    cam.data.lens = 100.0
    e = math.radians(elev)
    cam.location = (0.0, -4.0 * math.cos(e), 0.55 + 4.0 * math.sin(e))
    cam.rotation_euler = (math.pi / 2 - e, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = W, H, 100
    c = scene.cycles
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = 32
    c.transmission_bounces = c.transparent_max_bounces = 32
    c.caustics_reflective = c.caustics_refractive = True


def _glass_mean(img, ref):
    """Mean luminance over the glass's walls: rows 20-80 % of the image, the columns where
    Cycles' image there differs from the World's 1.0."""
    rows = slice(int(0.2 * H), int(0.8 * H))
    cols = np.flatnonzero((np.abs(ref[rows] - 1.0) > 0.02).any(axis=0))
    return float(img[rows][:, cols[0]:cols[-1] + 1].mean()), float(
        ref[rows][:, cols[0]:cols[-1] + 1].mean())


@pytest.mark.slow
def test_smooth_glass_standing_on_a_table_matches_cycles(fresh_scene, bpy_addon, tmp_path):
    """Head-on through the walls: ours within 8 % of Cycles 256 spp over the glass
    (measured 0.998 at 96 x 72; main 3.77: Cycles 0.213, ours 0.804 of the World), and
    seen from above (89 degrees) the table under the glass's base is dark in both (Cycles
    0.040 over the base's middle, the top face's reflection of the World; main 0.80:
    photons refracted out onto the table, its gather rays through the glass)."""
    from blender_helpers import cheap, cycles_plain, read_rgba, render_exr
    bpy = bpy_addon
    scene = fresh_scene
    got = {}
    for elev in (0.0, 89.0):
        bpy.ops.wm.read_homefile(use_empty=True)
        scene = bpy.context.scene
        _scene(bpy, scene, elev)
        scene.render.engine = "PHOTONMAP"
        cheap(scene, spp=16, photons=50_000, caustic_photons=50_000)
        ours = read_rgba(bpy, render_exr(bpy, scene, tmp_path / f"ours{elev}.exr"))[..., :3]
        scene.render.engine = "CYCLES"
        cycles_plain(scene, 256, 32)
        ref = read_rgba(bpy, render_exr(bpy, scene, tmp_path / f"cycles{elev}.exr"))[..., :3]
        got[elev] = ours.mean(axis=2), ref.mean(axis=2)
    ours, ref = got[0.0]
    o, c = _glass_mean(ours, ref)
    ours_top, ref_top = got[89.0]
    mid = (slice(H // 2 - 5, H // 2 + 5), slice(W // 2 - 5, W // 2 + 5))
    print(f"smooth glass on a table: head-on ours {o:.4f} / Cycles {c:.4f} = {o / c:.3f}; "
          f"under the base from above ours {ours_top[mid].mean():.4f} / Cycles "
          f"{ref_top[mid].mean():.4f}")
    assert c < 0.5  # Cycles loses most of the light at the contact
    assert o / c == pytest.approx(1.0, abs=0.08)
    assert ref_top[mid].mean() < 0.1
    assert ours_top[mid].mean() == pytest.approx(ref_top[mid].mean(), abs=0.03)
