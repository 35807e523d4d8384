"""The world volume: a homogeneous medium filling all space outside the objects (Blender's
World > Volume; Scene.world_medium, engine.scene.WorldMedium).

Cycles (Blender manual, World > Volume; intern/cycles/kernel/integrator/shade_volume.h):
the world's volume shader is the medium every ray starts in and returns to when it leaves
an object's volume; the world itself lies infinitely far away, so a ray escaping the scene
crosses an infinite length of it and keeps exp(-sigma_t x infinity) = 0 of the world's
light: the Background / HDRI and sun lamps light nothing through it and the camera sees
black where it sees no object (with Film > Transparent the pixels are opaque: alpha is
1 - the mean of the escaping ray's throughput, 0 there). Point, spot, area and mesh lights
inside it light the fog and the scene through it.

Here the world medium is one more row of the material table (world_material: no triangle
uses it), so engine/media.py's and engine/volumescatter.py's kernels read its extinction,
scattering and phase as any object's medium: a path outside every object's medium is in
that row (medium_row) instead of "none" (-1): camera paths start in it (unless the camera
is inside an object's medium), and a path leaving an object's medium through its back face
returns to it (media.after_continuation's, PhotonMedia.after_scatter's and
mediumstart.point_medium's `outside`). Segments in it are dimmed by exp(-sigma_t s)
(camera paths, final-gather rays, photons); shadow rays that meet no surface lie wholly in it
(integrator._medium_sigma); rays escaping to infinity scatter the lamps' light along
their whole length (escaping: a segment long enough that the rest is below 1e-13).
prepare_lights leaves out the world light and suns (lights/__init__.py), and
the camera sees black where its rays escape (background).

Shadow rays (from surfaces and from points in the fog) that cross transparent surfaces keep
exp(-sigma_t length) of it over their whole length (directlight.direct_light's and
volumescatter.in_scattered's world_sigma).

Limits: the part of such a ray inside a fog box on its way is counted in both media; a
channel with zero extinction still loses the world's light (Cycles keeps it there: a
warning says so).
"""
from __future__ import annotations

import numpy as np

from .scene import Material

# The name of the table row that holds the world medium (no mesh may use it: the table's
# last row, added after the scene's own materials).
ROW_NAME = "(world volume)"
# An escaping ray's segment in the world medium is cut where exp(-sigma_t s) falls to
# exp(-FAR_DEPTH) (1e-13: nothing an image shows lies beyond).
FAR_DEPTH = 30.0


def active(scene) -> bool:
    """Whether the scene has a world medium that dims or scatters (a WorldMedium with
    some extinction)."""
    wm = getattr(scene, "world_medium", None)
    return wm is not None and bool(np.any(wm.extinction > 0))


def world_material(scene):
    """The Material row holding the scene's world medium (its absorption, scattering and
    anisotropy; a surface no ray meets), or None without one (active)."""
    if not active(scene):
        return None
    wm = scene.world_medium
    row = Material(ROW_NAME, base_color=(0.0, 0.0, 0.0), alpha=0.0,
                   absorption=np.asarray(wm.absorption, np.float64),
                   scattering=np.asarray(wm.scattering, np.float64),
                   anisotropy=float(wm.anisotropy),
                   volume_emission=np.asarray(getattr(wm, "emission", np.zeros(3)), np.float64),
                   volume_only=True)
    return row


def table_materials(scene) -> list:
    """The materials of the scene's table, in order: its own, then the world medium's
    row (world_material) when it has one."""
    mats = [scene.materials[n] for n in scene.materials]
    row = world_material(scene)
    return mats if row is None else mats + [row]


