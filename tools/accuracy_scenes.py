"""Scenes and render helpers for the Cycles accuracy comparison (issue 4).

Shared by tools/make_references.py (Cycles references), bench/bench_accuracy_cycles.py
(docs/accuracy.md) and tests/test_accuracy_cycles.py. Needs the bpy wheel.

Every scene is set up in the current bpy session by `setup(name)`: the five example blends
(their camera, lights and materials) and extra scenes built here with bpy. All render at
WIDTH x HEIGHT (small: references stay tiny, tests stay fast).
"""
from __future__ import annotations

import math
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)
BLENDS = os.path.join(ROOT, "example_blends")
REF_DIR = os.path.join(ROOT, "tests", "references")
WIDTH, HEIGHT = 96, 72

import bpy  # noqa: E402

sys.path.insert(0, BLENDS)
import make_blends as mb  # noqa: E402  (bpy helpers: material, plane, box, sphere, light...)

sys.path.pop(0)


def ensure_addon():
    import addon
    if not hasattr(bpy.types.Scene, "photonmap"):
        addon.register()


# --- scenes ----------------------------------------------------------------------------
# kind: "diffuse" = only diffuse surfaces (targets: brightness 2 %, relMSE 0.02),
#       "specular" = glass / mirrors / glossy (target: brightness 5 %).

def _blend(name):
    def build():
        bpy.ops.wm.open_mainfile(filepath=os.path.join(BLENDS, name + ".blend"),
                                 load_ui=False)
    return build


def _diffuse_box():
    mb.reset()
    white = mb.material("white", "diffuse", (0.75, 0.75, 0.75))
    red = mb.material("red", "diffuse", (0.7, 0.12, 0.1))
    green = mb.material("green", "diffuse", (0.12, 0.55, 0.15))
    mb.cornell_box(white, red, green)
    mb.box("TallBlock", 1.0, 1.0, 2.0, white, (-0.7, 0.6, 1.0), (0, 0, math.radians(20)))
    mb.box("ShortBlock", 1.0, 1.0, 1.0, white, (0.8, -0.4, 0.5), (0, 0, math.radians(-15)))
    mb.light("RectLight", "AREA", (0, 0, 3.98), 150.0, rotation=(0, 0, 0),
             shape="RECTANGLE", size=1.2, size_y=0.6)
    mb.camera((0, -7.6, 2.0), (0, 0, 2.0), 38.0)


def _sun_point():
    mb.reset()
    white = mb.material("white", "diffuse", (0.8, 0.8, 0.8))
    blue = mb.material("blue", "diffuse", (0.15, 0.25, 0.7))
    orange = mb.material("orange", "diffuse", (0.8, 0.4, 0.1))
    mb.plane("Floor", 12, 12, white)
    mb.plane("Back", 12, 5, white, (0, 3, 2.5), (math.pi / 2, 0, 0))
    mb.box("Cube", 1.2, 1.2, 1.2, blue, (-1.0, 0.5, 0.6), (0, 0, math.radians(30)))
    mb.sphere("Ball", 0.7, orange, (1.2, -0.2, 0.7), segments=32, rings=16)
    mb.light("Sun", "SUN", (0, 0, 5), 2.0, rotation=(math.radians(40), 0,
                                                     math.radians(30)), angle=0.0)
    mb.light("Point", "POINT", (0.5, -2.0, 2.5), 150.0, color=(1.0, 0.9, 0.8),
             shadow_soft_size=0.2)
    mb.camera((0, -7.0, 3.0), (0, 0, 0.8), 45.0)


