"""Paper mode, the paper's API names, the photon-hit pass and hard shadows (issue 17)."""
import numpy as np
import pytest

from engine import RenderSettings
from engine.api import (PAPER_FIGURE6_LADDER, PAPER_FIGURE6_RADIUS_SCALE, PaperScene,
                        cornell_box)
from engine.photons import CAUSTIC, DIRECT, INDIRECT
from engine.render import PHOTON_KIND_COLORS, photon_hit_budget
from engine.scene import SceneError


def _back_wall_bleed(film):
    """Green over red of the indirect light on the upper back wall of cornell_box (the
    patch above the block and the glass ball)."""
    h, w = film.height, film.width
    patch = film.indirect[int(0.1 * h):int(0.3 * h), int(0.3 * w):int(0.7 * w)]
    return patch[..., 1].mean() / patch[..., 0].mean()


def test_paper_mode_is_the_classic_estimator_without_final_gathering():
    st = RenderSettings(paper_mode=True, estimator="knn_simpson", final_gather=True)
    assert st.estimator == "classic" and st.final_gather is False
    assert RenderSettings().paper_mode is False
    with pytest.raises(ValueError, match="paper_mode"):
        RenderSettings(paper_mode="yes")


def test_paper_ladder_changes_the_colour_bleeding_in_paper_mode():
    """The Figure 6 ladder's first two rungs (1k photons r 4.0, 10k r 2.0 in the paper's
    units): in paper mode the photon count and radius show in the colour bleeding on the
    back wall; with final gathering they did not (issue 17: 1.203 at every rung)."""
    s = cornell_box(40, 30, glass_sphere=False)
    ratios = []
    for photons, r in PAPER_FIGURE6_LADDER[:2]:
        f = s.render(RenderSettings(photons=photons, caustic_photons=0, spp=1, seed=3,
                                    radius=r * PAPER_FIGURE6_RADIUS_SCALE, paper_mode=True))
        assert f.stats["radius_global"] == pytest.approx(r * PAPER_FIGURE6_RADIUS_SCALE)
        assert "estimated directly from the global map" in " ".join(f.stats["effects"])
        ratios.append(_back_wall_bleed(f))
    # Over seeds 0-7 the two rungs' means are 0.908 +- 0.050 and 0.853 +- 0.026: the old
    # "> 0.05" held at seed 3 by luck. What paper mode changes is that each rung's own
    # photons and radius reach the image at all (final gathering once gave the same value
    # to three digits at every rung), so the assertion is "differs".
    assert abs(ratios[0] - ratios[1]) > 0.01, ratios


def test_the_papers_names_set_the_render_settings():
    s = cornell_box(16, 12, glass_sphere=False)
    s.MaxRayTraceDepth = 3
    s.MaxPhotonTraceDepth = 5
    s.MaxPhotonSearchRadius = 0.3
    s.MinPhotonsForEstimate = 4
    s.DisablePhotonMapping()
    s.EnablePhotonMapping()
    assert (s.MaxRayTraceDepth, s.MaxPhotonTraceDepth, s.MaxPhotonSearchRadius) == (3, 5, 0.3)
    s.lights[0].MaxRayPerLightSrc = 1234
    f = s.render(spp=1, caustic_photons=0, paper_mode=True)
    assert f.stats["photons_emitted"] == 1234
    assert f.stats["radius_global"] == pytest.approx(0.3)
    assert "1,234 photons" in " ".join(f.stats["effects"])
    s.DisablePhotonMapping()
    f = s.render(spp=1)
    assert f.indirect.max() == 0 and f.stats.get("photons_emitted", 0) == 0


def test_max_ray_per_light_src_is_per_light():
    s = PaperScene(16, 12)
    s.add_plane((0, 0, 0), (0, 0, 1), 4, "white_diffuse")
    s.add_plane((0, 0, 3), (0, 0, -1), 4, "white_diffuse")
    strong = s.add_point_light((0, 0, 1.5), power=900)
    weak = s.add_point_light((1, 0, 1.5), power=100)
    s.set_camera((0, -5, 1.5), (0, 0, 1.5))
    s.MaxRayPerLightSrc = 500        # the paper: every light emits this many
    weak.MaxRayPerLightSrc = 2000    # ... unless it says otherwise
    from engine.render import photon_counts, prepare_context
    s.photons_per_light = s._photon_counts()
    ctx = prepare_context(s, RenderSettings(photons=2500))
    try:
        assert photon_counts(ctx, 2500) == [500, 2000]
    finally:
        ctx.accel.close()
    assert strong.MaxRayPerLightSrc is None and s.MaxRayPerLightSrc == 500


