"""Light Linking (engine/lightlinking.py) against closed-form values and invariants:
a lamp linked to one of two patches lights that one only (shadow rays), its photons end
at the first hit on an object it does not link, and a surface it does not link does not
show it by BSDF-sampled rays either (mirror and rough gloss: MIS's both halves)."""
import math

import numpy as np

from engine import RenderSettings
from engine.api import PaperScene
from engine.photons import trace_photons
from engine.photonkernels import DIRECT
from engine.render import close_context, prepare_context
from engine.scene import Camera, Material
from engine.scenefile import load_scene
from helpers import pixel_to_world, rel_err

DIRECT_ONLY = dict(photon_mapping=False, max_depth=0)
H, P, E_SUN = 2.0, 1000.0, 0.5


def two_patches(rho=0.5, res=48, view=4.0):
    """Two diffuse patches side by side at z=0 (left x<0, right x>0) seen straight down."""
    s = PaperScene(width=res, height=res)
    s.add_material(Material("matte", (rho,) * 3))
    s.add_plane((-1.0, 0, 0), (0, 0, 1), (2.0, 4.0), "matte", name="left", up=(0, 1, 0))
    s.add_plane((1.0, 0, 0), (0, 0, 1), (2.0, 4.0), "matte", name="right", up=(0, 1, 0))
    s.camera = Camera(position=(0, 0, 5), rotation=np.eye(3), kind="ORTHO", ortho_scale=view)
    return s


def _expected(s, rho, view, key_on_left, key_on_right):
    x, y = pixel_to_world(s, view)
    r2 = x * x + y * y + H * H
    key = rho * (P / (4 * math.pi)) * (H / np.sqrt(r2)) / r2 / math.pi
    sun = rho * E_SUN / math.pi
    lit = np.where(x < 0, key_on_left, key_on_right)
    return sun + key * lit, x


def test_point_lamp_linked_to_one_patch_lights_only_that_one():
    """The key lamp's receivers = ['left']: the right patch reads the sun alone, the left
    one the sun plus the inverse-square law (direct light by shadow rays)."""
    rho, view = 0.5, 4.0
    s = two_patches(rho, view=view)
    key = s.add_point_light((0, 0, H), power=P, name="key")
    key.receivers = ["left"]
    s.add_sun((0, 0, -1), strength=E_SUN, name="fill")
    img = s.render(RenderSettings(spp=16, **DIRECT_ONLY)).combined[..., 1]
    want, x = _expected(s, rho, view, 1.0, 0.0)
    inner = np.abs(x) > 0.2  # away from the seam between the patches
    err = np.abs(img - want) / want
    assert err[inner].max() < 0.015, err[inner].max()
    # The exclude form: non_receivers = ['left'] lights the right patch only.
    s = two_patches(rho, view=view)
    key = s.add_point_light((0, 0, H), power=P, name="key")
    key.non_receivers = ["left"]
    s.add_sun((0, 0, -1), strength=E_SUN, name="fill")
    img = s.render(RenderSettings(spp=16, **DIRECT_ONLY)).combined[..., 1]
    want, _ = _expected(s, rho, view, 0.0, 1.0)
    err = np.abs(img - want) / want
    assert err[inner].max() < 0.015, err[inner].max()


def test_light_tree_picks_keep_the_links():
    """Many lamps (the light tree picks one per hit): the unlinked patch's mean is the
    other lamps' light alone, within the noise of 256 samples."""
    rho, view = 0.5, 4.0
    means = {}
    for linked in (False, True):
        s = two_patches(rho, res=16, view=view)
        for i in range(12):
            lamp = s.add_point_light((-1.5 + 0.25 * i, 0.3, H), power=P / 12,
                                     name=f"lamp{i}")
            if linked and i % 2 == 0:
                lamp.receivers = ["left"]
        img = s.render(RenderSettings(spp=256, seed=5, **DIRECT_ONLY)).combined[..., 1]
        x, _ = pixel_to_world(s, view)
        means[linked] = (img[x > 0.2].mean(), img[x < -0.2].mean())
    # Unlinked: the even lamps no longer light the right patch.
    s = two_patches(rho, res=16, view=view)
    for i in range(1, 12, 2):
        s.add_point_light((-1.5 + 0.25 * i, 0.3, H), power=P / 12, name=f"lamp{i}")
    odd = s.render(RenderSettings(spp=4, **DIRECT_ONLY)).combined[..., 1]
    x, _ = pixel_to_world(s, view)
    assert rel_err(means[True][0], odd[x > 0.2].mean()) < 0.02, (means, odd[x > 0.2].mean())
    # The linked patch keeps every lamp's light.
    assert rel_err(means[True][1], means[False][1]) < 0.02, means