def _disk_spot():
    mb.reset()
    white = mb.material("white", "diffuse", (0.8, 0.8, 0.8))
    red = mb.material("red", "diffuse", (0.8, 0.1, 0.1))
    green = mb.material("green", "diffuse", (0.1, 0.7, 0.2))
    yellow = mb.material("yellow", "diffuse", (0.8, 0.7, 0.1))
    mb.plane("Floor", 10, 10, white)
    mb.plane("Back", 10, 5, white, (0, 2.5, 2.5), (math.pi / 2, 0, 0))
    mb.box("RedBox", 1.0, 1.0, 1.0, red, (-1.4, 0.5, 0.5), (0, 0, math.radians(15)))
    mb.sphere("GreenBall", 0.6, green, (0.2, 0.0, 0.6), segments=32, rings=16)
    mb.box("YellowBox", 0.7, 1.4, 0.5, yellow, (1.6, 0.3, 0.25), (0, 0, math.radians(-25)))
    mb.light("Disk", "AREA", (-1.0, -0.5, 3.0), 200.0, look_at=(-0.8, 0.3, 0.0),
             shape="DISK", size=1.0)
    # spot aimed so the floor and the green ball see both the full cone and its blend ring
    mb.light("Spot", "SPOT", (1.5, -1.5, 3.5), 400.0, look_at=(0.8, 0.2, 0.0),
             spot_size=math.radians(45.0), spot_blend=0.3, shadow_soft_size=0.1)
    mb.camera((0, -7.0, 3.2), (0, 0, 0.7), 42.0)


def _ellipse_scaled():
    mb.reset()
    white = mb.material("white", "diffuse", (0.8, 0.8, 0.8))
    teal = mb.material("teal", "diffuse", (0.1, 0.6, 0.6))
    purple = mb.material("purple", "diffuse", (0.5, 0.2, 0.7))
    mb.plane("Floor", 10, 10, white)
    mb.plane("Back", 10, 5, white, (0, 2.5, 2.5), (math.pi / 2, 0, 0))
    cube = mb.box("ScaledCube", 1.0, 1.0, 1.0, teal, (-0.9, 0.3, 0.75),
                  (0, 0, math.radians(25)))
    cube.scale = (1.6, 0.6, 1.5)  # non-uniform object scale (normals must follow)
    ball = mb.sphere("Ellipsoid", 0.5, purple, (1.2, -0.3, 0.5), segments=32, rings=16)
    ball.scale = (1.5, 1.0, 1.0)
    lamp = mb.light("Ellipse", "AREA", (0.0, -0.8, 3.2), 250.0, look_at=(0.2, 0.0, 0.0),
                    shape="ELLIPSE", size=1.0, size_y=0.5)
    lamp.scale = (1.5, 0.8, 1.0)  # object scale on the light: area = pi/4 * 1.5 * 0.4
    mb.camera((0, -7.0, 3.0), (0, 0, 0.8), 42.0)


def _mirror_glass():
    mb.reset()
    white = mb.material("white", "diffuse", (0.75, 0.75, 0.75))
    red = mb.material("red", "diffuse", (0.7, 0.12, 0.1))
    blue = mb.material("blue", "diffuse", (0.12, 0.2, 0.7))
    mirror = mb.material("mirror", "principled", (0.9, 0.9, 0.9), roughness=0.0,
                         metallic=1.0)
    glass = mb.material("glass", "glass", (1.0, 1.0, 1.0), ior=1.5)
    mb.cornell_box(white, red, blue)
    mb.box("MirrorPanel", 1.6, 0.05, 2.2, mirror, (-0.8, 1.3, 1.1),
           (0, 0, math.radians(25)))
    # The block and the ball stand 0.1 mm above the floor: at exact contact Cycles' image
    # is a rounding discontinuity (moving the whole scene up 1.913 m, or lifting the glass
    # 0.1 mm, gives the same image, 2.6 % brighter than at z = 0: light refracted out
    # through the block's bottom is lost there), which the test should not measure
    # (docs/accuracy.md, contact30). Ours is the same at contact and lifted.
    mb.box("GlassBlock", 0.8, 0.8, 1.0, glass, (0.9, -0.3, 0.5001), (0, 0, math.radians(30)))
    mb.sphere("GlassBall", 0.45, glass, (-0.5, -0.8, 0.4501), segments=48, rings=24)
    mb.light("CeilingLight", "AREA", (0, 0, 3.98), 150.0, rotation=(0, 0, 0),
             shape="SQUARE", size=1.0)
    mb.camera((0, -7.6, 2.0), (0, 0, 2.0), 38.0)


def _caustic_soft_spot():
    """Figure 8 with a spot of radius 0.15 m: a light Cycles' paths can hit through the
    glass ball, so it can render the caustic (slowly: the reference needs 64k spp)."""
    _blend("figure8_caustic")()
    bpy.data.objects["Spot"].data.shadow_soft_size = 0.15