@pytest.mark.parametrize("name", ["MaxPhotonSearchRadiuss", "MaxRayPerLightSource"])
def test_unknown_attributes_are_refused_with_the_valid_names(name):
    s = cornell_box(8, 6)
    with pytest.raises(AttributeError, match="valid names: .*MaxPhotonSearchRadius"):
        setattr(s, name, 1.0)
    with pytest.raises(AttributeError, match="valid names: .*MaxRayPerLightSrc"):
        setattr(s.lights[0], name, 1.0)
    with pytest.raises(AttributeError, match="EnablePhotonMapping"):
        s.EnablePhotonMaping()
    with pytest.raises(SceneError, match="MaxRayTraceDepth"):
        s.MaxRayTraceDepth = -1
    with pytest.raises(SceneError, match="MaxRayPerLightSrc"):
        s.lights[0].MaxRayPerLightSrc = 1.5


def test_photon_hit_pass_is_filled_on_black_and_coloured_by_kind():
    s = cornell_box(48, 36)
    f = s.render(RenderSettings(photons=4000, caustic_photons=4000, spp=1, seed=2))
    hits = f.photon_hits
    dots = hits.max(axis=2) > 0
    assert 0.01 < dots.mean() < 0.5  # drawn, and black elsewhere
    # Not painted over the image: combined is the sum of the effects.
    total = sum(getattr(f, n) for n in ("direct", "indirect", "caustic", "specular", "emission"))
    np.testing.assert_array_equal(f.combined, total)
    # A pixel holds one kind's colour or a mix of them; all three kinds appear.
    colours = np.array([PHOTON_KIND_COLORS[k] for k in (DIRECT, INDIRECT, CAUSTIC)])
    px = hits[dots].astype(np.float64)
    for c in colours:
        assert np.any(np.all(np.abs(px - c) < 1e-6, axis=1)), c
    assert f.stats["photon_hits_shown"] > 0


def test_photon_hit_view_is_thinned_but_still_grows():
    assert photon_hit_budget(100, 160, 120) == 100
    counts = [photon_hit_budget(n, 160, 120) for n in (1_000, 10_000, 100_000, 400_000)]
    assert counts == sorted(counts) and counts[-1] < 0.3 * 160 * 120
    s = cornell_box(40, 30, glass_sphere=False)
    cover = []
    for photons in (2_000, 100_000):
        f = s.render(RenderSettings(photons=photons, caustic_photons=0, spp=1,
                                    final_gather=False))
        cover.append((f.photon_hits.max(axis=2) > 0).mean())
    assert cover[0] < cover[1] < 0.5, cover  # 100k photons did not saturate the view


def test_show_photons_output_is_the_view_and_tiles_agree():
    s = cornell_box(32, 24, glass_sphere=False)
    st = RenderSettings(photons=30000, caustic_photons=0, spp=1, show_photons=True)
    from engine.render import render
    full = render(s, st)
    np.testing.assert_array_equal(full.combined, full.photon_hits)
    tile = render(s, st, region=(0, 0, 16, 12))
    np.testing.assert_array_equal(tile.photon_hits, full.photon_hits[:12, :16])


def _shadow_scene():
    """A 0.3 m square 1 m below a 0.6 m area light, off its axis: its shadow on the floor
    is all penumbra (no point of the floor sees none of the light), seen from above."""
    s = PaperScene(48, 48)
    s.add_plane((0, 0, 0), (0, 0, 1), 6, "white_diffuse", name="floor")
    s.add_box((0.6, 0, 1.0), (0.3, 0.3, 0.02), "white_diffuse", name="blocker")
    s.add_rect_area_light((0, 0, 2.0), (0.6, 0.6), power=300, name="panel")
    s.set_camera((0, 0, 6), (0, 0, 0), up=(0, 1, 0), view_angle=40)
    return s


