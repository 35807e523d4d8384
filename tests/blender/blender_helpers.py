"""Helpers and fixtures for the Blender (bpy wheel) tests (imported by conftest.py).

bpy can be imported once per process; the add-on is registered once per session (the
register test unregisters and re-registers it itself). Heavy work (the extension install)
runs in subprocesses with their own Blender user directory.
"""
import math
import os
import sys

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)
BLENDS = os.path.join(ROOT, "example_blends")
PYTHON = sys.executable


def blender_ext_path():
    """Blender's extension tool inside the bpy wheel (site-packages/bpy/<ver>/scripts/...)."""
    import glob
    import site
    for sp in site.getsitepackages():
        hits = glob.glob(os.path.join(sp, "bpy", "*", "scripts", "addons_core", "bl_pkg",
                                      "cli", "blender_ext.py"))
        if hits:
            return sorted(hits)[-1]
    pytest.skip("blender_ext.py not found in the bpy wheel")


@pytest.fixture(scope="session")
def bpy_addon():
    bpy = pytest.importorskip("bpy")
    import addon
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()
    return bpy


@pytest.fixture()
def fresh_scene(bpy_addon):
    """Empty scene with our engine selected and cheap settings."""
    bpy = bpy_addon
    bpy.ops.wm.read_homefile(use_empty=True)
    from addon import engine
    engine._previous_frame_warnings.clear()  # no test's frame is another's next frame
    scene = bpy.context.scene
    scene.render.engine = "PHOTONMAP"
    cheap(scene)
    return scene


@pytest.fixture()
def open_ground(fresh_scene):
    """A grey ball on a 30 m ground under a dim grey world and one area light, seen from
    close by: nearly all the light the camera sees on the ground is direct, and most of
    the world's light lands where no gather ray ends (the photon-importance and
    gather-share tests)."""
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends as mb
    scene = mb.reset()
    grey = mb.material("grey", "principled", (0.5, 0.5, 0.5), roughness=1.0)
    mb.plane("Floor", 30, 30, grey)
    mb.sphere("Ball", 0.5, grey, (0, 0, 0.5), segments=24, rings=12)
    mb.set_world((0.05, 0.05, 0.05))
    mb.light("Area", "AREA", (1.0, -1.0, 3.0), 500.0, look_at=(0, 0, 0), size=1.0)
    mb.camera((0, -4, 1.5), (0, 0, 0.4))
    cheap(scene, width=32, height=24, spp=1, photons=20_000, caustic_photons=2_000)
    return scene


def cheap(scene, width=None, height=None, pct=None, spp=2, photons=20_000,
          caustic_photons=10_000):
    pm = scene.photonmap
    pm.spp = spp
    pm.photons = photons
    pm.caustic_photons = caustic_photons
    if width is not None:
        scene.render.resolution_x = width
    if height is not None:
        scene.render.resolution_y = height
    if pct is not None:
        scene.render.resolution_percentage = pct


def default_photonmap(scene):
    """Every Photon Mapping setting of scene back to its default (the tests share one
    Blender session, and a scene built by make_blends.reset keeps what an earlier test
    set: 10k caustic photons read a mirror-lit floor 4 % darker). Returns scene.photonmap."""
    pm = scene.photonmap
    for p in pm.bl_rna.properties:
        if p.identifier != "rna_type":
            pm.property_unset(p.identifier)
    return pm


def default_cycles(scene):
    """Every Cycles scene setting back to its default (Light Paths, pixel filter,
    caustics, ...): an earlier test's Transmission bounces 0 left in the shared session
    zeroed the reference's Transmission Indirect. Enums whose registered default is not
    one of their items (sampling_pattern, denoiser: the startup file's Tabulated Sobol
    would become an invalid 0, and Cycles' noise another) keep their value. Returns
    scene.cycles."""
    c = scene.cycles
    for p in c.bl_rna.properties:
        if p.identifier == "rna_type" or p.is_readonly:
            continue
        if p.type == "ENUM" and p.default not in {i.identifier for i in p.enum_items}:
            continue
        c.property_unset(p.identifier)
    return c