def _figure7_mirror():
    """scenes/figure7_mirror.toml in Blender: the Figure 7 room with a perfect mirror
    floor and a small point light left of a panel that runs wall to wall from the ceiling
    down to 0.4 m. The room's right half is lit only through the slot and the mirror."""
    mb.reset()
    white = mb.material("white", "diffuse", (0.75, 0.75, 0.75))
    blue = mb.material("blue", "diffuse", (0.15, 0.2, 0.7))
    mirror = mb.material("perfect_mirror", "principled", (0.9, 0.9, 0.9), roughness=0.0,
                         metallic=1.0)
    h = 2.0
    mb.plane("Floor", 4, 4, mirror, (0, 0, 0))
    mb.plane("Ceiling", 4, 4, white, (0, 0, 4), (math.pi, 0, 0))
    mb.plane("Back", 4, 4, white, (0, h, h), (math.pi / 2, 0, 0))
    mb.plane("LeftWall", 4, 4, white, (-h, 0, h), (0, math.pi / 2, 0))
    mb.plane("RightWall", 4, 4, blue, (h, 0, h), (0, -math.pi / 2, 0))
    mb.box("Panel", 0.1, 4.0, 3.6, white, (-0.3, 0.0, 2.2))
    mb.light("Light", "POINT", (-1.5, 0.0, 2.0), 200.0, shadow_soft_size=0.1)
    mb.camera((0, -7.6, 2.0), (0, 0, 1.8), 38.0)


# The Principled row (issue 14): name, Principled BSDF inputs. Dielectrics from smooth to
# fully rough, clear glass, two metals, a clear-coated and a sheen ball.
PRINCIPLED_BALLS = (
    ("Smooth", dict(base_color=(0.8, 0.15, 0.1), roughness=0.0)),
    ("Glossy", dict(base_color=(0.8, 0.5, 0.1), roughness=0.25)),
    ("Satin", dict(base_color=(0.2, 0.6, 0.2), roughness=0.5)),
    ("Rough", dict(base_color=(0.1, 0.4, 0.8), roughness=1.0)),
    ("Glass", dict(base_color=(1.0, 1.0, 1.0), roughness=0.0, transmission_weight=1.0,
                   ior=1.5)),
    ("Gold", dict(base_color=(0.95, 0.7, 0.3), roughness=0.2, metallic=1.0)),
    ("Steel", dict(base_color=(0.6, 0.6, 0.62), roughness=0.5, metallic=1.0)),
    ("Coated", dict(base_color=(0.6, 0.05, 0.1), roughness=0.6, coat_weight=1.0,
                    coat_roughness=0.05)),
    ("Sheen", dict(base_color=(0.1, 0.1, 0.35), roughness=0.7, sheen_weight=1.0,
                   sheen_roughness=0.4, sheen_tint=(1.0, 0.9, 0.8))),
)
PRINCIPLED_INPUTS = {"base_color": "Base Color", "roughness": "Roughness",
                     "metallic": "Metallic", "ior": "IOR",
                     "transmission_weight": "Transmission Weight", "coat_weight": "Coat Weight",
                     "coat_roughness": "Coat Roughness", "sheen_weight": "Sheen Weight",
                     "sheen_roughness": "Sheen Roughness", "sheen_tint": "Sheen Tint"}


def principled(name, **inputs):
    """A material with one Principled BSDF node; `inputs` by PRINCIPLED_INPUTS key."""
    m, nt, out = mb.empty_material(name)
    n = nt.nodes.new("ShaderNodeBsdfPrincipled")
    for key, value in inputs.items():
        if isinstance(value, tuple):
            value = (*value, 1.0)
        n.inputs[PRINCIPLED_INPUTS[key]].default_value = value
    nt.links.new(n.outputs[0], out.inputs["Surface"])
    return m


