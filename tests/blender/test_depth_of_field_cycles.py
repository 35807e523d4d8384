"""Camera depth of field against Cycles (issue 14, s26 dof): Blender's Depth of Field
(F-Stop, focus distance or focus object, blades, rotation, ratio) exported and rendered
with the thin lens Cycles uses.

Two emissive squares (6 px) on a black world, seen by a 100 mm perspective camera (64 x
32 px, box filter): one at 2 m, one at 6 m, the camera focused at 6 m. At F/0.5 the lens
radius is A = 100 mm / (2 x 0.5) = 0.1 m, so the near square spreads over the circle of
confusion of radius r = A (1/2 - 1/6) m^-1 x 177.8 px = 5.9 px (docs/accuracy.md "dof");
the far one stays sharp. Per square (each half of the image) we compare the flux, and the
spread (the image's standard deviation about the square's centroid, x and y) with
Cycles rendered live, and with the analytic spread: per axis
var = R_x^2 m2 + s^2 / 12 + 1/12 (the aperture's second moment m2 = 1/4 for a disk,
(1 + 2 cos^2(pi/n)) / 12 for an n-gon of circumradius 1; x divided by the ratio), the
square's s^2/12 and the pixel's box. An orthographic case (F/1.8, hexagon) checks Cycles'
orthographic lens: radius 1 / (2 f-stop) m, focus measured from the camera plane."""
import math
import os
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

pytestmark = pytest.mark.blender

WIDTH, HEIGHT = 64, 32
LENS_MM = 100.0
PX_PER_UNIT = (WIDTH / 2.0) / (18.0 / LENS_MM)  # 36 mm sensor, horizontal fit
NEAR, FAR = 2.0, 6.0
SQUARE_PX = 6.0
FSTOP = 0.5
# Orthographic: 2 m across 64 px (32 px/m), F/1.8: A = 1 / (2 x 1.8) m; the plane of focus
# at 6 m from the camera plane (not from the near clip plane at 0.5 m: measured, Cycles'
# far square stays exactly sharp, and a lens on the clip plane would spread the near one
# 9 % wider).
ORTHO_SCALE, ORTHO_FSTOP, ORTHO_CLIP = 2.0, 1.8, 0.5
CASES = {
    # name: (camera type, focus by object, blades, rotation (deg), ratio)
    "round_distance": ("PERSP", False, 0, 0.0, 1.0),
    "pentagon_object_anamorphic": ("PERSP", True, 5, 20.0, 1.5),
    "ortho_hexagon": ("ORTHO", False, 6, 0.0, 1.0),
}


@pytest.fixture(scope="module")
def acc(bpy_addon):
    sys.path.insert(0, os.path.join(ROOT, "tools"))
    import accuracy_scenes
    return accuracy_scenes


def _px_per_unit(kind, z):
    """Pixels per metre across the image at depth z."""
    return WIDTH / ORTHO_SCALE if kind == "ORTHO" else PX_PER_UNIT / z


