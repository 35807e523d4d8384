"""Ray visibility and holdout in the engine (docs/scene_format.md, "Ray visibility").

The Blender tests (tests/blender/test_blender_fidelity.py) compare each flag with Cycles;
these check the engine's own invariants without bpy.
"""
import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.geometry import ALL_RAYS, CAMERA, DIFFUSE, SHADOW, prepare
from engine.scene import Material
from engine.scenefile import SceneFileError, load_scene
from engine.visibility import VisibilityAccel
from engine.accel import Accel

FLAGS = ("visible_camera", "visible_diffuse", "visible_glossy", "visible_transmission",
         "visible_shadow")


def _room(ghost=None):
    """A floor and a back wall under a point light, seen at an angle; `ghost`: flags of
    a large plane between the light and the floor (None: no plane)."""
    s = PaperScene(width=40, height=30)
    s.add_material(Material("white", (0.8, 0.8, 0.8)))
    s.add_material(Material("red", (0.8, 0.1, 0.1)))
    s.add_plane((0, 0, 0), (0, 0, 1), 6.0, "white", name="floor")
    s.add_plane((0, 2, 1.5), (0, -1, 0), (6.0, 3.0), "red", name="wall")
    s.add_point_light((0, 0, 2.5), power=300.0)
    if ghost is not None:
        mesh = s.add_plane((0, 0, 1.5), (0, 0, 1), 2.0, "white", name="ghost")
        for k, v in ghost.items():
            setattr(mesh, k, v)
    s.set_camera((0, -5, 3), (0, 0, 0.5), view_angle=50)
    return s


def _grow(mask):
    out = mask.copy()
    out[1:] |= mask[:-1]
    out[:-1] |= mask[1:]
    out[:, 1:] |= mask[:, :-1]
    out[:, :-1] |= mask[:, 1:]
    return out


def _inside(mask):
    """Pixels of mask whose 4 neighbours are in it too (no partly covered edge pixels)."""
    return ~_grow(~mask)


def _settings(**kw):
    return RenderSettings(**{**dict(spp=4, photons=40_000, caustic_photons=0, seed=3), **kw})


def test_mesh_invisible_to_every_ray_changes_nothing():
    """A plane no ray sees leaves direct light, indirect light (gathering and photons:
    they land on it and pass on, and none leave it) and the image as they were. 16 spp:
    at 4 the indirect means of the two differed by up to 4.4 % over seeds (gather noise)."""
    base = _room().render(_settings(spp=16))
    ghost = _room({f: False for f in FLAGS}).render(_settings(spp=16))
    solid = _room({}).render(_settings(spp=16))
    for name in ("direct", "indirect"):
        a, b = getattr(base, name).mean(), getattr(ghost, name).mean()
        assert abs(b / a - 1) < 0.04, (name, a, b)
    # The control: a visible plane there changes the image a lot.
    assert abs(solid.direct.mean() / base.direct.mean() - 1) > 0.15


def test_camera_invisible_mesh_keeps_shadow_and_gathered_light():
    """visible_camera off: the camera sees through the plane, its shadow stays."""
    base = _room().render(_settings())
    hidden = _room({"visible_camera": False}).render(_settings())
    solid = _room({}).render(_settings())
    # Where the solid plane hides the floor, the hidden one shows the floor in its shadow.
    closer = _inside(solid.depth < base.depth - 0.5)
    assert closer.sum() > 20
    np.testing.assert_allclose(hidden.depth[closer], base.depth[closer], rtol=1e-4)
    # Its shadow (a 2 m plane 1 m under the light) darkens the floor as the solid one's.
    assert hidden.direct.mean() < 0.8 * base.direct.mean()
    seen = ~_grow(_grow(solid.depth < base.depth - 0.5))
    np.testing.assert_allclose(hidden.direct[seen].mean(), solid.direct[seen].mean(), rtol=0.02)


def test_shadow_invisible_mesh_casts_no_shadow():
    base = _room().render(_settings(photon_mapping=False))
    unshadowed = _room({"visible_shadow": False, "visible_camera": False}).render(
        _settings(photon_mapping=False))
    np.testing.assert_allclose(unshadowed.direct, base.direct, rtol=1e-4, atol=1e-6)


def test_holdout_cuts_alpha_and_colour():
    s = _room({"holdout": True})
    film = s.render(_settings(film_transparent=True))
    solid = _room({}).render(_settings(film_transparent=True))
    base = _room().render(_settings(film_transparent=True))
    hole = _inside(solid.depth < base.depth - 0.5)
    assert hole.sum() > 20
    outside = ~_grow(_grow(solid.depth < base.depth - 0.5))
    assert film.alpha[hole].max() == 0.0 and film.combined[hole].max() == 0.0
    np.testing.assert_array_equal(film.alpha[outside], base.alpha[outside])
    # To other rays the holdout is a black surface: it still shadows the floor.
    assert film.direct[outside].mean() < base.direct[outside].mean()