def _principled_spheres():
    """Issue 14's scene as a new Blender user builds it: a row of Principled balls on a
    rough Principled floor, one area light, a dim grey world (Blender's default 0.05)."""
    mb.reset()
    floor = principled("Floor", base_color=(0.5, 0.5, 0.5), roughness=0.8)
    mb.plane("Floor", 30, 30, floor)
    n = len(PRINCIPLED_BALLS)
    for i, (name, inputs) in enumerate(PRINCIPLED_BALLS):
        x = (i - (n - 1) / 2) * 1.15
        mb.sphere(name, 0.5, principled(name, **inputs), (x, 0.0, 0.5), segments=48, rings=24)
    mb.light("AreaLight", "AREA", (-2.0, -3.0, 5.0), 500.0, look_at=(0.0, 0.0, 0.5),
             shape="SQUARE", size=2.0)
    mb.camera((0.0, -9.0, 3.0), (0.0, 0.0, 0.4), 62.0)
    world = bpy.data.worlds.new("World")
    if bpy.app.version < (5, 0, 0):
        world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.05, 0.05, 0.05, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    bpy.context.scene.world = world


SCENES = {
    "figure3_sphere": (_blend("figure3_sphere"), "specular"),
    "figure6_box": (_blend("figure6_box"), "specular"),
    "figure7_blocker": (_blend("figure7_blocker"), "specular"),
    "figure8_caustic": (_blend("figure8_caustic"), "specular"),
    "hdri_sphere": (_blend("hdri_sphere"), "specular"),
    "diffuse_box_rect": (_diffuse_box, "diffuse"),
    "sun_point": (_sun_point, "diffuse"),
    "disk_spot": (_disk_spot, "diffuse"),
    "ellipse_scaled": (_ellipse_scaled, "diffuse"),
    "mirror_glass": (_mirror_glass, "specular"),
    "caustic_soft_spot": (_caustic_soft_spot, "specular"),
    "figure7_mirror": (_figure7_mirror, "specular"),
    "principled_spheres": (_principled_spheres, "specular"),
}
# Scenes rendered at another resolution than WIDTH x HEIGHT.
SIZES = {"principled_spheres": (160, 120)}
# Scenes whose Cycles reference needs more samples than the default to converge: the
# caustic is found only by paths that hit the small spot through the glass. figure7_mirror
# (a 0.1 m point light seen through a mirror) is capped at 8192 spp so its reference takes
# minutes on 2 cores; references.json records its noise floor (reference_relmse_floor).
REFERENCE_SAMPLES = {"caustic_soft_spot": 65536, "figure7_mirror": 8192}


def setup(name, width=None, height=None):
    """Build / open scene `name` in the current bpy session; returns bpy.context.scene.
    The resolution defaults to the scene's (SIZES, else WIDTH x HEIGHT)."""
    ensure_addon()
    width = width or SIZES.get(name, (WIDTH, HEIGHT))[0]
    height = height or SIZES.get(name, (WIDTH, HEIGHT))[1]
    SCENES[name][0]()
    scene = bpy.context.scene
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = width, height, 100
    r.film_transparent = False
    r.use_border = False
    return scene


# --- renderers -------------------------------------------------------------------------

# The pixel filter both renderers use when compared (a Cycles setting that our add-on reads
# too: addon/export.pixel_filter_settings): a 1-pixel box, so a pixel is the plain mean
# over its area; feature cases about the filter pass their own.
COMPARE_FILTER = ("BOX", 1.0)


def set_pixel_filter(scene, kind="BOX", width=1.0):
    """Film > Pixel Filter (scene.cycles: BOX, GAUSSIAN, BLACKMAN_HARRIS; width in px)."""
    scene.cycles.pixel_filter_type = kind
    scene.cycles.filter_width = width


# Light Paths > Max Bounces of every comparison (the stored references were rendered so):
# Cycles' limits in set_cycles, ours (the same four settings) in set_photonmap_defaults.
COMPARE_BOUNCES = 32


def set_cycles(scene, samples, seed=0, pixel_filter=COMPARE_FILTER):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = samples
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    for attr in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
                 "volume_bounces", "transparent_max_bounces"):
        setattr(c, attr, COMPARE_BOUNCES)
    set_pixel_filter(scene, *pixel_filter)
    c.seed = seed
    scene.render.threads_mode = "AUTO"