def test_soft_shadows_off_gives_a_hard_shadow_from_the_light_centre():
    s = _shadow_scene()
    soft = s.render(RenderSettings(photon_mapping=False, spp=8, seed=1))
    hard = s.render(RenderSettings(photon_mapping=False, spp=8, seed=1, soft_shadows="off"))
    lum_s, lum_h = soft.direct.mean(axis=2), hard.direct.mean(axis=2)
    # The point at the light's centre casts a 0.6 m umbra (x 0.9..1.5 m on the floor,
    # about 6 x 6 pixels); the area light casts none.
    dark_h, dark_s = int((lum_h == 0).sum()), int((lum_s == 0).sum())
    assert dark_h >= 16 and dark_h >= 4 * dark_s + 10, (dark_h, dark_s)
    # Away from the shadow, the centre point gives the whole light's irradiance (the
    # area light's size changes it by well under a percent at 2 m).
    block = (slice(4, 12), slice(4, 12))
    assert lum_h[block].mean() == pytest.approx(lum_s[block].mean(), rel=0.03)
    line = [x for x in hard.stats["effects"] if x.startswith("soft shadows 'panel'")][0]
    assert "off" in line and "hard shadows" in line


def test_cli_paper_switch_and_saved_photon_hit_pass(tmp_path, capsys):
    from engine.cli import main
    out = tmp_path / "f3.png"
    assert main(["render", "scenes/figure3.toml", "-o", str(out), "--paper", "--width", "24",
                 "--height", "18", "--spp", "1", "--photons", "3000", "--radius", "0.3",
                 "--save-passes", "--quiet"]) == 0
    assert (tmp_path / "f3.photon_hits.png").exists()
    from PIL import Image
    hits = np.asarray(Image.open(tmp_path / "f3.photon_hits.png"))[..., :3]
    assert 0 < (hits.max(axis=2) > 0).mean() < 0.6


def test_batch_command_takes_radius_estimator_final_gather_and_paper():
    from addon.batch import parse_args
    a = parse_args(["x.blend", "-o", "y.png", "--radius", "0.4", "--estimator", "classic",
                    "--no-final-gather", "--paper"])
    assert (a.radius, a.estimator, a.final_gather, a.paper) == (0.4, "classic", False, True)
    assert parse_args(["x.blend", "-o", "y.png"]).final_gather is None
    assert parse_args(["x.blend", "-o", "y.png", "--final-gather"]).final_gather is True


@pytest.mark.parametrize("name,caster", [("figure6", "glass_sphere"), ("figure7", None),
                                         ("figure8", "glass_sphere")])
def test_paper_scene_files_render(name, caster):
    import os

    from engine.scenefile import load_scene
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    scene, overrides = load_scene(os.path.join(root, "scenes", f"{name}.toml"))
    assert (scene.width, scene.height) == (320, 240)
    scene.width, scene.height = 32, 24
    overrides.update(spp=1, photons=4000, caustic_photons=6000, seed=1)
    film = scene.render(RenderSettings(**overrides))
    assert np.isfinite(film.combined).all() and film.combined.mean() > 0.01
    effects = " ".join(film.stats["effects"])
    if caster:
        # The caustic is in view (Figure 6's camera was moved to show it).
        assert f"'{caster}'" in effects and film.caustic.max() > 0
        assert (film.photon_hits == np.float32(PHOTON_KIND_COLORS[CAUSTIC])).all(axis=2).any()


def _lamp_in_a_box():
    s = PaperScene(24, 18)
    s.add_plane((0, 0, 0), (0, 0, 1), 10, "white_diffuse", name="floor")
    s.add_box((0, 0, 1), (1, 1, 1), "white_diffuse", name="lamp_box")
    s.add_point_light((0, 0, 1), power=100, name="bulb")
    s.set_camera((0, -6, 2), (0, 0, 1))
    return s


def test_a_light_shut_in_a_closed_mesh_is_named_and_indirect_light_is_not_claimed():
    s = _lamp_in_a_box()
    f = s.render(RenderSettings(spp=1, photons=2000))
    assert len(f.warnings) == 1 and "'bulb'" in f.warnings[0] and "'lamp_box'" in f.warnings[0]
    assert f.combined.max() == 0
    line = next(x for x in f.stats["effects"] if x.startswith("indirect light"))
    assert line.startswith("indirect light (global map): off") and "'lamp_box'" in line
    # The camera inside the same box sees the light: no warning, indirect light on.
    s.set_camera((0.2, 0.2, 1.2), (0, 0.5, 1))
    f = s.render(RenderSettings(spp=1, photons=2000))
    assert not f.warnings and any(x.startswith("indirect light (global map): on")
                                  for x in f.stats["effects"])