def _photon_scene(linked: bool):
    s = two_patches(0.5, res=8)
    key = s.add_point_light((0, 0, H), power=P, name="key")
    if linked:
        key.receivers = ["left"]
    return s


def test_photons_end_at_a_first_hit_the_light_does_not_link():
    """Photons of a lamp linked to the left patch: none stored directly on the right one,
    and those on the left are the very photons of the unlinked lamp (same seed, same
    paths: each photon's numbers are its slot's)."""
    settings = RenderSettings(spp=1, photons=20000, seed=2)
    stored = {}
    for linked in (False, True):
        ctx = prepare_context(_photon_scene(linked), settings)
        try:
            ph = trace_photons(ctx, ctx.lights, [20000], False, 0)
        finally:
            close_context(ctx)
        x = ph.position[:, 0] + ctx.geo.offset[0]
        direct = ph.kind == DIRECT
        stored[linked] = (x[direct], ph.power[direct])
    x_on, _ = stored[True]
    assert len(x_on) > 1000
    assert (x_on < 0).all(), (x_on > 0).sum()
    x_off, _ = stored[False]
    assert (x_off > 0).sum() > 1000  # without the link both patches take photons
    np.testing.assert_array_equal(np.sort(x_on), np.sort(x_off[x_off < 0]))