def set_photonmap_defaults(scene, pixel_filter=COMPARE_FILTER):
    """Our engine at its default settings (every scene.photonmap property unset), with
    the pixel filter and the bounce limits set_cycles gives Cycles."""
    ensure_addon()
    set_pixel_filter(scene, *pixel_filter)
    scene.render.engine = "PHOTONMAP"
    pm = scene.photonmap
    for prop in pm.bl_rna.properties:
        if prop.identifier != "rna_type":
            pm.property_unset(prop.identifier)
    # The bounce limits Cycles gets in set_cycles (the photons (max photon depth 32) stay
    # within them; only photons past 29 bounces, a handful, leave the deepest regather
    # map). The add-on reads Cycles' own Light Paths properties when the Cycles add-on is
    # there (addon/export.light_path_settings): set them as set_cycles does; ours too (the
    # fallback without Cycles).
    cycles = getattr(scene, "cycles", None)
    for attr in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces"):
        if hasattr(pm, attr):
            setattr(pm, attr, COMPARE_BOUNCES)
    for attr in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
                 "volume_bounces", "transparent_max_bounces"):
        if cycles is not None and hasattr(cycles, attr):
            setattr(cycles, attr, COMPARE_BOUNCES)
    # Filter Glossy 0, as set_cycles renders the references: the add-on passes Cycles'
    # (default 1.0), which our camera paths (engine/filterglossy.py) and the maps' split
    # (engine/glossysplit.py) now follow.
    if cycles is not None and hasattr(cycles, "blur_glossy"):
        cycles.blur_glossy = 0.0
    # No clamp, as set_cycles renders the references (the add-on reads Cycles' Clamping,
    # default Indirect 10, when the Cycles add-on is there: addon/export.clamp_settings).
    for owner in (pm, cycles):
        if owner is not None and hasattr(owner, "sample_clamp_indirect"):
            owner.sample_clamp_direct = owner.sample_clamp_indirect = 0.0


def render_rgba(scene):
    """Render to a 32-bit linear EXR; returns ((H, W, 4) float32 top-to-bottom, seconds)."""
    s = scene.render.image_settings
    if hasattr(s, "media_type"):  # Blender 5.0+
        s.media_type = "IMAGE"
    s.file_format = "OPEN_EXR"
    s.color_depth = "32"
    s.color_mode = "RGBA"
    fd, path = tempfile.mkstemp(suffix=".exr", prefix="acc_")
    os.close(fd)
    try:
        scene.render.filepath = path
        scene.render.use_file_extension = False
        t0 = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        elapsed = time.perf_counter() - t0
        img = bpy.data.images.load(path, check_existing=False)
        try:
            w, h = img.size
            buf = np.empty(w * h * 4, np.float32)
            img.pixels.foreach_get(buf)
        finally:
            bpy.data.images.remove(img)
    finally:
        os.unlink(path)
    return buf.reshape(h, w, 4)[::-1].copy(), elapsed


def render_rgb(scene):
    """render_rgba without alpha: ((H, W, 3) float32, seconds)."""
    rgba, elapsed = render_rgba(scene)
    return rgba[:, :, :3].copy(), elapsed


def render_rgb_cached(scene, path):
    """render_rgb's image, saved to path (.npy) and loaded from it when it is there:
    ((H, W, 3), CPU s of the render; 0 from the cache)."""
    if os.path.isfile(path):
        return np.load(path), 0.0
    c0 = time.process_time()
    img, _ = render_rgb(scene)
    cpu = time.process_time() - c0
    np.save(path, img)
    return img, cpu


def render_cycles(name, samples, seed=0):
    scene = setup(name)
    set_cycles(scene, samples, seed)
    return render_rgb(scene)


