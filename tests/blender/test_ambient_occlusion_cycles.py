"""Ambient Occlusion node against Cycles (issue 14): rays from the shading point inside
the shader (engine/ambientocclusion.py, Cycles' svm_ao). It read the socket's own value
before (warned).

The harness of test_color_nodes_cycles.py without its lift (an emissive surface whose
colour is the node under test, seen from above, samples at the pixel centres): a floor
whose emission is the AO node's Color (white) or AO output, with a box and a wall standing
on it; both renderers average 64 samples of 16 AO rays a pixel, compared in blocks of
4 x 4 pixels (their noise patterns differ: Cycles draws each AO ray from its sampler, we
from a hash of the hit)."""
import numpy as np
import pytest

from test_color_nodes_cycles import _plane_scene

pytestmark = pytest.mark.blender

W = H = 32
SPP = 64


def _ao_node(output="Color", distance=0.6, inside=False, only_local=False, samples=16):
    def build(nodes, links):
        ao = nodes.new("ShaderNodeAmbientOcclusion")
        ao.inputs["Distance"].default_value = distance
        ao.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
        ao.samples, ao.inside, ao.only_local = samples, inside, only_local
        return ao.outputs[output]
    return build


def _blocks(img, k=4):
    h, w = img.shape[:2]
    return img[:h - h % k, :w - w % k].reshape(h // k, k, w // k, k, -1).mean(axis=(1, 3))


def _obstacles(bpy, join_to=None):
    """A box (0.6 m) and a wall (0.2 x 1.6 x 0.8 m) on the floor; join_to: the floor
    object they are joined into (one object: Only Local sees them)."""
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(-0.35, 0.25, 0.3))
    box = bpy.context.object
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.55, 0.0, 0.4))
    wall = bpy.context.object
    wall.scale = (0.2, 1.6, 0.8)
    if join_to is None:
        return
    for ob in bpy.context.view_layer.objects:
        ob.select_set(ob in (box, wall, join_to))
    bpy.context.view_layer.objects.active = join_to
    bpy.ops.object.join()


def _compare(bpy, scene, tmp_path, name):
    from blender_helpers import render_pixel_centres
    scene.render.resolution_x, scene.render.resolution_y = W, H
    ours = render_pixel_centres(bpy, scene, tmp_path / "ours.exr", "PHOTONMAP", spp=SPP)
    ref = render_pixel_centres(bpy, scene, tmp_path / "cycles.exr", "CYCLES", spp=SPP)
    ours, ref = ours[..., :3], ref[..., :3]
    bo, br = _blocks(ours), _blocks(ref)
    err = np.abs(bo - br)
    print(f"{name}: mean ours {ours.mean():.4f} Cycles {ref.mean():.4f}, blocks "
          f"{br.min():.3f} .. {br.max():.3f}, max block |ours - Cycles| {err.max():.4f}")
    assert np.all(np.isfinite(ours))
    return ours, ref, err


CASES = {
    # The floor darkens towards the box and the wall (AO 1 far from them)
    "color": dict(build=_ao_node("Color")),
    "ao_output": dict(build=_ao_node("AO", distance=0.3)),
    # Box and wall separate objects: Only Local on the floor sees only the floor: 1
    "only_local_apart": dict(build=_ao_node("Color", only_local=True)),
    # Box and wall joined into the floor's object: Only Local sees them
    "only_local_joined": dict(build=_ao_node("Color", only_local=True), join=True),
    # Distance 0 (unlinked): World > Settings > Ambient Occlusion > Distance (0.35 m)
    "world_distance": dict(build=_ao_node("Color", distance=0.0), world_distance=0.35),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_ambient_occlusion_matches_cycles(fresh_scene, bpy_addon, tmp_path, case):
    bpy = bpy_addon
    scene = fresh_scene
    spec = CASES[case]
    _plane_scene(bpy, scene, spec["build"])
    floor = bpy.context.object
    _obstacles(bpy, join_to=floor if spec.get("join") else None)
    if "world_distance" in spec:
        scene.world.light_settings.distance = spec["world_distance"]
    ours, ref, err = _compare(bpy, scene, tmp_path, case)
    assert abs(ours.mean() - ref.mean()) <= 0.01 * ref.mean()
    assert err.max() <= 0.03
    if case == "only_local_apart":
        # the floor's pixels away from the obstacles' outlines (their tops are black: no
        # light in the scene; an outline pixel's samples fall on both)
        on = np.pad(ref[..., 0] > 0.5, 1)
        floor_px = np.logical_and.reduce([on[1 + dy:1 + dy + H, 1 + dx:1 + dx + W]
                                          for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
        # Ours: 1 on every floor pixel. Cycles: 1 except along the floor's diagonal (the
        # shared edge of its two triangles, i + j = W - 1), 0.97-0.98 there: its local AO
        # rays skip only the triangle they leave (ray.self.prim), and those leaving near
        # the edge at a grazing angle meet the coplanar neighbour. Ours leave from the
        # triangle's surface offset (engine/rayoffset.py), as every ray of the engine.
        assert np.all(np.abs(ours[floor_px] - 1.0) < 1e-4)
        i, j = np.nonzero(floor_px & (ref[..., 0] < 1.0 - 1e-4))
        assert np.all(np.abs(i + j - (W - 1)) <= 1)
        assert np.all(ref[floor_px] > 0.95)
    else:
        assert np.ptp(_blocks(ref)) > 0.2  # occlusion shows


def test_inside_only_local_reads_thickness(fresh_scene, bpy_addon, tmp_path):
    """Inside with Only Local on a box seen from above (the AO node's thickness use): the
    rays go into the box; within 0.4 m they meet its far faces near the edges."""
    bpy = bpy_addon
    scene = fresh_scene
    mat = _plane_scene(bpy, scene, _ao_node("Color", distance=0.4, inside=True,
                                            only_local=True))
    bpy.data.objects.remove(bpy.context.object)  # (the floor)
    bpy.ops.mesh.primitive_cube_add(size=1.2)
    box = bpy.context.object
    box.rotation_euler = (0.0, 0.0, 0.4)
    box.data.materials.append(mat)
    ours, ref, err = _compare(bpy, scene, tmp_path, "inside_only_local")
    assert abs(ours.mean() - ref.mean()) <= 0.01 * ref.mean()
    assert err.max() <= 0.03
    assert np.ptp(_blocks(ref)) > 0.2