def _mirror_scene(roughness: float, linked: bool):
    """A glossy floor under a downward area lamp, seen from above beside the lamp: the
    camera sees the lamp only in the floor (BSDF rays, and with roughness light samples
    too). Linked to nothing but a far card, the lamp is gone from the floor."""
    s = PaperScene(width=24, height=24)
    s.add_material(Material("gloss", (0.9, 0.9, 0.9), metallic=1.0, roughness=roughness))
    s.add_material(Material("matte", (0.5,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "gloss", name="floor")
    s.add_plane((20, 0, 0), (0, 0, 1), 1.0, "matte", name="card")
    # Turned towards the camera, which sees its face directly and in the floor.
    lamp = s.add_rect_area_light((0, 0, 1.0), (1.0, 1.0), power=200.0, name="lamp",
                                 direction=(0, -1.0, -0.3))
    lamp.visible_camera = True
    if linked:
        lamp.receivers = ["card"]
    s.camera = Camera.look_at((0.0, -3.0, 3.0), (0, 0.5, 0), fov_degrees=50)
    return s


def test_surface_the_lamp_does_not_link_does_not_show_it():
    """Mirror (BSDF rays only) and rough metal (shadow rays and BSDF rays, MIS): with the
    lamp linked to another object the floor reflects nothing of it, while the camera
    still sees the lamp itself (Cycles: camera rays see every lamp)."""
    for roughness in (0.0, 0.3):
        settings = RenderSettings(spp=16, seed=1, photon_mapping=False, max_depth=2)
        plain = _mirror_scene(roughness, False).render(settings).combined
        linked = _mirror_scene(roughness, True).render(settings).combined
        assert plain.sum() > 0
        lamp_px = linked.max(axis=2) > 0
        assert lamp_px.sum() > 5
        # What is left is the lamp seen directly, the same pixels as without the link;
        # its reflection (about a third of the image's light) is gone.
        np.testing.assert_allclose(linked[lamp_px], plain[lamp_px], rtol=1e-6)
        gone = plain.sum() - linked.sum()
        assert gone > 0.3 * plain.sum(), (roughness, linked.sum(), plain.sum())
        assert (plain.max(axis=2) > 0).sum() > lamp_px.sum() + 20


def test_scene_file_reads_receivers(tmp_path):
    path = tmp_path / "linked.toml"
    path.write_text("""
[camera]
position = [0, -4, 2]
look_at = [0, 0, 0]
[[objects]]
type = "plane"
name = "floor"
receivers = ["floor"]
[[lights]]
type = "point"
position = [0, 0, 2]
receivers = ["floor"]
non_receivers = ["wall"]
""")
    scene, _ = load_scene(str(path))
    assert scene.lights[0].receivers == ["floor"]
    assert scene.lights[0].non_receivers == ["wall"]
    assert scene.meshes[0].receivers == ["floor"]


def test_unknown_receiver_names_warn():
    s = two_patches(res=4)
    key = s.add_point_light((0, 0, H), power=P, name="key")
    key.receivers = ["left", "nowhere"]
    s.validate()
    assert ("light 'key': receivers names 'nowhere', which is no object of the scene; "
            "ignored") in s.warnings


def _corner(key_receivers, with_key=True):
    """A matte floor and wall meeting at a corner, a fill lamp, and a key lamp near the
    corner, seen in perspective (the render path: the photon shot's emitters may wrap the
    lights, engine/visualimportance.py)."""
    s = PaperScene(width=24, height=18)
    s.add_material(Material("matte", (0.7, 0.7, 0.7)))
    s.add_plane((0, 0, 0), (0, 0, 1), 30.0, "matte", name="floor")
    s.add_plane((1.0, 0, 1.0), (-1, 0, 0), (4.0, 2.0), "matte", name="wall")
    s.add_point_light((-1.0, 0.0, 2.0), power=300.0, name="fill")
    if with_key:
        key = s.add_point_light((0.6, 0.0, 0.6), power=1000.0, name="key")
        key.receivers = key_receivers
    s.camera = Camera.look_at((-3.0, -3.0, 2.0), (0.5, 0.0, 0.5), fov_degrees=50)
    return s


def test_a_lamp_linked_to_nothing_adds_nothing_through_photons():
    """Full render with photon mapping: a key lamp whose receivers list is empty gives
    the image of the scene without it (its shadow rays give nothing, its photons all end
    at their first hit), while unlinked it brightens the corner a lot."""
    settings = RenderSettings(spp=8, photons=60_000, caustic_photons=0, seed=4)
    without = _corner(None, with_key=False).render(settings).combined.mean()
    nothing = _corner([]).render(settings).combined.mean()
    plain = _corner(None).render(settings).combined.mean()
    assert plain > 1.5 * without, (plain, without)
    assert rel_err(nothing, without) < 0.03, (nothing, without)


def test_aimed_photon_emitters_keep_their_lights_links():
    """The photon shot may emit a light through a wrapper (visual importance's
    RegionEmitter aims part of its photons at the region in view): the wrapper's photons
    end where the light's would (a Blender scene seen close up read its floor 3-7 %
    bright with bounces before the wrapper was unwrapped)."""
    from engine.lightlinking import link_row_of
    from engine.visualimportance import Region, RegionEmitter
    ctx = prepare_context(_photon_scene(True), RenderSettings(spp=1))
    try:
        key = ctx.lights[0]
        region = Region(np.zeros((1, 3)), np.ones(1), 1.0, 1)
        wrapped = RegionEmitter(key, region, 0.5)
        names = [m.name for m in ctx.scene.meshes]
        want = np.array([n == "left" for n in names])
        np.testing.assert_array_equal(link_row_of(ctx, key), want)
        np.testing.assert_array_equal(link_row_of(ctx, wrapped), want)
    finally:
        close_context(ctx)


def _card_over_left(key_links: dict):
    """The two patches under a point key and a straight-down sun, with a camera-invisible
    card at z = 1 over x in [-2, -0.5] (it shadows that part of the left patch)."""
    s = two_patches(0.5, view=4.0)
    card = s.add_plane((-1.25, 0, 1.0), (0, 0, 1), (1.5, 4.0), "matte", name="card",
                       up=(0, 1, 0))
    card.visible_camera = False
    key = s.add_point_light((0, 0, H), power=P, name="key")
    for attr, names in key_links.items():
        setattr(key, attr, names)
    s.add_sun((0, 0, -1), strength=E_SUN, name="fill")
    return s


def test_shadow_linking_lets_a_lamps_shadow_rays_pass_non_blockers():
    """Shadow Linking: the key's shadow rays pass the card when the card is not among
    its blockers (non_blockers = ['card'], or blockers naming other objects only), while
    the sun, not linked, is still shadowed by it: under the card the patch reads the
    key's inverse-square law alone, elsewhere key + sun."""
    rho, view = 0.5, 4.0
    for links in ({"non_blockers": ["card"]}, {"blockers": ["right"]}):
        img = _card_over_left(links).render(
            RenderSettings(spp=16, **DIRECT_ONLY)).combined[..., 1]
        s = two_patches(rho, view=view)
        want, x = _expected(s, rho, view, 1.0, 1.0)
        under = x < -0.5  # (the card spans x in [-2, -0.5], as the patch)
        want = np.where(under, want - rho * E_SUN / math.pi, want)
        inner = (np.abs(x) > 0.2) & (np.abs(x + 0.5) > 0.15)  # off the seam, card edge
        err = np.abs(img - want) / want
        assert err[inner].max() < 0.015, (links, err[inner].max())
    # Without the link the card shadows the key too: where it hides the key from the
    # patch (x in [-2, -1]: the ray to the key crosses z = 1 at x / 2) the patch reads 0.
    img = _card_over_left({}).render(RenderSettings(spp=4, **DIRECT_ONLY)).combined[..., 1]
    x, _ = pixel_to_world(two_patches(view=view), view)
    assert img[(x > -1.9) & (x < -1.1)].max() < 1e-6


def _glossy_lamps(mode: str):
    """A rough metal floor under 40 small area lamps (the light tree picks them, MIS with
    the BSDF rays; the 20 of "subset" too: more than SAMPLE_ALL_UP_TO); mode "linked":
    the even ones light only a far card, "subset": they are left out."""
    s = PaperScene(width=24, height=18)
    s.add_material(Material("metal", (0.9, 0.8, 0.7), metallic=1.0, roughness=0.35))
    s.add_material(Material("matte", (0.5,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "metal", name="floor")
    s.add_plane((30, 0, 0), (0, 0, 1), 1.0, "matte", name="card")
    for i in range(40):
        if mode == "subset" and i % 2 == 0:
            continue
        lamp = s.add_rect_area_light((-2.0 + 0.1 * i, 1.0 + 0.3 * math.sin(i), 1.2),
                                     (0.3, 0.3), power=20.0, name=f"lamp{i}",
                                     direction=(0, -0.5, -1.0))
        if mode == "linked" and i % 2 == 0:
            lamp.receivers = ["card"]
    s.camera = Camera.look_at((0.0, -3.0, 2.0), (0, 0.5, 0), fov_degrees=60)
    return s


def test_each_receiver_set_has_its_own_light_tree():
    """With the light tree, a surface picks only the lamps that light it (Cycles'
    per-set trees) and the BSDF rays' MIS weights use that tree's probabilities: the
    floor renders as the scene without the lamps it is not linked to (glossy floor: light
    samples and BSDF rays both count): the same picks, so the same image to rounding
    (with one shared tree the zeroed picks cost noise: bench/bench_light_linking.py)."""
    settings = RenderSettings(spp=16, seed=3, photon_mapping=False, max_depth=1)
    linked = _glossy_lamps("linked").render(settings).combined
    subset = _glossy_lamps("subset").render(settings).combined
    assert subset.mean() > 0.05
    np.testing.assert_allclose(linked, subset, rtol=1e-5, atol=1e-6)


def test_a_session_keeps_the_links():
    """The progressive / viewport session (engine/session.py) builds its own context:
    the links and the shadow groups come with it (its image is the render's)."""
    from engine.session import Session
    scene = _card_over_left({"non_blockers": ["card"]})
    key = scene.lights[0]
    key.receivers = ["left"]
    settings = RenderSettings(spp=4, **DIRECT_ONLY)
    want = _card_over_left({"non_blockers": ["card"], "receivers": ["left"]}).render(
        settings).combined
    session = Session(scene, settings, passes=1).start()
    try:
        assert session.wait_idle(timeout=120)
        frame = session.frame
    finally:
        session.stop()
    got = frame.rgba[..., :3]
    x, _ = pixel_to_world(scene, 4.0)
    inner = np.abs(x) > 0.2
    assert rel_err(got[inner].mean(), want[inner].mean()) < 0.01


def _panel_scene(receivers, floor="matte", res=32, panel=True, visible=False, glow=4.0):
    """Two patches (or a glossy floor) under an emitting panel facing down (an emitting
    object, Mesh.receivers its Light Linking) and a straight-down sun."""
    s = two_patches(0.5, res=res)
    if floor != "matte":
        s.meshes[:] = []
        s.add_material(Material("metal", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.3))
        s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "metal", name="left")
        s.camera = Camera.look_at((0.0, -3.0, 2.5), (0, 0.3, 0), fov_degrees=50)
    if panel:
        s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(glow, glow, glow)))
        p = s.add_plane((0.3, 0.2, 1.0), (0, 0, -1), 0.8, "glow", name="panel")
        p.visible_camera = visible
        p.receivers = receivers
    s.add_plane((30, 0, 0), (0, 0, 1), 1.0, "matte", name="card")
    s.add_sun((0, 0, -1), strength=E_SUN, name="fill")
    return s


def test_an_emitting_objects_links():
    """An emitting object's Light Linking (the panel lights the left patch only): direct
    light (its triangles zeroed for the right patch's set), a glossy floor not linked
    shows none of it (BSDF rays), and a panel linked to nothing adds nothing through the
    photons either."""
    direct = RenderSettings(spp=16, seed=2, **DIRECT_ONLY)
    linked = _panel_scene(["left"]).render(direct).combined[..., 1]
    plain = _panel_scene(None).render(direct).combined[..., 1]
    dark = _panel_scene(["left"], glow=0.0).render(direct).combined[..., 1]
    x, _ = pixel_to_world(two_patches(res=32), 4.0)
    right, left = x > 0.2, x < -0.2
    # The right patch: the sun alone (the panel's shadow included), as with a dark panel.
    np.testing.assert_allclose(linked[right], dark[right], rtol=1e-6, atol=1e-7)
    assert plain[right].mean() > 1.5 * dark[right].mean()
    np.testing.assert_allclose(linked[left], plain[left], rtol=1e-6)
    # A glossy floor: the panel seen in it (BSDF rays, MIS) only when linked to it.
    glossy = RenderSettings(spp=16, seed=2, photon_mapping=False, max_depth=2)
    seen = _panel_scene(None, floor="metal").render(glossy).combined.mean()
    away = _panel_scene(["card"], floor="metal").render(glossy).combined.mean()
    none = _panel_scene(None, floor="metal", glow=0.0).render(glossy).combined.mean()
    assert seen > 1.5 * none
    assert rel_err(away, none) < 1e-3, (away, none)
    # Photons (the corner of a floor and a wall, where they bounce): linked to nothing,
    # the panel's photons all end at their first hit, its light is gone.
    full = RenderSettings(spp=8, photons=60_000, caustic_photons=0, seed=4)
    means = {}
    for key, receivers, glow in (("nothing", [], 60.0), ("dark", None, 0.0),
                                 ("plain", None, 60.0)):
        s = _corner(None, with_key=False)
        s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(glow,) * 3))
        panel = s.add_plane((0.6, 0.0, 0.5), (-1, 0, 0), 0.8, "glow", name="panel")
        panel.visible_camera = False
        panel.receivers = receivers
        means[key] = s.render(full).combined.mean()
    assert means["plain"] > 1.5 * means["dark"], means
    assert rel_err(means["nothing"], means["dark"]) < 0.03, means