def store_cycles_means(path, means_of, **about):
    """Script entry of the tests whose Cycles image means are stored (tests/references/):
    registers the add-on in this process' Blender, means_of(bpy, tmp_path) -> {key: mean
    or list of means}, written to path as JSON with the Blender version and `about`."""
    import json
    import pathlib
    import tempfile
    import bpy
    import addon
    addon.register()
    with tempfile.TemporaryDirectory() as tmp:
        means = means_of(bpy, pathlib.Path(tmp))
    rounded = {k: [round(x, 7) for x in v] if isinstance(v, list) else round(v, 7)
               for k, v in means.items()}
    with open(path, "w") as f:
        json.dump({"blender": bpy.app.version_string, **about, "means": rounded}, f, indent=1)
        f.write("\n")


def stored_cycles_means(path):
    """The "means" that store_cycles_means wrote to path (JSON)."""
    import json
    with open(path) as f:
        return json.load(f)["means"]


def cycles_plain(scene, spp, bounces):
    """Cycles' sampling as the tests compare against it: CPU, seed 0, `spp` samples, no
    denoising, no adaptive sampling, no clamping, no glossy blur, `bounces` as Light
    Paths > Max Bounces (docs/units.md: the settings that change its image). Returns
    scene.cycles."""
    c = scene.cycles
    c.device, c.samples, c.seed = "CPU", spp, 0
    c.use_denoising = c.use_adaptive_sampling = False
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.max_bounces = bounces
    return c


def open_blend(bpy, name):
    bpy.ops.wm.open_mainfile(filepath=os.path.join(BLENDS, name), load_ui=False)
    scene = bpy.context.scene
    assert scene.render.engine == "PHOTONMAP"
    return scene


def render_exr(bpy, scene, path, multilayer=False):
    """Render with write_still to a linear float EXR; returns the file path."""
    s = scene.render.image_settings
    if hasattr(s, "media_type"):  # Blender 5.0+
        s.media_type = "MULTI_LAYER_IMAGE" if multilayer else "IMAGE"
        s.file_format = "OPEN_EXR_MULTILAYER" if multilayer else "OPEN_EXR"
    else:
        s.file_format = "OPEN_EXR_MULTILAYER" if multilayer else "OPEN_EXR"
    s.color_depth = "32"
    if not multilayer:
        s.color_mode = "RGBA"
    scene.render.filepath = str(path)
    scene.render.use_file_extension = False
    bpy.ops.render.render(write_still=True)
    assert os.path.isfile(path), f"render did not write {path}"
    return str(path)


def read_rgba(bpy, path):
    """EXR -> (H, W, 4) float32, rows top to bottom."""
    img = bpy.data.images.load(str(path), check_existing=False)
    try:
        w, h = img.size
        buf = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(buf)
        return buf.reshape(h, w, 4)[::-1].copy()
    finally:
        bpy.data.images.remove(img)


def ours_and_cycles_means(bpy, scene, tmp_path, cycles_blur):
    """(ours, Cycles) image means of the scene's RGB: ours first (the scene's engine,
    with engine.blurredpassage.CYCLES_BLUR set to cycles_blur for the render: the
    emulation of Cycles' blurred window passages, off by default), then Cycles."""
    from engine import blurredpassage
    was = blurredpassage.CYCLES_BLUR
    blurredpassage.CYCLES_BLUR = cycles_blur
    try:
        ours = float(read_rgba(bpy, render_exr(bpy, scene, tmp_path / "ours.exr"))
                     [..., :3].mean())
    finally:
        blurredpassage.CYCLES_BLUR = was
    scene.render.engine = "CYCLES"
    ref = float(read_rgba(bpy, render_exr(bpy, scene, tmp_path / "cycles.exr"))[..., :3].mean())
    return ours, ref