def background(scene, d, camera=None) -> np.ndarray:
    """(N,3) the world's radiance along escaping rays d (N,3) as the camera sees it:
    lights.world.background_radiance, or black beyond a world volume (active). camera
    (N,) bool: the rays that are camera rays (or passed on through transparent surfaces:
    Cycles' Is Camera Ray), which see the scene's camera world where it has one
    (Scene.camera_background / camera_environment); None: none is."""
    if active(scene):
        return np.zeros((len(d), 3))
    from .lights.world import background_radiance
    out = background_radiance(scene, d)
    if camera is None or not has_camera_world(scene):
        return out
    rows = np.flatnonzero(camera)
    if len(rows):
        out = np.array(out, np.float64)
        env = getattr(scene, "camera_environment", None)
        out[rows] = (env.radiance(np.take(d, rows, axis=0)) if env is not None
                     else np.asarray(scene.camera_background, np.float64))
    return out


def has_camera_world(scene) -> bool:
    """The scene's camera rays see a world of their own (Scene.camera_background or
    camera_environment set)."""
    return (getattr(scene, "camera_environment", None) is not None
            or getattr(scene, "camera_background", None) is not None)


def medium_row(ctx) -> int:
    """The material row of the world medium in ctx.table (-1: none): the medium of every
    path outside the objects' media."""
    if not active(ctx.scene):
        return -1
    return len(ctx.scene.materials)


def far_length(ctx) -> float:
    """The length (m) of an escaping ray's segment in the world medium: where the
    smallest positive extinction has dimmed it to exp(-FAR_DEPTH)."""
    sigma_t = ctx.scene.world_medium.extinction
    return FAR_DEPTH / float(sigma_t[sigma_t > 0].min())


def escaping(ctx, prim, d, medium, row):
    """The escaping rays among prim (n,) (< 0: no surface met) that are in the world
    medium (medium (n,) int64 == row): (rows (K,) int64 into the n, prim (K,) a
    placeholder triangle (0: sample_segments reads it only for a medium not known),
    t (K,) float64 the far length in units of |d| (d (n,3))). K = 0 without a world
    medium or a scene without triangles."""
    if row < 0 or ctx.geo.count == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
    rows = np.flatnonzero((np.asarray(prim) == -1) & (np.asarray(medium) == row))
    if len(rows) == 0:
        return rows, np.zeros(0, np.int64), np.zeros(0)
    dl = np.linalg.norm(np.take(np.asarray(d, np.float64), rows, axis=0), axis=1)
    return rows, np.zeros(len(rows), np.int64), far_length(ctx) / np.maximum(dl, 1e-300)


def warnings_for(scene) -> list:
    """What the world medium changes that a user should know (the world's light off)."""
    if not active(scene):
        return []
    out = []
    sigma_t = scene.world_medium.extinction
    if np.any(sigma_t <= 0):
        out.append("world volume: a colour channel with no extinction lets the world's "
                   "light through in Cycles; here the world light and suns are off in "
                   "every channel")
    lamps = [li for li in scene.lights if li.kind != "SUN"]
    emitters = any(np.any(np.asarray(m.emission, np.float64) > 0)
                   or getattr(m, "emission_texture", None) is not None
                   or np.any(np.asarray(getattr(m, "volume_emission", 0.0), np.float64) > 0)
                   for m in scene.materials.values())
    glow = np.any(np.asarray(getattr(scene.world_medium, "emission", 0.0), np.float64) > 0)
    if not lamps and not emitters and not glow:
        # (newuser41: a World Volume under a sky and a sun rendered black, the reason
        # only in the effect report)
        out.append("world volume: it fills the space around the objects, so the world's "
                   "light and the sun lamps, infinitely far beyond it, light nothing (as in "
                   "Cycles) and no other light is left: the image is black. For fog lit by "
                   "the sky or the sun, give a box around the scene a Volume Scatter "
                   "material instead")
    return out


def effect_reason(scene) -> str:
    """The effect report's line for the world medium."""
    wm = scene.world_medium
    st = np.round(wm.extinction, 4).tolist()
    ss = np.round(np.asarray(wm.scattering, np.float64), 4).tolist()
    return (f"world volume: sigma_t {st} 1/m, sigma_s {ss} 1/m, g {wm.anisotropy:g} fills "
            "the space outside the objects; the world light (Background / HDRI) and sun "
            "lamps are off (infinitely far beyond it: T = 0) and the background reads black")
