"""Shadow catchers in the engine (engine/shadowcatcher.py): invariants and analytic
cases without bpy; tests/blender/test_shadow_catcher_cycles.py compares with Cycles."""
import numpy as np
import pytest

from engine import Budget, RenderSettings, render_progressive
from engine.api import PaperScene
from engine.scene import Material
from engine.shadowcatcher import combined_rgba, shadow_catcher_pass

WORLD = (0.2, 0.3, 0.5)


def _scene(roof=False, cube=False, world_light=False):
    """A grey floor (catcher, 6 m) under a sun straight down, seen from above (the floor
    fills the image). roof: a black 3 x 6 m plane at 1 m the camera does not see,
    over the image's left half (x < 0): that half is in full shadow and nothing bounces
    into it. cube: a red cube (1 m) on the floor."""
    s = PaperScene(width=24, height=24)
    s.add_material(Material("grey", (0.5, 0.5, 0.5)))
    s.add_material(Material("black", (0.0, 0.0, 0.0)))
    s.add_material(Material("red", (0.8, 0.1, 0.1)))
    s.add_plane((0, 0, 0), (0, 0, 1), 6.0, "grey", name="floor").shadow_catcher = True
    if roof:
        r = s.add_plane((-1.5, 0, 1.0), (0, 0, 1), (6.0, 3.0), "black", name="roof")
        r.visible_camera = False
    if cube:
        s.add_box((0.6, 0, 0.5), 1.0, "red", name="cube")
    s.add_sun((0.0, 0.0, -1.0), strength=3.0)
    s.background = WORLD
    s.background_is_light = world_light
    s.set_camera((0, 0, 5), (0, 0, 0), up=(0, 1, 0), view_angle=30)
    return s


def _settings(**kw):
    return RenderSettings(**{**dict(spp=4, photons=20_000, caustic_photons=0, seed=2), **kw})


def test_catcher_alone_is_invisible():
    """Nothing else in the scene: with = without (the same photons and camera samples),
    so the floor is alpha 0 and colour 0 everywhere, and the pass is 1."""
    film = _scene(world_light=True).render(_settings(film_transparent=True))
    rgba = combined_rgba(film, True)
    assert np.abs(rgba).max() < 1e-6, np.abs(rgba).max()
    assert np.allclose(shadow_catcher_pass(film, True), 1.0, atol=1e-6)
    # Without a transparent film the world shows through the floor unchanged.
    film = _scene(world_light=True).render(_settings())
    rgba = combined_rgba(film, False)
    assert np.allclose(rgba[..., :3], WORLD, atol=1e-6) and np.all(rgba[..., 3] == 1.0)


def test_full_shadow_is_opaque_black():
    """Under the roof (no light with the objects, the sun's without) the shadow is full:
    alpha 1, colour 0 (transparent film), black without a transparent film; the sunlit
    half stays invisible / the world's colour. The pass: 0 under the roof, 1 beside it."""
    for transparent in (True, False):
        film = _scene(roof=True).render(_settings(film_transparent=transparent))
        rgba = combined_rgba(film, transparent)
        shade = shadow_catcher_pass(film, transparent)
        left, right = rgba[:, 2:10], rgba[:, 14:22]  # x < -0.2 m, x > 0.2 m
        assert np.abs(left[..., :3]).max() < 1e-6
        assert np.allclose(left[..., 3], 1.0)
        assert np.allclose(shade[:, 2:10], 0.0) and np.allclose(shade[:, 14:22], 1.0)
        if transparent:
            assert np.abs(right).max() < 1e-6
        else:
            assert np.allclose(right[..., :3], WORLD) and np.allclose(right[..., 3], 1.0)


def test_objects_render_as_without_a_catcher():
    """The cube itself renders as in the same scene without a catcher (its light lands
    on the floor either way), alpha 1; the film's effect passes still hold the full
    render (the floor as an ordinary surface)."""
    kw = dict(film_transparent=True, spp=8)
    film = _scene(cube=True, world_light=True).render(_settings(**kw))
    plain_scene = _scene(cube=True, world_light=True)
    plain_scene.meshes[0].shadow_catcher = False
    plain = plain_scene.render(_settings(**kw))
    rgba = combined_rgba(film, True)
    top = np.zeros(rgba.shape[:2], bool)
    top[8:16, 15:22] = True  # the cube's top face (x 0.1..1.1 m, inside by a pixel)
    assert np.allclose(rgba[top][:, 3], 1.0)
    assert np.allclose(rgba[top][:, :3].mean(0), plain.combined[top].mean(0), rtol=0.03), (
        rgba[top][:, :3].mean(0), plain.combined[top].mean(0))
    assert np.allclose(film.combined.mean(), plain.combined.mean(), rtol=0.03)
    assert film.stats.get("time_shadow_catcher", 0) > 0
    assert any(line.startswith("shadow catcher: on") for line in film.stats["effects"])