def _scene(acc, kind, focus_object, blades, rotation, ratio):
    bpy, mb = acc.bpy, acc.mb
    acc.ensure_addon()
    scene = mb.reset()
    m, nt, out = mb.empty_material("glow")
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    em.inputs["Strength"].default_value = 1.0
    nt.links.new(em.outputs[0], out.inputs["Surface"])
    squares = []
    for name, z, cx in (("Near", NEAR, -14.0), ("Far", FAR, 14.0)):
        ppu = _px_per_unit(kind, z)
        squares.append(mb.plane(name, SQUARE_PX / ppu, SQUARE_PX / ppu, m, (cx / ppu, 0.0, -z)))
    cd = bpy.data.cameras.new("Camera")
    cd.lens, cd.sensor_width, cd.sensor_fit = LENS_MM, 36.0, "AUTO"
    cd.clip_start, cd.clip_end = 0.1, 100.0
    if kind == "ORTHO":
        cd.type, cd.ortho_scale, cd.clip_start = "ORTHO", ORTHO_SCALE, ORTHO_CLIP
    cd.dof.use_dof = True
    cd.dof.aperture_fstop = ORTHO_FSTOP if kind == "ORTHO" else FSTOP
    cd.dof.aperture_blades = blades
    cd.dof.aperture_rotation = math.radians(rotation)
    cd.dof.aperture_ratio = ratio
    if focus_object:
        cd.dof.focus_distance = 1.0  # ignored: the object decides
        cd.dof.focus_object = squares[1]
    else:
        cd.dof.focus_distance = FAR
    cam = bpy.data.objects.new("Camera", cd)
    cam.location = (0.0, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = WIDTH, HEIGHT, 100
    r.use_border = False
    return scene


def _moments(img):
    """Per half (near: columns < W/2, far: the rest): (flux, std x, std y) in pixels."""
    out = []
    for part in (img[:, :WIDTH // 2], img[:, WIDTH // 2:]):
        w = part[..., 0].astype(np.float64)
        ys, xs = np.mgrid[0:part.shape[0], 0:part.shape[1]] + 0.5
        f = w.sum()
        cx, cy = (w * xs).sum() / f, (w * ys).sum() / f
        out.append((f, math.sqrt((w * (xs - cx) ** 2).sum() / f),
                    math.sqrt((w * (ys - cy) ** 2).sum() / f)))
    return out


def _analytic(kind, blades, ratio, z):
    """(std x, std y) of the image of the square at depth z, pixels (module docstring)."""
    if kind == "ORTHO":
        A = 1.0 / (2.0 * ORTHO_FSTOP)
        R = A * abs(1.0 - z / FAR) * WIDTH / ORTHO_SCALE
    else:
        A = LENS_MM * 1e-3 / (2.0 * FSTOP)
        R = A * abs(1.0 / z - 1.0 / FAR) * PX_PER_UNIT
    m2 = 0.25 if blades < 3 else (1.0 + 2.0 * math.cos(math.pi / blades) ** 2) / 12.0
    base = SQUARE_PX ** 2 / 12.0 + 1.0 / 12.0
    return math.sqrt(R * R * m2 / ratio ** 2 + base), math.sqrt(R * R * m2 + base)


@pytest.mark.parametrize("name", sorted(CASES))
def test_depth_of_field_matches_cycles(acc, name):
    kind, focus_object, blades, rotation, ratio = CASES[name]
    scene = _scene(acc, kind, focus_object, blades, rotation, ratio)
    acc.set_cycles(scene, 256, seed=0)
    cyc, _ = acc.render_rgba(scene)
    acc.set_photonmap_defaults(scene)
    scene.photonmap.spp = 256
    scene.photonmap.photon_mapping = False
    ours, _ = acc.render_rgba(scene)
    (fc_n, sxc_n, syc_n), (fc_f, sxc_f, syc_f) = _moments(cyc)
    (fo_n, sxo_n, syo_n), (fo_f, sxo_f, syo_f) = _moments(ours)
    ax, ay = _analytic(kind, blades, ratio, NEAR)
    info = (f"{name}: near flux {fo_n:.2f} / Cycles {fc_n:.2f}, std x {sxo_n:.3f} / "
            f"{sxc_n:.3f} / analytic {ax:.3f}, y {syo_n:.3f} / {syc_n:.3f} / {ay:.3f}; far "
            f"flux {fo_f:.2f} / {fc_f:.2f}, std {sxo_f:.3f} / {sxc_f:.3f}; image mean "
            f"{ours[..., 0].mean():.5f} / {cyc[..., 0].mean():.5f}")
    print(info)
    # The blur: Cycles' and the analytic thin lens, within a few percent
    assert sxo_n == pytest.approx(sxc_n, rel=0.04), info
    assert syo_n == pytest.approx(syc_n, rel=0.04), info
    assert sxo_n == pytest.approx(ax, rel=0.04), info
    assert syo_n == pytest.approx(ay, rel=0.04), info
    # Not the pinhole's (the square's own 1.76 px): the test can tell
    assert syo_n > 1.5 * math.sqrt(SQUARE_PX ** 2 / 12.0 + 1.0 / 12.0)
    # In focus: sharp in both, the pinhole's image (6 whole pixels: var (s^2 - 1) / 12)
    assert sxo_f == pytest.approx(sxc_f, rel=0.03), info
    assert syo_f == pytest.approx(syc_f, rel=0.03), info
    assert sxo_f == pytest.approx(math.sqrt((SQUARE_PX ** 2 - 1.0) / 12.0), rel=0.01), info
    # Light moved, not lost: the flux and the image mean
    assert fo_n == pytest.approx(fc_n, rel=0.03), info
    assert fo_f == pytest.approx(fc_f, rel=0.03), info
    assert ours[..., 0].mean() == pytest.approx(cyc[..., 0].mean(), rel=0.03), info


def test_export_reads_blenders_depth_of_field(acc):
    """Cycles' blender/camera.cpp: radius = lens (m) / (2 f-stop) (orthographic
    1 / (2 f-stop)); a focus object's distance along the view axis; a focus object outside
    the scene, or a zero focus distance, warn naming the camera (no "not supported")."""
    from addon import export
    import engine as pm
    bpy = acc.bpy
    scene = _scene(acc, "PERSP", True, 6, 30.0, 1.25)
    cam = scene.camera
    cam.location = (0.3, -0.2, 1.0)  # the focus square 7 m along the view axis, off-axis
    bpy.context.view_layer.update()
    warnings = []
    c = export.convert_camera(pm, cam, WIDTH, HEIGHT, scene.render, warnings, scene.objects)
    assert warnings == []
    assert c.aperture_radius == pytest.approx(LENS_MM * 1e-3 / (2.0 * FSTOP))
    assert c.focus_distance == pytest.approx(FAR + 1.0)
    assert (c.aperture_blades, c.aperture_ratio) == (6, 1.25)
    assert c.aperture_rotation == pytest.approx(math.radians(30.0))
    # A focus object outside the scene: still used (as Cycles), with a warning
    other = bpy.data.objects.new("Elsewhere", None)
    import mathutils
    other.matrix_world = mathutils.Matrix.Translation((0.0, 0.0, -3.0))  # not evaluated
    cam.data.dof.focus_object = other
    c = export.convert_camera(pm, cam, WIDTH, HEIGHT, scene.render, warnings, scene.objects)
    assert c.focus_distance == pytest.approx(4.0)
    assert any("'Camera'" in w and "'Elsewhere'" in w for w in warnings), warnings
    # Focused at the camera itself: in focus everywhere, warned
    warnings.clear()
    cam.data.dof.focus_object = None
    cam.data.dof.focus_distance = 0.0
    c = export.convert_camera(pm, cam, WIDTH, HEIGHT, scene.render, warnings, scene.objects)
    assert not c.has_dof and any("'Camera'" in w for w in warnings), warnings
    # Off: a pinhole, no warning
    warnings.clear()
    cam.data.dof.use_dof = False
    c = export.convert_camera(pm, cam, WIDTH, HEIGHT, scene.render, warnings, scene.objects)
    assert not c.has_dof and warnings == []
    cam.data.type = "ORTHO"
    cam.data.dof.use_dof = True
    cam.data.dof.focus_distance = 3.0
    c = export.convert_camera(pm, cam, WIDTH, HEIGHT, scene.render, warnings, scene.objects)
    assert c.aperture_radius == pytest.approx(1.0 / (2.0 * FSTOP))