def object_labels(name, samples=64):
    """Per-pixel object labels of scene `name` from Cycles coverage renders:
    ((H, W) uint8, object names); label i + 1 marks a pixel that object i covers fully
    (coverage >= 0.999 of `samples` box-filtered samples: edge pixels, which mix objects,
    are 0 like the background). One render per mesh object, the object white emission,
    everything else black emission, the world black."""
    scene = setup(name)
    set_cycles(scene, samples)
    objects = sorted((o for o in scene.objects if o.type == "MESH"), key=lambda o: o.name)
    white, black = (mb.empty_material(n) for n in ("_mask_white", "_mask_black"))
    for (m, nt, out), strength in ((white, 1.0), (black, 0.0)):
        em = nt.nodes.new("ShaderNodeEmission")
        em.inputs["Strength"].default_value = strength
        nt.links.new(em.outputs[0], out.inputs["Surface"])
    white, black = white[0], black[0]
    world = bpy.data.worlds.new("_mask_world")
    world.color = (0.0, 0.0, 0.0)
    if world.node_tree is not None:
        for node in world.node_tree.nodes:
            if node.type == "BACKGROUND":
                node.inputs["Strength"].default_value = 0.0
    scene.world = world
    for o in objects:
        for slot in o.material_slots:
            slot.link = "OBJECT"
    labels = None
    for i, target in enumerate(objects):
        for o in objects:
            for slot in o.material_slots:
                slot.material = white if o is target else black
        img, _ = render_rgb(scene)
        if labels is None:
            labels = np.zeros(img.shape[:2], np.uint8)
        labels[img[:, :, 0] >= 0.999] = i + 1
    return labels, [o.name for o in objects]


def object_means(img, labels, names):
    """{object name: mean RGB (3,) over its label's pixels} of an (H, W, 3) image."""
    return {n: img[labels == i + 1].mean(axis=0) for i, n in enumerate(names)
            if np.any(labels == i + 1)}


def export_ours(name):
    """(engine Scene, RenderSettings kwargs) of scene `name` at our default settings (every
    scene.photonmap property unset, COMPARE_FILTER), exported as the add-on exports it for
    a render: for many engine renders of one scene (seeds, regions) without the add-on's
    per-render export and EXR round trip."""
    from addon import export as ex
    import engine
    scene = setup(name)
    set_photonmap_defaults(scene)
    dg = bpy.context.evaluated_depsgraph_get()
    w, h = ex.render_size(scene.render)
    pm_scene, _ = ex.export_scene(engine, dg, width=w, height=h, render_visibility=True)
    return pm_scene, scene.photonmap.to_settings_kwargs(scene.render.film_transparent)


def render_ours(name, **overrides):
    scene = setup(name)
    set_photonmap_defaults(scene)
    for k, v in overrides.items():
        setattr(scene.photonmap, k, v)
    return render_rgb(scene)


# --- metrics ---------------------------------------------------------------------------

def relmse(x, ref):
    x = np.asarray(x, np.float64)
    ref = np.asarray(ref, np.float64)
    return float(np.mean((x - ref) ** 2 / (ref * ref + 0.01)))


def flip(x, ref, return_map=False):
    import flip_evaluator
    res = flip_evaluator.evaluate(np.ascontiguousarray(ref, np.float32),
                                  np.ascontiguousarray(x, np.float32), "HDR")
    return (float(res[1]), res[0]) if return_map else float(res[1])


def brightness(x, ref):
    return float(np.mean(x) / np.mean(ref))


def load_reference(name):
    """(H, W, 3) float32 Cycles reference of scene `name`: NAME.npy (tools/make_references.py)
    or the image of NAME.npz (tools/make_principled_reference.py)."""
    path = os.path.join(REF_DIR, name + ".npy")
    if os.path.isfile(path):
        return np.load(path).astype(np.float32)
    with np.load(os.path.join(REF_DIR, name + ".npz")) as z:
        return z["image"].astype(np.float32)


def load_labels(name):
    """(labels (H, W) uint8, object names) stored with scene `name`'s reference
    (object_labels), or None when its reference has none."""
    path = os.path.join(REF_DIR, name + ".npz")
    meta = load_scene_meta(name)
    if not os.path.isfile(path) or "objects" not in meta:
        return None
    with np.load(path) as z:
        return z["labels"], meta["objects"]


def load_scene_meta(name):
    """The reference's description: references.json's entry, else NAME.json ({} if none)."""
    import json
    meta = load_meta()
    if name in meta:
        return meta[name]
    path = os.path.join(REF_DIR, name + ".json")
    if not os.path.isfile(path):
        return {}
    with open(path) as f:
        return json.load(f)


def load_meta():
    import json
    path = os.path.join(REF_DIR, "references.json")
    if not os.path.isfile(path):
        return {}
    with open(path) as f:
        return json.load(f)
