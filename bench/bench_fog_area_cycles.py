"""Fog lit by area lights and thin fog (fog37, issue 14): ours against live Cycles at
equal samples. Direct light only (Cycles Light Paths Max Bounces 0, Volume bounces 0;
ours photon mapping off), 64 x 48, box filter. Scenes (a Principled Volume box 2.4 x 2.4
x 1.2 m over a white floor, Color 0.8 / 0.7 / 0.6, Anisotropy 0.3):
  area        an 0.8 m area light above the box (Density 0.6)
  area thin   the same, Density 0.08 (optical depth ~0.1-0.2 across the box)
  soft box    an area light of Spread 40 degrees inside a taller thin box (Density 0.15)
  spot thin   a 30-degree spot above the thin box (Density 0.15)
  lamp in fog a point light of radius 0.1 inside that box
  world       the Density 0.6 box under a white world (strength 1), no lamp
Per scene and variant: relMSE ((x - r)^2 / (r^2 + 0.01), RGB, mean over seeds) of the
image and of the fog's 9 x 9 block against Cycles at REF_SPP, the image mean over the
reference's, seconds a render. Variants (engine/volumescatter.py module switches,
VARIANTS below; FOG37_VARIANTS picks some, separated by ";", FOG37_SCENES by ","):
  before                equiangular towards point / spot lights only (s36), share 1/2,
                        aimed at a lamp's centre, random numbers
  area, centre          area lights aimed at too, at their centre; a lamp's peak
                        widened by its radius
  area, centre widened  an area light's peak widened by sqrt(A / pi) too
  + adaptive share      the exponential's share tau / (tau + rho) in [0.1, 0.9]
                        (adaptive_share; share 1/2 above: the bounds 0.5, 0.5)
  + stratified          and the distances' numbers stratified over the pixel's samples
  stratified alone      s36's sampling with stratified numbers
  area, stratified      area lights (centre), share 1/2, stratified
  after (the defaults)  the module's defaults (centre widened, adaptive, stratified), and
                        the surfaces seen through the fog box shaded with the stratified
                        sampler (integrator.UNBENT_STRATIFIED; every variant but "before")
  after, surfaces through the fog random   that last one off
  cycles                Cycles itself at the same samples (seeds 1..SEEDS)
fog37's variants that aimed at a random point on an area light (AREA_AIM_RANDOM) or set
the share by the optical depth alone (SHARE_ADAPTIVE off) are gone with those switches
(s38); their rows are in docs/accuracy.md, fog37.

    PYTHONPATH=$PWD .venv/bin/python bench/bench_fog_area_cycles.py [SPP [SEEDS [REF_SPP]]]

References are cached in /tmp/fog37-ref-<scene>-<REF_SPP>.npy.
"""
import math, os, sys, time
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT); sys.path.insert(0, os.path.join(ROOT, "tests", "blender"))
sys.path.insert(0, os.path.join(ROOT, "example_blends"))
import numpy as np
import bpy, addon
if not hasattr(bpy.types.Scene, "photonmap"):
    addon.register()
from blender_helpers import (black_world, cheap, cycles_plain, default_photonmap, project,
                             read_rgba, render_exr)
import make_blends as mb
from engine import integrator as EI, volumescatter as vs

SPP = int(sys.argv[1]) if len(sys.argv) > 1 else 16
SEEDS = int(sys.argv[2]) if len(sys.argv) > 2 else 4
REF_SPP = int(sys.argv[3]) if len(sys.argv) > 3 else 4096
ONLY = os.environ.get("FOG37_SCENES")
TMP = "/tmp/fog37"
os.makedirs(TMP, exist_ok=True)


def fog(name, density):
    m, nt, out = mb.empty_material(name)
    v = nt.nodes.new("ShaderNodeVolumePrincipled")
    v.inputs["Color"].default_value = (0.8, 0.7, 0.6, 1.0)
    v.inputs["Density"].default_value = density
    v.inputs["Anisotropy"].default_value = 0.3
    nt.links.new(v.outputs[0], out.inputs["Volume"])
    return m


def build(kind):
    scene = mb.reset()
    default_photonmap(scene)
    mb.plane("Floor", 8, 8, mb.material("white", "diffuse", (0.8, 0.8, 0.8)))
    if kind in ("area", "area thin"):
        mb.box("Fog", 2.4, 2.4, 1.2, fog("fog", 0.6 if kind == "area" else 0.08),
               location=(0.0, 0.0, 1.0))
        mb.light("Area", "AREA", (0.5, 0.3, 2.5), 300.0, look_at=(0, 0, 0), size=0.8)
    elif kind == "soft box":
        mb.box("Fog", 2.4, 2.4, 2.6, fog("fog", 0.15), location=(0.0, 0.0, 1.4))
        light = mb.light("Area", "AREA", (0.2, 0.1, 2.4), 300.0, look_at=(0, 0, 0), size=0.5)
        light.data.spread = math.radians(40.0)
    elif kind == "world":
        mb.box("Fog", 2.4, 2.4, 1.2, fog("fog", 0.6), location=(0.0, 0.0, 1.0))
    elif kind == "lamp in fog":
        mb.box("Fog", 2.4, 2.4, 1.2, fog("fog", 0.15), location=(0.0, 0.0, 1.0))
        mb.light("Point", "POINT", (0.3, 0.2, 1.1), 60.0, shadow_soft_size=0.1)
    elif kind == "spot thin":
        mb.box("Fog", 2.4, 2.4, 1.2, fog("fog", 0.15), location=(0.0, 0.0, 1.0))
        mb.light("Spot", "SPOT", (0.0, 0.0, 3.0), 400.0, look_at=(0, 0, 0),
                 spot_size=math.radians(30.0), spot_blend=0.3, shadow_soft_size=0.0)
    mb.camera((0.0, -5.0, 1.2), (0.0, 0.0, 0.8), fov_deg=45.0)
    black_world(bpy, scene, strength=1.0 if kind == "world" else 0.0)
    scene.render.resolution_x, scene.render.resolution_y = 64, 48
    scene.render.resolution_percentage = 100
    scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
    return scene