def test_one_bvh_unless_flags_differ():
    s = _room({"visible_camera": False})
    s.validate()
    geo, _ = prepare(s)
    acc = VisibilityAccel(geo.vertices32, geo.faces32, geo.visibility, Accel)
    assert acc.has_invisible and acc.for_class(SHADOW) is acc.full
    assert acc.for_class(CAMERA) is not acc.full
    assert acc.for_class(DIFFUSE) is acc.full
    ghost = np.nonzero(geo.visibility != ALL_RAYS)[0]
    # A ray straight down through the ghost plane: camera rays reach the floor (and
    # report the floor's triangle index in the full table), shadow rays the ghost.
    o = np.array([[0.1, 0.1, 2.0]]) - geo.offset
    d = np.array([[0.0, 0.0, -1.0]])
    _, prim_cam, _, _ = acc.intersect(o, d, cls=CAMERA)
    _, prim_sh, _, _ = acc.intersect(o, d, cls=SHADOW)
    _, prim_mix, _, _ = acc.intersect(np.repeat(o, 2, 0), np.repeat(d, 2, 0),
                                      cls=np.array([CAMERA, SHADOW]))
    assert prim_sh[0] in ghost and prim_cam[0] not in ghost and prim_cam[0] >= 0
    assert list(prim_mix) == [prim_cam[0], prim_sh[0]]
    plain = _room()
    plain.validate()
    geo2, _ = prepare(plain)
    acc2 = VisibilityAccel(geo2.vertices32, geo2.faces32, geo2.visibility, Accel)
    assert not acc2.has_invisible
    assert all(acc2.for_class(c) is acc2.full for c in (CAMERA, DIFFUSE, SHADOW))


def test_scene_file_flags(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text('[camera]\nposition = [0, -5, 2]\nlook_at = [0, 0, 0]\n'
                 '[[objects]]\ntype = "box"\ncenter = [0, 0, 0.5]\n'
                 'visible_camera = false\nvisible_shadow = false\nholdout = true\n')
    scene, _ = load_scene(str(f))
    m = scene.meshes[0]
    assert not m.visible_camera and not m.visible_shadow and m.holdout and m.visible_diffuse
    assert m.visibility == ALL_RAYS & ~CAMERA & ~SHADOW
    f.write_text('[camera]\nposition = [0, -5, 2]\nlook_at = [0, 0, 0]\n'
                 '[[objects]]\ntype = "box"\ncenter = [0, 0, 0.5]\nvisible_camera = "no"\n')
    with pytest.raises(SceneFileError, match="'visible_camera' must be true or false"):
        load_scene(str(f))


def test_photons_from_diffuse_invisible_surface_are_not_stored():
    """Without final gathering the floor reads the global photon map directly. Its only
    indirect light is what a red wall bounces onto it; with the wall invisible to diffuse
    rays that light is gone (Cycles: the floor's diffuse rays do not see the wall), so
    the photons that left the wall must not be stored."""
    def floor_indirect(flags):
        s = PaperScene(width=24, height=24)
        s.add_material(Material("white", (0.8, 0.8, 0.8)))
        s.add_material(Material("red", (0.9, 0.05, 0.05)))
        s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "white", name="floor")
        wall = s.add_plane((0, 0.6, 1.0), (0, -1, 0), (4.0, 2.0), "red", name="wall")
        for k, v in flags.items():
            setattr(wall, k, v)
        s.add_point_light((0, -0.5, 1.5), power=200.0)
        s.set_camera((0, -0.3, 4), (0, -0.3, 0), up=(0, 1, 0), view_angle=30)
        film = s.render(RenderSettings(spp=4, photons=60_000, caustic_photons=0, seed=3,
                                       final_gather=False))
        floor = (film.depth > 3.9) & (film.depth < 10)  # the wall is nearer the camera
        # Pixels whose neighbours are floor too: the Depth pass is the first sample's,
        # so a pixel on the wall's edge may read floor while its other samples see the
        # wall (its own indirect light).
        inner = floor.copy()
        inner[1:-1, 1:-1] &= (floor[:-2, 1:-1] & floor[2:, 1:-1]
                              & floor[1:-1, :-2] & floor[1:-1, 2:])
        inner[[0, -1], :] = inner[:, [0, -1]] = False
        floor = inner
        return film.indirect[floor].reshape(-1, 3).mean(axis=0)
    seen = floor_indirect({})
    assert seen[0] > 1.3 * seen[1] and seen[0] > 0.01
    hidden = floor_indirect({"visible_diffuse": False})
    assert hidden.max() < 0.01 * seen[0], (hidden, seen)