def test_same_image_for_any_thread_count_and_over_passes():
    """Seeded: the catcher's Combined and pass are the same bits on 1 and 2 threads; a
    progressive render averages them over its passes."""
    outs = []
    for threads in (1, 2):
        film = _scene(roof=True, cube=True, world_light=True).render(
            _settings(workers=threads, chunk_size=256, film_transparent=True))
        outs.append((combined_rgba(film, True), shadow_catcher_pass(film, True)))
    assert np.array_equal(outs[0][0], outs[1][0]) and np.array_equal(outs[0][1], outs[1][1])
    film = render_progressive(_scene(roof=True), _settings(film_transparent=True),
                              Budget(passes=2))
    rgba = combined_rgba(film, True)
    assert film.stats["passes"] == 2
    assert np.allclose(rgba[:, 2:10, 3], 1.0) and np.abs(rgba[:, 14:22]).max() < 1e-6


def test_scene_file_flag_and_cli_output(tmp_path):
    """`shadow_catcher = true` in a scene file (docs/scene_format.md) marks the object,
    an instance takes it from its object; the command line writes the approximate
    shadow catcher's RGBA with a transparent film and the pass with --save-passes."""
    from engine.cli import main
    from engine.imageio import read_image
    from engine.scenefile import load_scene
    f = tmp_path / "s.toml"
    f.write_text('[render]\nwidth = 16\nheight = 12\nfilm_transparent = true\n'
                 '[camera]\nposition = [0, -4, 3]\nlook_at = [0, 0, 0]\n'
                 '[[lights]]\ntype = "sun"\ndirection = [0.3, 0.2, -1]\nstrength = 3\n'
                 '[[objects]]\ntype = "plane"\nname = "floor"\ncenter = [0, 0, 0]\n'
                 'size = 8\nshadow_catcher = true\n'
                 '[[objects]]\ntype = "box"\nname = "cube"\ncenter = [0, 0, 0.5]\n')
    scene, _ = load_scene(str(f))
    assert [m.shadow_catcher for m in scene.meshes] == [True, False]
    out = tmp_path / "c.exr"
    assert main(["render", str(f), "-o", str(out), "--spp", "2", "--photons", "5000",
                 "--save-passes", "--quiet"]) == 0
    import OpenEXR
    with OpenEXR.File(str(out)) as exr:
        ch = exr.channels()
        rgba = np.asarray((ch.get("RGBA") or ch["RGB"]).pixels, np.float32)
    assert rgba.shape == (12, 16, 4)
    shade = read_image(str(tmp_path / "c.shadow_catcher.exr"))
    assert shade.shape[:2] == (12, 16) and (shade[..., :3] < 0.5).any()
    # The shadow's pixels are the opaque ones beside the cube's: alpha 1 - shadow there.
    assert (rgba[..., 3] > 0.3).any() and (rgba[..., 3] < 0.05).mean() > 0.5


def test_viewport_session_shows_the_catcher_and_follows_the_view():
    """The rendered viewport (engine/session.py) shows Cycles' approximate shadow catcher,
    the same bits as a progressive render, and follows the view (the catchers-alone
    scene takes the new camera)."""
    from engine import Camera
    from engine.session import Session, _scene_with
    settings = _settings(film_transparent=True, spp=1)
    scene = _scene(roof=True, cube=True, world_light=True)
    # A lamp, not the sun: the floor's light varies across the image, so a catchers-alone
    # scene left at the old view would compare the wrong points.
    scene.lights.clear()
    scene.add_point_light((0.8, 0.3, 2.5), power=400.0)

    def reference(sc):
        film = render_progressive(_scene_with(sc), settings, Budget(passes=2))
        return combined_rgba(film, True)

    session = Session(scene, settings, passes=2).start()
    try:
        assert session.wait_idle(120) and session.error is None, session.error
        np.testing.assert_array_equal(session.frame.rgba, reference(scene))
        cam = Camera.look_at((0.5, -0.5, 5.0), (0.2, 0.0, 0.0), up=(0, 1, 0),
                             fov_degrees=35.0)
        session.update_view(cam, 24, 24)
        assert session.wait_idle(120) and session.error is None, session.error
        # (Not the same bits: the session keeps the photons the first view aimed, with or
        # without a catcher.)
        ref = reference(_scene_with(scene, camera=cam))
        diff = np.abs(session.frame.rgba[..., 3] - ref[..., 3])
        # Measured 0.003; an alone scene left at the old view: 0.026.
        assert diff.mean() < 0.01, diff.mean()
    finally:
        session.stop()