def render(scene, engine, spp, seed):
    scene.render.engine = engine
    c = cycles_plain(scene, spp, 0)
    c.volume_bounces = 0
    c.seed = seed
    if engine != "CYCLES":
        cheap(scene, spp=spp)
        scene.photonmap.photon_mapping = False
        scene.photonmap.seed = seed
    t = time.perf_counter()
    img = read_rgba(bpy, render_exr(bpy, scene, os.path.join(TMP, "bench.exr")))[..., :3]
    return img.astype(np.float64), time.perf_counter() - t


def rel_mse(x, r):
    return float(np.mean((x - r) ** 2 / (r * r + 0.01)))


DEFAULTS = {k: getattr(vs, k) for k in ("EQUIANGULAR_AREA", "EXP_SHARE_THIN", "EXP_SHARE_THICK",
                                        "AREA_WIDEN", "EQ_RADIUS", "STRATIFIED")}
BASE = dict(EQUIANGULAR_AREA=True, EXP_SHARE_THIN=0.5, EXP_SHARE_THICK=0.5, AREA_WIDEN=0.0,
            EQ_RADIUS=True, STRATIFIED=False)
ADAPT = dict(EXP_SHARE_THIN=0.1, EXP_SHARE_THICK=0.9)
VARIANTS = {
    "before": dict(EQUIANGULAR_AREA=False, EQ_RADIUS=False),
    "area, centre": dict(),
    "area, centre widened": dict(AREA_WIDEN=1.0),
    "+ adaptive share": dict(ADAPT, AREA_WIDEN=1.0),
    "+ stratified": dict(ADAPT, AREA_WIDEN=1.0, STRATIFIED=True),
    "stratified alone": dict(EQUIANGULAR_AREA=False, EQ_RADIUS=False, STRATIFIED=True),
    "area, stratified": dict(STRATIFIED=True),
    "after (the defaults)": DEFAULTS,
    "after, surfaces through the fog random": dict(DEFAULTS, UNBENT=False),
}
if os.environ.get("FOG37_VARIANTS"):
    VARIANTS = {k: v for k, v in VARIANTS.items() if k in os.environ["FOG37_VARIANTS"].split(";")}
print(f"| scene | variant | spp | relMSE image | relMSE fog block | mean / ref | s |")
print("|---|---|---|---|---|---|---|")
for kind in ("area", "area thin", "soft box", "spot thin", "lamp in fog", "world"):
    if ONLY and kind not in ONLY.split(","):
        continue
    scene = build(kind)
    ref_file = os.path.join(TMP, f"ref-{kind.replace(' ', '_')}-{REF_SPP}.npy")
    if os.path.exists(ref_file):
        ref = np.load(ref_file)
    else:
        ref = render(scene, "CYCLES", REF_SPP, 12345)[0]
        np.save(ref_file, ref)
    y, x = project(bpy, scene, (0.0, 0.0, 1.0))
    blk = (slice(y - 4, y + 5), slice(x - 4, x + 5))
    for name in (*VARIANTS, "cycles"):
        errs, berrs, means, secs = [], [], [], []
        for seed in range(1, SEEDS + 1):
            if name == "cycles":
                img, sec = render(scene, "CYCLES", SPP, seed)
            else:
                settings = {**BASE, **VARIANTS[name]}
                # integrator.UNBENT_STRATIFIED: hits reached through the fog box's
                # invisible faces shaded with the stratified sampler (off in "before")
                EI.UNBENT_STRATIFIED = settings.pop("UNBENT", name != "before")
                for key, value in settings.items():
                    setattr(vs, key, value)
                img, sec = render(scene, "PHOTONMAP", SPP, seed)
            errs.append(rel_mse(img, ref))
            berrs.append(rel_mse(img[blk], ref[blk]))
            means.append(img.mean() / ref.mean())
            secs.append(sec)
        print(f"| {kind} | {name} | {SPP} | {np.mean(errs):.5f} | {np.mean(berrs):.5f} | "
              f"{np.mean(means):.4f} | {np.mean(secs):.2f} |", flush=True)
