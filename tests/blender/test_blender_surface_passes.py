"""Cycles' surface data passes through the add-on (issue 14, engine/datapasses.py SURFACE):
Object Index, Material Index, Position, UV, Mist and Depth against live Cycles' same passes at
1 sample a pixel with the same pixel filter, on a UV-mapped floor, a box without a UV map
and its linked duplicate (its own Pass Index), a world with Mist Pass settings.

At 1 spp both engines write the one sample's surface; the samples sit at different
places inside the pixel filter (the samplers differ), so the continuous passes are
compared within the pass' own change to the next pixel (Cycles'), the indices exactly
where a pixel and its neighbours see one object.
"""
import math
import os
import sys

import numpy as np
import pytest

from blender_helpers import ROOT, cheap, cycles_plain, read_layers, render_exr

pytestmark = pytest.mark.blender

W, H = 64, 48
PASSES = ("Object Index", "Material Index", "Position", "UV", "Mist", "Depth")
FLOOR = 8.0


def _scene(bpy):
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends as mb
    scene = mb.reset()
    floor_mat = mb.material("floor", "principled", (0.6, 0.6, 0.6), roughness=1.0)
    red = mb.material("red", "principled", (0.7, 0.1, 0.1), roughness=0.6)
    floor_mat.pass_index, red.pass_index = 2, 4
    floor = mb.plane("Floor", FLOOR, FLOOR, floor_mat)
    floor.pass_index = 1
    # A UV map: u, v = x / 8 + 0.5, y / 8 + 0.5 (corners in from_pydata's order).
    uv = floor.data.uv_layers.new(name="map")
    for loop, (x, y) in zip(floor.data.loops, [(-1, -1), (1, -1), (1, 1), (-1, 1)]):
        uv.data[loop.index].uv = (0.5 + 0.5 * x, 0.5 + 0.5 * y)
    box = mb.box("Box", 1.0, 1.0, 1.0, red, (-0.8, 0.3, 0.5), (0, 0, math.radians(30)))
    box.pass_index = 5
    twin = bpy.data.objects.new("Twin", box.data)  # a linked duplicate, its own index
    twin.location, twin.rotation_euler = (1.0, 0.8, 0.5), (0, 0, math.radians(-20))
    twin.pass_index = 9
    scene.collection.objects.link(twin)
    mb.set_world((0.2, 0.2, 0.2))
    mist = scene.world.mist_settings
    mist.start, mist.depth, mist.falloff = 3.0, 6.0, "INVERSE_QUADRATIC"
    mb.light("Sun", "SUN", (0, 0, 5), 3.0, look_at=(0.3, 0.2, 0))
    mb.camera((0, -5.5, 2.6), (0, 0.6, 0.2))
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = W, H, 100
    r.use_compositing = False
    vl = scene.view_layers[0]
    vl.use_pass_object_index = vl.use_pass_material_index = True
    vl.use_pass_position = vl.use_pass_uv = vl.use_pass_mist = True
    vl.use_pass_z = True
    return scene


@pytest.fixture(scope="module")
def renders(bpy_addon, tmp_path_factory):
    """{engine: {pass: (H,W,C)}}: Cycles and ours, 1 sample a pixel each."""
    bpy = bpy_addon
    tmp = tmp_path_factory.mktemp("surface_passes")
    scene = _scene(bpy)
    out = {}
    for engine in ("CYCLES", "PHOTONMAP"):
        scene.render.engine = engine
        if engine == "CYCLES":
            cycles_plain(scene, 1, 4)
        else:
            cheap(scene, spp=1, photons=2_000, caustic_photons=200)
        out[engine] = read_layers(render_exr(bpy, scene, tmp / f"{engine}.exr",
                                             multilayer=True))
    return out


def _uniform(a, r=2):
    """(H,W) bool: the (2r+1)^2 pixels around each of a (H,W) hold one value (edges
    False). r = 2: one pixel's sample and its neighbour's, each within the filter's
    1.5-pixel width, may lie 1.5 pixels apart, on either side of an edge between them."""
    same = np.zeros(a.shape, bool)
    h, w = a.shape
    c = a[r:h - r, r:w - r]
    ok = np.ones(c.shape, bool)
    for dy in range(-r, r + 1):
        for dx in range(-r, r + 1):
            ok &= a[r + dy:h - r + dy, r + dx:w - r + dx] == c
    same[r:h - r, r:w - r] = ok
    return same