def test_a_set_no_lamp_of_the_tree_lights():
    """Every lamp of the tree linked to the left patch: the right patch's set has an
    empty tree (no pick, no light), the left patch keeps every lamp's light."""
    imgs = {}
    for linked in (False, True):
        s = two_patches(0.5, res=16)
        for i in range(20):
            lamp = s.add_point_light((-1.5 + 0.15 * i, 0.3, H), power=P / 20,
                                     name=f"lamp{i}")
            if linked:
                lamp.receivers = ["left"]
        imgs[linked] = s.render(RenderSettings(spp=8, seed=1, **DIRECT_ONLY)).combined
    x, _ = pixel_to_world(two_patches(res=16), 4.0)
    assert imgs[False][x > 0.2].min() > 0
    assert imgs[True][x > 0.2].max() == 0.0
    np.testing.assert_allclose(imgs[True][x < -0.2], imgs[False][x < -0.2], rtol=1e-6)


def test_linked_renders_do_not_depend_on_the_worker_count():
    """Same seed, same image for 1 and 2 workers, with receiver sets, a shadow group and
    photons (the hits of each set split per chunk)."""
    imgs = []
    for workers in (1, 2):
        s = _corner(["wall"])
        s.lights[1].non_blockers = ["wall"]  # the key
        imgs.append(s.render(RenderSettings(spp=4, photons=20_000, caustic_photons=0,
                                            seed=7, workers=workers)).combined)
    np.testing.assert_array_equal(imgs[0], imgs[1])