def test_a_spot_aimed_at_the_back_of_a_bounce_card_is_not_called_shut_in():
    """Every photon of a narrow spot hits the back of an open card (the winding's inside):
    the card shuts nothing in, so no warning, indirect light stays on and the light the
    card bounces reaches the floor (the trapped-light probe once followed the emission
    and turned indirect light off here)."""
    s = PaperScene(24, 18)
    s.add_plane((0, 0, 0), (0, 0, 1), 10, "white_diffuse", name="floor")
    # The card faces +x; the spot at x = -0.5 lights its back (-x side).
    s.add_plane((1.5, 0, 1), (1, 0, 0), 2.0, "white_diffuse", name="card")
    s.add_spot_light((-0.5, 0, 1), (1.5, 0, 1), power=200, spot_size_degrees=20,
                     name="key")
    s.set_camera((-3, -6, 3), (0.5, 0, 0.5))
    f = s.render(RenderSettings(spp=1, photons=2000))
    assert not f.warnings
    line = next(x for x in f.stats["effects"] if x.startswith("indirect light"))
    assert line.startswith("indirect light (global map): on")
    assert f.indirect.mean() > 0 and np.isfinite(f.combined).all()


def test_radius_mistakes_are_explained_and_the_report_shows_the_maps():
    s = cornell_box(24, 18)
    cheap = dict(spp=1, photons=4000, caustic_photons=2000, final_gather=False)
    auto = s.render(RenderSettings(**cheap))
    assert not auto.warnings
    report = auto.stats["effects"][-1]
    assert report.startswith("photon maps: on - ") and "automatic radius" in report
    assert f"{auto.stats['global_photons']:,} global photons stored" in report
    assert f"search radius {auto.stats['radius_global']:.4g} m" in report
    big = s.render(RenderSettings(radius=1000.0, **cheap))
    assert any("% of the scene's size" in w for w in big.warnings)
    assert "search radius 1000 m" in big.stats["effects"][-1]
    tiny = s.render(RenderSettings(radius=0.002, **cheap))
    assert any("below the photon spacing" in w for w in tiny.warnings)
    fine = s.render(RenderSettings(radius=0.3, **cheap))
    assert not fine.warnings


def test_a_plastic_ball_is_called_glossy_not_mirror_or_glass():
    s = PaperScene(24, 18)
    s.add_plane((0, 0, 0), (0, 0, 1), 10, "white_diffuse", name="floor")
    s.add_sphere((0, 0, 1), 1.0, "red_plastic", name="ball")
    s.add_sphere((2.5, 0, 1), 0.5, "glass", name="lens")
    s.add_rect_area_light((0, 0, 4), (1, 1), power=300)
    s.set_camera((0, -8, 2), (1, 0, 1))
    f = s.render(RenderSettings(spp=1, photons=2000, caustic_photons=1000))
    line = [x for x in f.stats["effects"] if x.startswith("specular reflection")][0]
    assert "glossy 'ball'" in line and "glass 'lens'" in line


def test_cli_photons_alone_scales_the_caustic_photons():
    """--photons without --caustic-photons keeps the defaults' ratio (a quick 5,000-photon
    render traced 200,000 caustic photons); an explicit --caustic-photons wins."""
    from engine.cli import _scene_and_overrides, build_parser
    parser = build_parser()
    base = ["render", "scenes/figure3.toml", "-o", "x.png"]
    _, over = _scene_and_overrides(parser.parse_args(base + ["--photons", "5000"]))
    d = RenderSettings()
    assert over["photons"] == 5000
    assert over["caustic_photons"] == 5000 * d.caustic_photons // d.photons
    _, over = _scene_and_overrides(parser.parse_args(base + ["--photons", "5000",
                                                             "--caustic-photons", "7"]))
    assert over["caustic_photons"] == 7
    _, over = _scene_and_overrides(parser.parse_args(base))
    assert "caustic_photons" not in over or over["caustic_photons"] == d.caustic_photons


def test_a_huge_radius_is_explained_in_a_short_line():
    from engine.render import radius_warnings
    (line,) = radius_warnings(1e300, 10.0, 50.0, 1000, 8)
    assert "search radius 1e+300 m is 1e+299 times the scene's size" in line
    assert "inf" not in line and "beyond any number" in line
    assert len(line) < 400
    (line,) = radius_warnings(50.0, 10.0, 50.0, 1000, 8)
    assert "is 500 % of the scene's size" in line