# --- photons: a segment has the kind of the camera-side ray that traverses it backwards,
# set by the use made of the photon where it arrives (docs/scene_format.md, "Ray
# visibility") ----------------------------------------------------------------------------

def _mirror_room(cube):
    """A mirror floor and a white back wall under a point light, with a cube (flags
    `cube`; None: no cube) between the light and the mirror, hidden from the camera so
    that every variant shows the same wall pixels. The wall's caustic pass is the light
    the mirror reflects onto it (L S D)."""
    s = PaperScene(width=32, height=24)
    s.add_material(Material("white", (0.8, 0.8, 0.8)))
    s.add_material(Material("red", (0.8, 0.1, 0.1)))
    s.add_material(Material("mirror", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 3.0, "mirror", name="mirror")
    s.add_plane((0, 1.5, 1.5), (0, -1, 0), (3.0, 3.0), "white", name="wall")
    s.add_point_light((0, -0.5, 3.0), power=300.0)
    if cube is not None:
        box = s.add_box((0, 0.0, 1.5), (0.8, 0.8, 0.8), "red", name="cube")
        box.visible_camera = False
        for k, v in cube.items():
            setattr(box, k, v)
    s.set_camera((0, -4, 1.5), (0, 1.5, 1.5), view_angle=40)
    return s


def _mirror_settings(**kw):
    return RenderSettings(spp=2, photons=20_000, caustic_photons=40_000, seed=3, **kw)


def test_glossy_invisible_cube_lets_light_reach_the_mirror():
    """Cycles: the light that reaches the wall through the mirror is found by the wall's
    diffuse ray, reflected by the mirror into a glossy ray, which passes a cube invisible
    to glossy rays. So the segment light -> mirror is a glossy ray (the kind of the event
    at the mirror), not a shadow ray (the kind of the event that started it)."""
    free = _mirror_room(None).render(_mirror_settings()).caustic.mean()
    ghost = _mirror_room({"visible_glossy": False}).render(_mirror_settings()).caustic.mean()
    assert free > 0.02
    assert abs(ghost / free - 1) < 0.05, (ghost, free)
    # The control: a cube glossy rays see shades the mirror and so the wall.
    solid = _mirror_room({}).render(_mirror_settings()).caustic.mean()
    assert solid < 0.2 * free, (solid, free)


def test_visibility_split_photons_are_deterministic():
    """Same seed, same image, with photons split at invisible surfaces, for any thread
    count (a split-off photon keeps its slot's random numbers)."""
    a = _mirror_room({"visible_glossy": False}).render(_mirror_settings(workers=1))
    b = _mirror_room({"visible_glossy": False}).render(_mirror_settings(workers=1))
    c = _mirror_room({"visible_glossy": False}).render(_mirror_settings(workers=2))
    np.testing.assert_array_equal(a.combined, b.combined)
    np.testing.assert_array_equal(a.combined, c.combined)


def _blocker_room(flags):
    """A white floor and back wall under a point light, a 1.6 m plane (flags) 1.2 m over
    the floor below the light; returns the wall's indirect light (global photon map, no
    final gathering) on its upper third (lit by the plane's top) and its lower half (lit
    by the floor, which the plane shades)."""
    s = PaperScene(width=32, height=24)
    s.add_material(Material("white", (0.8, 0.8, 0.8)))
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "white", name="floor")
    s.add_plane((0, 1.0, 1.5), (0, -1, 0), (4.0, 3.0), "white", name="wall")
    s.add_point_light((0, 0, 2.8), power=300.0)
    plane = s.add_plane((0, 0, 1.2), (0, 0, 1), 1.6, "white", name="blocker")
    for k, v in flags.items():
        setattr(plane, k, v)
    s.set_camera((0, -4, 1.5), (0, 1.0, 1.5), view_angle=45)
    film = s.render(RenderSettings(spp=2, photons=40_000, caustic_photons=0, seed=3,
                                   final_gather=False))
    h = film.indirect.shape[0]
    return film.indirect[: h // 3].mean(), film.indirect[h // 2:].mean()


def test_light_bounced_off_a_diffuse_surface_follows_shadow_rays():
    """The segment light -> floor, continued by a diffuse bounce at the floor, is the
    floor's direct light: on the camera side a shadow ray from the floor (Cycles' next
    event estimation; this engine's gather ends in the direct photons). A plane seen only
    by shadow rays shades the floor for that bounce too: the wall's light from the floor
    is as dim as under a plane every ray sees, not as bright as under no plane."""
    ghost_top, ghost_low = _blocker_room({f: False for f in FLAGS})
    shadow_top, shadow_low = _blocker_room({f: f == "visible_shadow" for f in FLAGS})
    assert ghost_low > 0.05
    assert shadow_low < 0.4 * ghost_low, (shadow_low, ghost_low)


def test_shadow_invisible_surface_is_lit_and_bounces_light():
    """A photon lands on a surface its segment's kind does not see: that surface is where
    the camera-side ray starts, and a ray never tests its own start. A plane invisible to
    shadow rays is lit by the light (Cycles) and bounces that light onto the wall as a
    plane every ray sees does."""
    ghost_top, _ = _blocker_room({f: False for f in FLAGS})
    solid_top, _ = _blocker_room({"visible_camera": False})
    unshadowing_top, _ = _blocker_room({"visible_camera": False, "visible_shadow": False})
    assert solid_top > 2 * ghost_top, (solid_top, ghost_top)
    assert abs(unshadowing_top / solid_top - 1) < 0.15, (unshadowing_top, solid_top)


def _lamp_scene(**flags):
    """A diffuse floor and a mirror panel under a visible area light with the given
    light-object ray visibility flags; camera looking down at both."""
    from engine.api import PaperScene
    from engine.scene import Camera, Light, Material
    s = PaperScene(width=48, height=32)
    s.add_material(Material("matte", (0.6, 0.6, 0.6)))
    s.add_material(Material("mirror", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0))
    s.add_plane((-1.0, 0, 0), (0, 0, 1), 2.0, "matte", name="floor")
    s.add_plane((1.0, 0, 0), (0, 0, 1), 2.0, "mirror", name="mirror")
    s.add_light(Light("panel", "AREA", 200.0, position=(0, 0, 2.0), direction=(0, 0, -1),
                      size_x=1.0, size_y=1.0, **flags))
    s.camera = Camera(position=(0, 0, 5), rotation=np.eye(3), kind="ORTHO", ortho_scale=4.0)
    return s


def test_light_object_ray_visibility():
    """A light's diffuse visibility off: the matte floor gets no light from it (direct or
    bounced); glossy off: the mirror no longer shows it; each flag alone leaves the other
    surface as it was (Cycles' Object > Visibility > Ray Visibility on a light)."""
    settings = RenderSettings(spp=4, photons=20_000, caustic_photons=10_000, seed=3)
    base = _lamp_scene().render(settings)
    no_diffuse = _lamp_scene(visible_diffuse=False).render(settings)
    no_glossy = _lamp_scene(visible_glossy=False).render(settings)
    floor, mirror = np.s_[:, :20], np.s_[:, 28:]
    assert base.combined[floor].mean() > 0.05 and base.specular[mirror].max() > 1.0
    assert no_diffuse.direct[floor].max() == 0.0
    assert no_diffuse.combined[floor].mean() < 0.05 * base.combined[floor].mean()
    np.testing.assert_allclose(no_diffuse.specular[mirror], base.specular[mirror])
    assert no_glossy.specular[mirror].max() < 0.05 * base.specular[mirror].max()
    np.testing.assert_allclose(no_glossy.direct[floor], base.direct[floor])


def test_holdout_still_bounces_light():
    """Cycles' holdout cuts a hole for camera rays only: every other ray sees the object's
    material, so the red wall made a holdout still tints the floor as before. 16 spp: at
    4 the floor's indirect mean moved by up to 12 % between seeds (gather noise; 16 spp:
    within 1.5 % over 4 seeds)."""
    plain = _room().render(_settings(spp=16))
    s = _room()
    next(m for m in s.meshes if m.name == "wall").holdout = True
    held = s.render(_settings(spp=16))
    seen_floor = (plain.alpha == 1) & (held.alpha == 1)
    assert seen_floor.sum() > 100 and (held.alpha == 0).sum() > 100  # the wall is a hole

    def redness(film):  # the red wall's bounce tints the white floor's indirect light
        ind = film.indirect[seen_floor].mean(axis=0)
        return ind[0] / ind[1], ind.mean()

    (r_plain, m_plain), (r_held, m_held) = redness(plain), redness(held)
    assert r_plain > 1.5, r_plain
    assert abs(r_held / r_plain - 1) < 0.1, (r_plain, r_held)
    assert abs(m_held / m_plain - 1) < 0.1, (m_plain, m_held)