def test_photons_pass_a_lamps_non_blockers():
    """Shadow Linking and photons: a second run of the key's photons continues those
    whose first hit is a non-blocker from the blocker behind it, so the patches under
    the card receive exactly the direct photons they would without the card (same
    numbers, same paths), and the card keeps its own."""
    settings = RenderSettings(spp=1, photons=20000, seed=2)
    stored = {}
    for case in ("no card", "non-blocker", "blocker"):
        s = _card_over_left({"non_blockers": ["card"]} if case == "non-blocker" else {})
        s.lights[:] = [s.lights[0]]  # the key alone
        if case == "no card":
            s.meshes[:] = [m for m in s.meshes if m.name != "card"]
        ctx = prepare_context(s, settings)
        try:
            ph = trace_photons(ctx, ctx.lights, [20000], False, 0)
        finally:
            close_context(ctx)
        z = ph.position[:, 2] + ctx.geo.offset[2]
        direct = ph.kind == DIRECT
        pos = ph.position[direct] + ctx.geo.offset
        stored[case] = (pos[np.abs(z[direct]) < 1e-3], (np.abs(z[direct] - 1.0) < 1e-3).sum())
    floor_none, _ = stored["no card"]
    floor_nb, on_card = stored["non-blocker"]
    floor_b, on_card_b = stored["blocker"]
    assert on_card > 500 and on_card == on_card_b
    assert len(floor_b) < len(floor_none) - 500  # the card shadows the floor
    order = np.lexsort(floor_none.T)
    np.testing.assert_allclose(floor_nb[np.lexsort(floor_nb.T)], floor_none[order],
                               atol=1e-5)