def test_adaptive_sampling_and_cryptomatte_keep_the_catcher():
    """Adaptive sampling's rounds keep the catcher sums per pixel (integrator._add_round)
    and the Cryptomatte / data passes of the main render are not asked of the
    catchers-alone pass: the full shadow still reads alpha 1, the lit floor 0."""
    film = _scene(roof=True).render(_settings(
        film_transparent=True, spp=16, adaptive_threshold=0.05, adaptive_min_samples=4,
        cryptomatte=("object",), data_passes=("denoising",)))
    assert film.sample_count is not None and film.cryptomatte
    rgba = combined_rgba(film, True)
    assert np.allclose(rgba[:, 2:10, 3], 1.0) and np.abs(rgba[:, 14:22]).max() < 1e-6


def test_memory_estimate_counts_the_catchers_alone_maps():
    """The catchers-alone pass' photon maps are held with the scene's: the estimate
    (engine/resources.py) counts one stored photon per emitted photon for them."""
    from engine.resources import BYTES_PER_STORED_PHOTON, estimate_memory
    s = _settings(photons=100_000)
    scene = _scene(cube=True)
    with_catcher = estimate_memory(scene, s).parts
    scene.meshes[0].shadow_catcher = False
    without = estimate_memory(scene, s).parts
    assert "shadow catcher maps" not in without
    assert with_catcher["shadow catcher maps"] == 100_000 * BYTES_PER_STORED_PHOTON


def test_instances_take_the_flag_from_their_object_or_their_own(tmp_path):
    """A template object marked shadow_catcher: its instances are catchers unless one
    says otherwise (placements without a world-space copy: the catchers-alone scene
    keeps their prototype)."""
    from engine.render import render
    from engine.scenefile import load_scene
    f = tmp_path / "s.toml"
    f.write_text('[render]\nwidth = 16\nheight = 12\n'
                 '[camera]\nposition = [0, -4, 3]\nlook_at = [0, 0, 0]\n'
                 '[[lights]]\ntype = "sun"\ndirection = [0.3, 0.2, -1]\nstrength = 3\n'
                 '[[objects]]\ntype = "plane"\nname = "tile"\ncenter = [0, 0, 0]\n'
                 'size = 4\ntemplate = true\nshadow_catcher = true\n'
                 '[[instances]]\nobject = "tile"\ntranslate = [-2, 0, 0]\n'
                 '[[instances]]\nobject = "tile"\ntranslate = [2, 0, 0]\n'
                 'shadow_catcher = false\n'
                 '[[objects]]\ntype = "box"\nname = "cube"\ncenter = [0, 0, 0.5]\n')
    scene, _ = load_scene(str(f))
    flags = {m.name: m.shadow_catcher for m in scene.meshes}
    assert flags == {"cube": False, "tile.instance.000": True, "tile.instance.001": False}
    film = render(scene, _settings(spp=2, photons=5000, film_transparent=True))
    alpha = combined_rgba(film, True)[..., 3]
    assert np.abs(alpha[8:, :4]).max() < 1e-6     # the catcher tile (left), lit
    assert np.allclose(alpha[8:, 12:], 1.0)       # the ordinary tile (right)


def test_a_catcher_seen_through_a_transparent_card_is_warned():
    """A half-transparent card between the camera and the catcher: camera rays through
    it meet the catcher past the first hit, where it is not split (it renders as an
    ordinary surface): one warning names the catcher and counts those samples
    (newuser37: a grey rectangle in the matte, nothing said). Without the card: none."""
    s = _scene()
    s.add_material(Material("card", (0.5, 0.5, 0.5), alpha=0.5))
    s.add_plane((0, 0, 2.0), (0, 0, 1), 1.0, "card", name="card")
    film = s.render(_settings(film_transparent=True))
    hits = [w for w in film.warnings if w.startswith("shadow catcher 'floor'")]
    assert len(hits) == 1 and "transparent surface" in hits[0], film.warnings
    samples = int(hits[0].split(": ")[1].split(" camera")[0].replace(",", ""))
    # The card covers (1 / (2 x 3 tan 15 deg))^2 of the image: ~0.39 of 24 x 24 x 4.
    assert 0.25 * 24 * 24 * 4 < samples < 0.55 * 24 * 24 * 4, samples
    film = _scene().render(_settings(film_transparent=True))
    assert not [w for w in film.warnings if "shadow catcher" in w]