def read_layers(path):
    """Multilayer EXR -> {pass name: (H, W, C) array} for the first view layer."""
    import OpenEXR
    f = OpenEXR.File(str(path), separate_channels=True)
    chans = {}
    for part in f.parts:  # Blender 5 writes one part per pass
        chans.update(part.channels)
    passes = {}
    for full, ch in chans.items():
        parts = full.split(".")
        name = parts[-2] if len(parts) >= 3 else parts[0]
        passes.setdefault(name, []).append((parts[-1], ch.pixels))
    out = {}
    order = "RGBAXYZV"
    for name, lst in passes.items():
        # (The UV pass' channels are U, V, A in that order; Cryptomatte's are lowercase
        # r, g, b, a: the spec's names.)
        seq = "UVA" if {c for c, _ in lst} == {"U", "V", "A"} else order
        lst.sort(key=lambda t: seq.index(t[0].upper()) if t[0].upper() in seq else 99)
        out[name] = np.stack([np.asarray(p, dtype=np.float32) for _, p in lst], axis=2)
    return out


def project(bpy, scene, point):
    """World point -> (row, col) pixel of the rendered image (rows top to bottom)."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector
    co = world_to_camera_view(scene, scene.camera, Vector(point))
    r = scene.render
    w = int(r.resolution_x * r.resolution_percentage / 100)
    h = int(r.resolution_y * r.resolution_percentage / 100)
    col = int(math.floor(co.x * w))
    row = int(math.floor((1.0 - co.y) * h))
    return row, col


def render_luminance(bpy, scene, path):
    """Render scene to the EXR at path and return its Rec.709 luminance (H, W)."""
    render_exr(bpy, scene, str(path))
    return luminance(read_rgba(bpy, str(path))[..., :3])


def luminance(rgb):
    rgb = np.asarray(rgb)
    return 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]


def node_material(bpy, name):
    """(material, node tree, Material Output): a new material with an empty node tree
    but its output (use_nodes is implied from Blender 5)."""
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    nt = m.node_tree
    nt.nodes.clear()
    return m, nt, nt.nodes.new("ShaderNodeOutputMaterial")


def glass_or_diffuse_material(bpy, name, kind, rgb, ior=1.5):
    """A material of one node: a smooth Glass BSDF (kind "glass", IOR ior) or a Diffuse
    BSDF, of colour rgb (3,) (the panes' and their floors' in the pane tests)."""
    m, nt, out = node_material(bpy, name)
    n = nt.nodes.new("ShaderNodeBsdfGlass" if kind == "glass" else "ShaderNodeBsdfDiffuse")
    n.inputs["Color"].default_value = (*rgb, 1.0)
    if kind == "glass":
        n.inputs["Roughness"].default_value = 0.0
        n.inputs["IOR"].default_value = ior
    nt.links.new(n.outputs[0], out.inputs["Surface"])
    return m


def convert_material(m):
    """The add-on's export of material m (addon.materials.MaterialConverter)."""
    from addon.core import load_engine
    from addon.materials import MaterialConverter
    return MaterialConverter(load_engine()).convert(m)


def black_world(bpy, scene, strength=0.0):
    """A new World of Background strength `strength` (0: black) on scene."""
    return world_color(bpy, scene, None, strength)


def world_color(bpy, scene, rgb, strength=1.0):
    """A new World on scene whose Background has colour rgb (None: the node's default)
    and `strength`. Returns the world."""
    world = bpy.data.worlds.new("World")
    scene.world = world
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    bg = next(n for n in world.node_tree.nodes if n.type == "BACKGROUND")
    bg.inputs["Strength"].default_value = strength
    if rgb is not None:
        bg.inputs["Color"].default_value = (*rgb, 1.0)
    return world


def sun_light(bpy, scene, rotation, energy=3.0):
    """A Sun of strength `energy` turned by the Euler angles `rotation` (radians; the
    light travels along the turned -Z), linked to scene. Returns the object."""
    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    sun.data.energy = float(energy)
    sun.rotation_euler = tuple(rotation)
    scene.collection.objects.link(sun)
    return sun