def _mirror_card(non_blocker: bool, card=True):
    """A mirror floor reflecting an area lamp past a black card (camera-invisible)
    hanging under the lamp: the card a non-blocker of the lamp or not."""
    s = PaperScene(width=24, height=24)
    s.add_material(Material("mirror", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0))
    s.add_material(Material("black", (0.0, 0.0, 0.0)))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "mirror", name="floor")
    if card:
        c = s.add_plane((0, 0.3, 0.8), (0, 0, 1), 1.0, "black", name="card")
        c.visible_camera = False
    lamp = s.add_rect_area_light((0, 0.3, 1.0), (1.0, 1.0), power=200.0, name="lamp",
                                 direction=(0, 0, -1))
    if non_blocker:
        lamp.non_blockers = ["card"]
    s.camera = Camera.look_at((0.0, -3.0, 3.0), (0, 0.5, 0), fov_degrees=50)
    return s


def test_a_lamp_is_seen_past_its_non_blockers():
    """Shadow Linking and rays that meet the lamp: the mirror shows the lamp through a
    card that is not one of its blockers (Cycles' dedicated shadow-linking ray), as
    without the card; a card that blocks hides it."""
    settings = RenderSettings(spp=4, seed=1, photon_mapping=False, max_depth=2)
    without = _mirror_card(False, card=False).render(settings).combined
    past = _mirror_card(True).render(settings).combined
    blocked = _mirror_card(False).render(settings).combined
    assert without.sum() > 0 and blocked.sum() < 0.2 * without.sum()
    np.testing.assert_allclose(past, without, rtol=1e-5, atol=1e-6)