def test_viewport_edits_rebuild_the_catchers_alone_only_when_it_changes():
    """A viewport session rebuilt the catchers-alone context (its geometry, BVH, lights)
    on every edit of the scene; it is kept through edits of the other objects (their
    materials, their place) and rebuilt when the catchers, their materials, the lights
    or the world change (shadowcatcher.alone_key). A kept one renders the same bits as a
    fresh render of the edited scene."""
    from dataclasses import replace

    from engine.session import Session, _scene_with
    settings = _settings(film_transparent=True, spp=1)
    scene = _scene(cube=True, world_light=True)

    def reference(sc):
        return combined_rgba(render_progressive(_scene_with(sc), settings,
                                                Budget(passes=1)), True)

    session = Session(scene, settings, passes=1).start()

    def edit(sc, geometry):
        before = session.counters.catcher_builds
        session.update_scene(sc, geometry=geometry)
        assert session.wait_idle(120) and session.error is None, session.error
        return session.counters.catcher_builds - before

    try:
        assert session.wait_idle(120) and session.error is None, session.error
        assert session.counters.catcher_builds == 1
        # The cube's material, then the cube moved: kept, and the image a fresh render's.
        materials = dict(scene.materials, red=Material("red", (0.1, 0.2, 0.8)))
        scene = _scene_with(scene, materials=materials)
        assert edit(scene, False) == 0
        np.testing.assert_array_equal(session.frame.rgba, reference(scene))
        cube = next(m for m in scene.meshes if m.name == "cube")
        moved = replace(cube, vertices=cube.vertices + np.array([-0.3, 0.2, 0.0]))
        scene = _scene_with(scene, meshes=[moved if m is cube else m for m in scene.meshes])
        assert edit(scene, True) == 0
        np.testing.assert_array_equal(session.frame.rgba, reference(scene))
        # The catcher's material, the light, the world, the catcher moved: rebuilt.
        materials = dict(scene.materials, grey=Material("grey", (0.3, 0.3, 0.3)))
        scene = _scene_with(scene, materials=materials)
        assert edit(scene, False) == 1
        light = scene.lights[0]
        scene = _scene_with(scene, lights=[replace(light, power=2.0 * light.power,
                                                   warnings=[])])
        assert edit(scene, False) == 1
        scene = _scene_with(scene, background=(0.1, 0.1, 0.1))
        assert edit(scene, False) == 1
        floor = scene.meshes[0]
        lowered = replace(floor, vertices=floor.vertices - np.array([0.0, 0.0, 0.1]))
        scene = _scene_with(scene, meshes=[lowered] + list(scene.meshes[1:]))
        assert edit(scene, True) == 1
        np.testing.assert_array_equal(session.frame.rgba, reference(scene))
    finally:
        session.stop()


def test_the_catcher_pass_has_its_own_span_of_the_progress_bar():
    """A scene with a catcher tells on_plan of its catcher-only pass; stagespans gives that
    pass the bar's last CATCHER_SHARE, and its own photon and camera stages move through
    that span in order (the bar sat near 100 % while it ran: polish38)."""
    from engine import render
    from engine.stagespans import CATCHER_SHARE, StageSpans, stage_spans
    spans = stage_spans(True, 1000, 1000, start=0.1, catcher=True)
    assert spans["shadow catcher"] == pytest.approx((1.0 - 0.9 * CATCHER_SHARE,
                                                     0.9 * CATCHER_SHARE))
    main_end = spans["render"][0] + spans["render"][1]
    assert main_end == pytest.approx(spans["shadow catcher"][0])
    settings = _settings(chunk_size=256)  # (several chunks: the bar moves through them)
    bar = StageSpans(True, settings.photons, 24 * 24 * settings.spp)
    seen, plans = [], []

    def plan(work):
        plans.append(dict(work))
        bar.plan(work)

    def progress(stage, fraction, _text):
        seen.append((stage, bar.whole(stage, fraction)))

    render(_scene(cube=True), settings, progress=progress, on_plan=plan)
    assert {"catcher_pass": True} in plans
    catcher = [w for stage, w in seen if stage == "shadow catcher"]
    main = [w for stage, w in seen if stage in ("photons", "photon_map", "render")]
    start = 1.0 - CATCHER_SHARE
    assert catcher and min(catcher) >= start - 1e-9 and max(main) <= start + 1e-9
    assert catcher == sorted(catcher) and catcher[-1] == pytest.approx(1.0)
    assert catcher[0] < start + 0.5 * CATCHER_SHARE  # it starts low in its span