def export_warnings(bpy) -> list:
    """The warnings the add-on's export gives for the current scene (8 x 8, no render)."""
    from addon import export
    from addon.core import load_engine
    out, _ = export.export_scene(load_engine(), bpy.context.evaluated_depsgraph_get(),
                                 width=8, height=8)
    return out.warnings


def looking_down_camera(bpy, scene, height, ortho_scale=None, lens=None):
    """A camera at (0, 0, height) looking down -Z (x across the image), orthographic of
    width ortho_scale, or perspective of focal length lens; the scene's camera."""
    cam = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    if ortho_scale is not None:
        cam.data.type, cam.data.ortho_scale = "ORTHO", float(ortho_scale)
    if lens is not None:
        cam.data.lens = float(lens)
    cam.location = (0.0, 0.0, float(height))
    scene.collection.objects.link(cam)
    scene.camera = cam
    return cam


def render_pixel_centres(bpy, scene, path, engine, spp=16):
    """RGBA (H,W,4) of a direct-light-only render whose samples all sit near the pixels'
    centres (a Gaussian pixel filter 0.01 px wide, both engines): a node tree's value
    per pixel, with steps between two centres reading alike in both. Cycles plain
    (no bounces); ours with photon mapping off."""
    scene.render.engine = engine
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "GAUSSIAN", 0.01
    if engine == "CYCLES":
        cycles_plain(scene, spp, 0)
    else:
        cheap(scene, spp=spp, photons=1_000, caustic_photons=0)
        scene.photonmap.photon_mapping = False
    return read_rgba(bpy, render_exr(bpy, scene, path))


def roof_window_room(bpy, scene):
    """A 4 x 4 x 2 m closed grey room (albedo 0.6, zero-thickness walls, as users model
    them) whose roof has a 1 x 1 m hole centred over the floor's middle, under a white
    world of strength 1; 32 x 32 px. The caller fills the hole (a pane, a light portal or
    nothing) and sets the camera. Returns the grey material."""
    import math
    sys.path.insert(0, os.path.join(ROOT, "example_blends"))
    import make_blends

    def plane(loc, rot, scale):
        bpy.ops.mesh.primitive_plane_add(size=1, location=loc, rotation=rot)
        ob = bpy.context.object
        ob.scale = scale
        ob.data.materials.append(grey)
        return ob
    grey = glass_or_diffuse_material(bpy, "Grey", "diffuse", (0.6,) * 3)
    plane((0, 0, 0), (0, 0, 0), (4.0, 4.0, 1.0)).name = "Floor"
    for k in range(4):
        a = k * math.pi / 2
        plane((2.0 * math.cos(a), 2.0 * math.sin(a), 1.0), (0.0, math.pi / 2, a),
              (2.0, 4.0, 1.0))
    # the roof round the hole: two 4 x 1.5 strips and two 1.5 x 1 strips
    for y in (1.25, -1.25):
        plane((0, y, 2.0), (0, 0, 0), (4.0, 1.5, 1.0))
    for x in (1.25, -1.25):
        plane((x, 0, 2.0), (0, 0, 0), (1.5, 1.0, 1.0))
    scene.world = bpy.data.worlds.new("World")
    make_blends.set_world((1.0, 1.0, 1.0), 1.0)
    scene.render.resolution_x = scene.render.resolution_y = 32
    scene.render.resolution_percentage = 100
    return grey


def renders_by_switch(bpy, scene, tmp_path, module, name, seeds=(0, 1)):
    """{(on, seed): (H, W, 3) float64} of our renders of scene with module.name (an
    engine switch, e.g. engine.portal.ENABLED) True and False at each seed; the switch and
    the seed restored after."""
    old = getattr(module, name)
    films = {}
    try:
        for on in (True, False):
            setattr(module, name, on)
            for seed in seeds:
                scene.photonmap.seed = seed
                films[on, seed] = read_rgba(bpy, render_exr(
                    bpy, scene, tmp_path / f"ours{on}{seed}.exr"))[..., :3].astype(np.float64)
    finally:
        setattr(module, name, old)
        scene.photonmap.seed = 0
    return films