def _fog(receivers, world=True, glow=True):
    """A white floor under a point lamp in fog: the world volume (world=True) or a
    volume-only fog box round the lamp; glow=False: the same extinction, no scattering
    (what the camera sees when the fog takes none of the lamp's light)."""
    from engine import WorldMedium
    sig_s = np.array([0.3, 0.3, 0.3]) if glow else np.zeros(3)
    sig_a = np.array([0.1, 0.1, 0.1]) + (0 if glow else 0.3)
    s = PaperScene(12, 12)
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "white_diffuse", name="floor")
    lamp = s.add_point_light((0.0, 0.0, 1.0), power=100.0, name="lamp")
    lamp.receivers = receivers
    s.set_camera((0, -1.5, 1.5), (0, 0, 0.5), up=(0, 0, 1), view_angle=50.0)
    if world:
        s.world_medium = WorldMedium(absorption=sig_a, scattering=sig_s)
    else:
        s.add_material(Material("fog", volume_only=True, absorption=sig_a, scattering=sig_s))
        s.add_box((0, 0, 0.6), (2.5, 2.5, 1.0), "fog", name="fogbox")
    return s


def test_volumes_take_the_lamps_of_their_set():
    """Volume light sampling takes the volume's receiver set (Cycles'
    light_link_receiver_nee at a volume point): the world volume is in no object (set 0),
    so a lamp with receivers lights no world fog; a fog box is lit by a lamp linked to
    it. Linked away, the fog reads as fog of the same extinction that scatters nothing."""
    # (max_depth 2: camera rays pass the fog box's volume-only faces)
    settings = RenderSettings(spp=16, seed=3, photon_mapping=False, max_depth=2)
    for world in (True, False):
        plain = _fog(None, world).render(settings).combined.mean()
        linked = _fog(["floor"], world).render(settings).combined.mean()
        dark = _fog(None, world, glow=False).render(settings).combined.mean()
        assert plain > 1.3 * dark, (world, plain, dark)
        assert rel_err(linked, dark) < 0.01, (world, linked, dark)
    with_box = _fog(["floor", "fogbox"], False).render(settings).combined.mean()
    assert rel_err(with_box, _fog(None, False).render(settings).combined.mean()) < 0.01


def _mirror_sun(non_blocker: bool, card=True):
    """A mirror floor reflecting a 20-degree sun's disc to the camera past a black,
    camera-invisible card across the reflected rays."""
    s = PaperScene(width=24, height=24)
    s.add_material(Material("mirror", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0))
    s.add_material(Material("black", (0.0, 0.0, 0.0)))
    s.add_plane((0, 0, 0), (0, 0, 1), 20.0, "mirror", name="floor")
    up = np.array([0.0, 0.76, 0.65]) / np.linalg.norm([0.0, 0.76, 0.65])
    if card:
        c = s.add_plane(tuple(np.array([0.0, 0.5, 0.0]) + 1.2 * up), tuple(up), 3.0,
                        "black", name="card")
        c.visible_camera = False
    sun = s.add_sun(tuple(-up), strength=3.0, angle_degrees=20.0, name="sun")
    if non_blocker:
        sun.non_blockers = ["card"]
    s.camera = Camera.look_at((0.0, -3.0, 3.0), (0, 0.5, 0), fov_degrees=50)
    return s


def test_a_sun_is_seen_past_its_non_blockers():
    """Shadow Linking and the sun's disc: the mirror shows it past a non-blocking card
    as without the card (Cycles' dedicated ray counts distant lights), a blocking card
    hides it."""
    settings = RenderSettings(spp=4, seed=1, photon_mapping=False, max_depth=2)
    without = _mirror_sun(False, card=False).render(settings).combined
    past = _mirror_sun(True).render(settings).combined
    blocked = _mirror_sun(False).render(settings).combined
    assert without.sum() > 0 and blocked.sum() < 0.2 * without.sum(), (without.sum(),
                                                                         blocked.sum())
    np.testing.assert_allclose(past, without, rtol=1e-5, atol=1e-6)