def _step(a):
    """(H,W) the largest change of a (H,W,C) to a neighbouring pixel (edges: inf)."""
    step = np.full(a.shape[:2], np.inf)
    c = a[1:-1, 1:-1]
    m = np.zeros(c.shape[:2])
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            n = a[1 + dy:a.shape[0] - 1 + dy, 1 + dx:a.shape[1] - 1 + dx]
            m = np.maximum(m, np.abs(n - c).max(axis=2))
    step[1:-1, 1:-1] = m
    return step


def test_surface_passes_match_cycles(renders):
    """Measured (64 x 48, 1 spp): the indices equal Cycles' on every pixel whose 5 x 5
    neighbourhood sees one object; Position, UV and Mist within 1.5 x Cycles' own change
    to the next pixel there, their mean signed difference a few % of that change."""
    cyc, ours = renders["CYCLES"], renders["PHOTONMAP"]
    for name in PASSES:
        assert name in ours and name in cyc, (name, sorted(ours), sorted(cyc))
        assert ours[name].shape == cyc[name].shape, (name, ours[name].shape, cyc[name].shape)
        assert np.isfinite(ours[name]).all(), name
    obj = cyc["Object Index"][..., 0]
    inside = _uniform(obj) & _uniform(cyc["Material Index"][..., 0])
    # Every object and the background is seen over whole pixels.
    for index in (0, 1, 5, 9):
        assert (inside & (obj == index)).sum() >= 10, (index, int((obj == index).sum()))
    for name in ("Object Index", "Material Index"):
        np.testing.assert_array_equal(ours[name][..., 0][inside], cyc[name][..., 0][inside],
                                      err_msg=name)
    np.testing.assert_array_equal(np.unique(cyc["Material Index"][..., 0][inside]),
                                  [0, 2, 4])
    report = {}
    for name in ("Position", "UV", "Mist", "Depth"):
        c, o = cyc[name], ours[name]
        tol = 1.5 * _step(c)[inside] + 1e-4
        diff = np.abs(o - c)[inside].max(axis=1)
        seen = obj[inside] > 0
        report[name] = {"max diff / step": float(np.max(diff[seen] / tol[seen])),
                        "mean |diff|": float(diff[seen].mean()),
                        "mean step": float(tol[seen].mean() / 1.5)}
        assert np.all(diff <= tol), (name, report[name])
        signed = (o - c)[inside].mean(axis=0)
        assert np.all(np.abs(signed) <= 0.1 * np.mean(tol) + 1e-4), (name, signed, np.mean(tol))
    # The background: Position and UV 0, Mist 1, in both.
    bg = inside & (obj == 0)
    assert np.all(ours["Mist"][..., 0][bg] == 1.0) and np.all(cyc["Mist"][..., 0][bg] == 1.0)
    assert not ours["Position"][bg].any() and not ours["UV"][bg].any()
    # Depth: none is 1e10 (Cycles' film_get_pass_pixel_depth reads its 0 so) in both.
    assert np.all(ours["Depth"][bg] >= 1e9) and np.all(cyc["Depth"][bg] >= 1e9)
    # The box has no UV map: 0, 0, 0 (Cycles' primitive_uv); the floor's third channel 1.
    box = inside & ((obj == 5) | (obj == 9))
    assert not ours["UV"][box].any() and not cyc["UV"][box].any()
    floor = inside & (obj == 1)
    assert np.all(ours["UV"][..., 2][floor] == 1.0) and np.all(cyc["UV"][..., 2][floor] == 1.0)
    print(report)


def test_surface_passes_not_named_unmade(bpy_addon, tmp_path):
    """The passes made here are no longer named in the 'does not make' warning."""
    import addon
    assert not any(label in ("Position", "UV", "Mist", "Object Index", "Material Index")
                   for _, _, label in addon.engine.UNMADE_PASSES)
    bpy = bpy_addon
    scene = _scene(bpy)
    scene.render.engine = "PHOTONMAP"
    cheap(scene, width=16, height=12, spp=1, photons=2_000, caustic_photons=200)
    seen = []
    listener = (lambda event, value: seen.append(value) if event == "warning" else None)
    addon.engine.status_listeners.append(listener)
    try:
        passes = read_layers(render_exr(bpy, scene, tmp_path / "w.exr", multilayer=True))
    finally:
        addon.engine.status_listeners.remove(listener)
    assert not [w for w in seen if "does not make" in w], seen
    for name in PASSES:
        assert name in passes, (name, sorted(passes))