def light_portal(bpy, scene, location, size=1.0, energy=10.0):
    """A square Area light of side `size` with Cycles' Portal on at `location`, its -Z
    (down) into the room; the object."""
    ld = bpy.data.lights.new("Portal", "AREA")
    ld.energy, ld.size = energy, size
    ld.cycles.is_portal = True
    ob = bpy.data.objects.new("Portal", ld)
    ob.location = location
    scene.collection.objects.link(ob)
    return ob


def principled_material(bpy, name, colour, roughness):
    """A new node material of its Principled BSDF with Base Color `colour` (RGB) and
    `roughness`."""
    m = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0):
        m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*colour, 1.0)
    p.inputs["Roughness"].default_value = roughness
    return m


def block_means(img, size=12):
    """(H/size, W/size) means of `size` x `size` blocks of an (H,W) image."""
    h, w = img.shape[:2]
    return img[:h // size * size, :w // size * size].reshape(
        h // size, size, w // size, size).mean(axis=(1, 3))


def compare_settings(scene, cycles_spp=256):
    """The settings cycles_and_ours renders both engines with: Cycles plain at cycles_spp
    (12 bounces) with its default indirect clamp 10, which ours reads too."""
    cycles_plain(scene, cycles_spp, 12)
    scene.cycles.sample_clamp_indirect = 10.0


def cycles_luminance(bpy, scene, tmp_path, cycles_spp=256):
    """Cycles' luminance image (H, W) of scene at compare_settings."""
    scene.render.engine = "CYCLES"
    compare_settings(scene, cycles_spp)
    return render_luminance(bpy, scene, tmp_path / "cycles.exr")


def ours_luminance(bpy, scene, tmp_path, cycles_spp=256, ours_spp=32):
    """Our luminance image (H, W) of scene at compare_settings and ours_spp samples (the
    same image whether or not Cycles rendered the scene first)."""
    compare_settings(scene, cycles_spp)
    scene.render.engine = "PHOTONMAP"
    scene.photonmap.spp = ours_spp
    return render_luminance(bpy, scene, tmp_path / "ours.exr")


def cycles_and_ours(bpy, scene, tmp_path, cycles_spp=256, ours_spp=32):
    """(ours, Cycles) luminance images of scene: Cycles plain at cycles_spp (12 bounces,
    its default indirect clamp 10, which ours reads too), then ours at ours_spp."""
    ref = cycles_luminance(bpy, scene, tmp_path, cycles_spp)
    return ours_luminance(bpy, scene, tmp_path, cycles_spp, ours_spp), ref


def cycles_block_means(bpy, builds, tmp_path):
    """{key: Cycles' 12 x 12 block means (luminance, flattened)} of each scene
    builds[key]() at compare_settings, rendered now (the stored references of the hair,
    particle hair and point cloud tests)."""
    return {key: block_means(cycles_luminance(bpy, build(), tmp_path)).ravel().tolist()
            for key, build in builds.items()}


def stored_block_means(path, key, shape=(6, 8)):
    """The stored cycles_block_means of `key` in the JSON at path, as (rows, columns)."""
    return stored_cycles_means(path)[key].reshape(shape)


def stored_cycles_means(path):
    """{key: float or (N,) float64 array} of a stored Cycles reference JSON
    (store_cycles_means wrote it)."""
    import json
    with open(path) as f:
        means = json.load(f)["means"]
    return {k: np.asarray(v, np.float64) if isinstance(v, list) else v
            for k, v in means.items()}


def assert_stored_means_are_now(stored, now, rtol=1e-3):
    """The slow re-checks of stored Cycles references: the same keys, every value within
    rtol (seeded renders: the same numbers up to float summation order)."""
    assert set(now) == set(stored), (sorted(now), sorted(stored))
    for k, v in now.items():
        np.testing.assert_allclose(np.asarray(v, np.float64), stored[k], rtol=rtol,
                                   atol=1e-7, err_msg=k)


