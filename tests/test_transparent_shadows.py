"""Transparent shadows (engine/shadowtransmittance.py) and alpha cut-outs (per-hit alpha,
engine/textures.py material_alpha): shadow rays cross alpha < 1 surfaces with (1 - alpha)
multiplied in, up to the transparent bounce limit; an alpha texture cuts camera rays,
shadow rays and photons alike."""
import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.bsdf import surface_hit
from engine.integrator import Counters, direct_irradiance
from engine.photons import CAUSTIC, DIRECT, trace_photons
from engine.render import prepare_context, render
from engine.scene import Material
from engine.shadernodes import ImageLookup
from engine.shadowtransmittance import ShadowTransmittance
from engine.textures import ImageTexture


def _floor_hits(ctx, n, seed=0, half=1.0):
    rng = np.random.default_rng(seed)
    o = np.column_stack([rng.uniform(-half, half, n), rng.uniform(-half, half, n),
                         np.full(n, 0.05)])
    d = np.tile([0.0, 0.0, -1.0], (n, 1))
    _, prim, u, v = ctx.accel.intersect(o, d)
    keep = prim >= 0
    return surface_hit(ctx.geo, ctx.table, prim[keep], u[keep], v[keep], d[keep])


def _sun_over_cards(alphas, gap=0.1, alpha_texture=None, tints=None, **settings):
    """A floor at z = 0 under a straight-down sun of 2 W/m^2 and len(alphas) horizontal
    4 x 4 m cards stacked above it (the first at z = 1), card i with alpha alphas[i] (and
    transparent tint tints[i])."""
    s = PaperScene(8, 6)
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
    for i, a in enumerate(alphas):
        name = f"card{i}"
        tint = (1.0, 1.0, 1.0) if tints is None else tints[i]
        s.add_material(Material(name, (0.5, 0.5, 0.5), alpha=a, alpha_texture=alpha_texture,
                                transparent_tint=tint))
        s.add_plane((0, 0, 1.0 + gap * i), (0, 0, 1), 4.0, name, name=name)
    s.add_sun((0, 0, -1), 2.0)
    s.set_camera((0, -6, 3), (0, 0, 0))
    return prepare_context(s, RenderSettings(workers=1, **settings))


def test_two_half_transparent_planes_pass_a_quarter():
    ctx = _sun_over_cards([0.5, 0.5])
    assert ctx.shadow is not None
    hit = _floor_hits(ctx, 400)
    E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
    assert np.allclose(E, 2.0 * 0.25, rtol=1e-12)


def test_tinted_cards_multiply_their_colours():
    """Cycles' transparent shadows carry the transparent closures' weight as a colour:
    a card of alpha 0.5 tinted (1, 0.5, 0) over one of alpha 0 tinted (0.5, 1, 1) pass
    0.5 x (0.5, 0.5, 0) of the sun; a black tint blocks like an opaque card."""
    ctx = _sun_over_cards([0.5, 0.0], tints=[(1.0, 0.5, 0.0), (0.5, 1.0, 1.0)])
    E = direct_irradiance(ctx, _floor_hits(ctx, 200), np.random.default_rng(1), Counters())
    assert np.allclose(E, 2.0 * np.array([0.25, 0.25, 0.0]), rtol=1e-12)
    ctx = _sun_over_cards([0.0], tints=[(0.0, 0.0, 0.0)])
    E = direct_irradiance(ctx, _floor_hits(ctx, 200), np.random.default_rng(1), Counters())
    assert np.all(E == 0.0)


def test_tinted_pass_colours_camera_rays_and_photons():
    """A clear card tinted (0.2, 0.6, 1.0) over a white floor lit by a straight-down sun,
    seen from above through the card: the floor takes the tint twice (light in by shadow
    rays, view out by the camera ray's pass); an untinted card leaves the floor as without
    it. Photons that cross the card carry the tint too (their power)."""
    from helpers import top_down_plane

    def scene(tint):
        s = top_down_plane(albedo=0.5, res=24, view=4.0)
        s.add_material(Material("card", (0.8, 0.8, 0.8), alpha=0.0, transparent_tint=tint))
        s.add_plane((0, 0, 1.0), (0, 0, 1), 2.0, "card", name="card")
        s.add_sun((0, 0, -1), 2.0)
        return s

    def film_for(tint):
        return render(scene(tint), RenderSettings(spp=2, photons=20000,
                                                  caustic_photons=5000, workers=1, seed=2))
    tint = np.array([0.2, 0.6, 1.0])
    clear, tinted = film_for((1.0, 1.0, 1.0)), film_for(tuple(tint))
    h = clear.combined.shape[0]
    c = slice(h // 2 - 3, h // 2 + 3)  # pixels under the card's centre
    lit = 0.5 / np.pi * 2.0
    assert np.allclose(clear.combined[c, c], lit, rtol=1e-5)
    assert np.allclose(tinted.combined[c, c], lit * tint * tint, rtol=1e-5)
    ctx = prepare_context(scene(tuple(tint)), RenderSettings(workers=1))
    ph = trace_photons(ctx, ctx.lights, [20000], caustic_only=False, stream=1)
    z = ph.position[:, 2].astype(np.float64) + ctx.geo.offset[2]
    x = ph.position[:, :2].astype(np.float64) + ctx.geo.offset[:2]
    under = (np.abs(z) < 1e-3) & np.all(np.abs(x) < 0.9, axis=1) & (ph.kind == DIRECT)
    beside = (np.abs(z) < 1e-3) & np.any(np.abs(x) > 1.1, axis=1) & (ph.kind == DIRECT)
    assert under.any() and beside.any()
    p_under = ph.power[under].astype(np.float64)
    p_beside = ph.power[beside].astype(np.float64)
    assert np.allclose(p_under / p_beside[0], tint, rtol=1e-5)


def test_opaque_card_still_blocks_and_open_scene_has_no_retrace():
    ctx = _sun_over_cards([0.5, 1.0])
    hit = _floor_hits(ctx, 200)
    E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
    assert np.all(E == 0.0)
    assert _sun_over_cards([1.0]).shadow is None  # nothing transparent: occlusion only


def test_transparent_bounce_limit_blocks_as_cycles():
    """Cycles: a shadow ray crosses up to transparent_max_bounces surfaces; one more blocks
    it (lit iff N <= T)."""
    for n, cap, lit in ((3, 3, True), (3, 2, False), (8, 8, True), (9, 8, False)):
        ctx = _sun_over_cards([0.9] * n, transparent_max_bounces=cap)
        E = direct_irradiance(ctx, _floor_hits(ctx, 50), np.random.default_rng(1), Counters())
        expect = 2.0 * 0.1 ** n if lit else 0.0
        assert np.allclose(E, expect, rtol=1e-9, atol=0), (n, cap)
    assert _sun_over_cards([0.5], transparent_max_bounces=0).shadow is None


def test_thousand_stacked_planes_end_in_bounded_steps():
    """1000 clear (alpha 0) planes 1 mm apart: the loop stops at the limit (blocked), and
    with a limit above 1000 all of them are crossed (transmittance 1)."""
    ctx = _sun_over_cards([0.0] * 1000, gap=0.001)
    geo = ctx.geo
    assert geo.count == 2 + 2000
    E = direct_irradiance(ctx, _floor_hits(ctx, 20), np.random.default_rng(1), Counters())
    assert np.all(E == 0.0)
    ctx = _sun_over_cards([0.0] * 1000, gap=0.001, transparent_max_bounces=1024)
    E = direct_irradiance(ctx, _floor_hits(ctx, 20), np.random.default_rng(1), Counters())
    assert np.allclose(E, 2.0, rtol=1e-12)


def test_transmittance_of_rays_and_refusal_of_bad_limit():
    ctx = _sun_over_cards([0.5, 0.25])
    o = (np.array([[0.0, 0.0, 3.0], [0.0, 0.0, 3.0], [3.0, 3.0, 3.0]])
         - ctx.geo.offset).astype(np.float32)  # re-centred world space
    d = np.tile(np.float32([0, 0, -1]), (3, 1))
    # To just above the floor / between the cards (z = 1.05) / beside the cards.
    t = np.array([2.95, 1.95, 2.95], np.float32)
    tr = ctx.shadow.transmittance(o, d, t)
    assert tr.shape == (3, 3)
    assert np.allclose(tr, np.array([0.5 * 0.75, 1.0 - 0.25, 1.0])[:, None])
    with pytest.raises(ValueError, match="max_hits"):
        ShadowTransmittance(ctx.geo, ctx.table, -1)


def _alpha_checker(n=8):
    """An n x n RGBA image: alpha 1 on the left half, 0 on the right (u >= 0.5)."""
    px = np.ones((n, n, 4), np.float32)
    px[:, n // 2:, 3] = 0.0
    return ImageTexture(px, interpolation="Closest", name="cutout")


def test_alpha_texture_cuts_shadow_where_alpha_is_zero():
    """A card whose right half is cut out (image alpha 0) shadows only under its left
    half."""
    node = ImageLookup(_alpha_checker(), output="ALPHA")
    ctx = _sun_over_cards([1.0], alpha_texture=node)
    assert ctx.shadow is not None
    hit = _floor_hits(ctx, 400, half=1.8)
    E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())[:, 0]
    y = hit.p[:, 1] + ctx.geo.offset[1]
    # add_plane's frame for normal +z has its u axis along -y: the cut-out half is y < 0.
    kept, cut = y > 0.05, y < -0.05
    assert kept.sum() > 100 and cut.sum() > 100
    assert np.all(E[kept] == 0.0) and np.allclose(E[cut], 2.0)
    a = hit.alpha  # the floor has no alpha texture: its alpha is 1 everywhere
    assert a is not None and np.all(a == 1.0)


def test_photons_through_a_cutout_are_direct_not_caustic_and_not_stored_on_it():
    node = ImageLookup(_alpha_checker(), output="ALPHA")
    ctx = _sun_over_cards([1.0], alpha_texture=node)
    ph = trace_photons(ctx, ctx.lights, [20000], caustic_only=False, stream=1)
    z = ph.position[:, 2].astype(np.float64) + ctx.geo.offset[2]
    on_card = np.abs(z - 1.0) < 1e-3
    y = ph.position[:, 1].astype(np.float64) + ctx.geo.offset[1]
    assert on_card.any() and np.all(y[on_card] > -1e-3)  # none stored on the cut-out half
    on_floor = np.abs(z) < 1e-3
    first = on_floor & (ph.kind == DIRECT)
    assert first.any() and not np.any(ph.kind == CAUSTIC)


def test_same_seed_same_image_with_transparent_shadows():
    def scene():
        s = PaperScene(24, 18)
        s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
        s.add_material(Material("card", (0.8, 0.2, 0.2), alpha=0.4))
        s.add_plane((0, 0, 1.0), (0.3, 0, 1), 2.0, "card", name="card")
        s.add_point_light((0.5, 0.2, 3.0), 300.0, radius=0.3)
        s.set_camera((0, -5, 3), (0, 0, 0.3))
        return s
    st = RenderSettings(spp=4, photons=5000, caustic_photons=2000, workers=1, seed=3)
    a = render(scene(), st).combined
    b = render(scene(), st).combined
    assert np.array_equal(a, b) and np.isfinite(a).all() and a.mean() > 0


def test_shadow_of_a_transparent_card_is_direct_light_without_noise():
    """A camera-invisible card of alpha 0.4 between a straight-down sun and a floor seen
    from above: the floor's direct pass under the card is exactly 0.6 of the lit floor's
    (shadow rays carry it; the sun has no size, so no noise at all), and no caustic photon
    carries the same light a second time. Before transparent shadows this light came from
    the caustic map only (grainy: pixel std 3x the lit floor's in the feature-matrix
    scene)."""
    from helpers import pixel_to_world, top_down_plane
    s = top_down_plane(albedo=0.5, res=32, view=4.0)
    s.add_material(Material("card", (0.8, 0.1, 0.1), alpha=0.4))
    card = s.add_plane((0, 0, 1.0), (0, 0, 1), 2.0, "card", name="card")
    card.visible_camera = False
    s.add_sun((0, 0, -1), 2.0)
    film = render(s, RenderSettings(spp=2, photons=20000, caustic_photons=20000, workers=1))
    x, y = pixel_to_world(s, 4.0)
    under = (np.abs(x) < 0.8) & (np.abs(y) < 0.8)
    beside = (np.abs(x) > 1.2) | (np.abs(y) > 1.2)
    lit = 0.5 / np.pi * 2.0
    direct = film.direct[..., 0].astype(np.float64)
    assert np.allclose(direct[beside], lit, rtol=1e-5)
    assert np.allclose(direct[under], 0.6 * lit, rtol=1e-5)
    assert np.all(film.caustic == 0.0)
    assert any("shadow rays cross up to 8" in str(d) for d in film.stats["effects"])


def test_shadow_invisible_cards_are_not_crossed_and_do_not_block():
    """Ray visibility (engine/visibility.py): a card invisible to shadow rays neither
    attenuates (transparent) nor blocks (opaque) them; the visible card still does."""
    s = PaperScene(8, 6)
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
    s.add_material(Material("half", (0.5, 0.5, 0.5), alpha=0.5))
    s.add_plane((0, 0, 1.0), (0, 0, 1), 4.0, "half", name="seen")
    s.add_plane((0, 0, 1.2), (0, 0, 1), 4.0, "half", name="unseen").visible_shadow = False
    s.add_plane((0, 0, 1.4), (0, 0, 1), 4.0, "white_diffuse",
                name="opaque").visible_shadow = False
    s.add_sun((0, 0, -1), 2.0)
    s.set_camera((0, -6, 3), (0, 0, 0))
    ctx = prepare_context(s, RenderSettings(workers=1))
    E = direct_irradiance(ctx, _floor_hits(ctx, 100), np.random.default_rng(1), Counters())
    assert np.allclose(E, 1.0, rtol=1e-12)


def test_glossy_floor_under_a_card_counts_the_light_once():
    """A rough metal floor under a black alpha-0.5 card (no reflection: it only passes
    half the light), lit by a small area light, ray tracing only: the floor is exactly
    half as bright as in the open. The glossy lobe's sampled rays that pass the card and
    meet the light are MIS-weighted against the shadow rays, which pass the card too
    (the camera path keeps the floor's MIS state through the pass,
    shadowtransmittance.CameraPassages); weighted in full they read 0.824."""
    def film(card):
        s = PaperScene(24, 18)
        s.add_plane((0, 0, 0), (0, 0, 1), 6.0,
                    Material("metal", (0.8, 0.8, 0.8), metallic=1.0, roughness=0.3),
                    name="floor")
        if card:
            s.add_plane((0, 0, 1.0), (0, 0, 1), 4.0, Material("card", (0, 0, 0), alpha=0.5),
                        name="card")
        s.add_rect_area_light((0.0, 0.0, 3.0), (0.5, 0.5), power=200.0)
        s.set_camera((0, -0.6, 0.6), (0, 0.3, 0), view_angle=50.0)
        return s.render(RenderSettings(spp=16, photon_mapping=False, seed=1, workers=1))
    card, open_ = film(True), film(False)
    assert card.direct.mean() / open_.direct.mean() == pytest.approx(0.5, rel=1e-6)
    assert card.combined.mean() / open_.combined.mean() == pytest.approx(0.5, rel=0.01)


def test_summed_transparency_above_one_tint_passes_the_whole_sun():
    """An Add Shader of a white Transparent BSDF and a surface (Cycles sums closure
    weights, bsdf_transparent_setup) exports alpha 1/2, tint 2, closure weight 2: the
    pass transmits (1 - alpha) x tint = 1, so the floor under the card gets the whole
    sun, and photons cross it with their power whole. The tint is kept (no warning)
    while (1 - alpha) x tint stays within 1; above that it is clamped there, warned, and
    with an alpha texture (alpha lower per hit) the tint itself stays within 1."""
    ctx = _sun_over_cards([0.5], tints=[(2.0, 2.0, 2.0)])
    from engine.closures import principled as pr
    assert np.allclose(ctx.table.closure_params[:, pr.M_TTINT:pr.M_TTINT + 3].max(), 2.0)
    E = direct_irradiance(ctx, _floor_hits(ctx, 200), np.random.default_rng(1), Counters())
    assert np.allclose(E, 2.0, rtol=1e-12)
    ph = trace_photons(ctx, ctx.lights, [100000], caustic_only=False, stream=1)
    z = ph.position[:, 2].astype(np.float64) + ctx.geo.offset[2]
    x = ph.position[:, :2].astype(np.float64) + ctx.geo.offset[:2]
    floor = (np.abs(z) < 1e-3) & (ph.kind == DIRECT)
    under = floor & np.all(np.abs(x) < 1.9, axis=1)
    beside = floor & np.any(np.abs(x) > 2.1, axis=1)
    assert under.any() and beside.any()
    # The photons' flux per m^2 on the floor: as much under the card as beside it (the
    # photons take the pass by its share of the lobes' weights, their power x weight /
    # probability; 100k photons: ~1 % of noise).
    flux_under = ph.power[under].astype(np.float64).sum(axis=0) / 3.8 ** 2
    flux_beside = ph.power[beside].astype(np.float64).sum(axis=0) / (8.0 ** 2 - 4.2 ** 2)
    assert np.allclose(flux_under, flux_beside, rtol=0.03), (flux_under, flux_beside)
    m = Material("sum", (0.5, 0.5, 0.5), alpha=0.5, transparent_tint=(2.0, 1.0, 0.5))
    assert np.allclose(m.transparent_tint, (2.0, 1.0, 0.5)) and not m.warnings
    m = Material("over", (0.5, 0.5, 0.5), alpha=0.5, transparent_tint=(3.0, 1.0, 0.5))
    assert np.allclose(m.transparent_tint, (2.0, 1.0, 0.5))
    assert any("clamped" in w for w in m.warnings)
    node = ImageLookup(_alpha_checker(), output="ALPHA")
    m = Material("cut", (0.5, 0.5, 0.5), alpha=0.5, alpha_texture=node,
                 transparent_tint=(2.0, 1.0, 0.5))
    assert np.allclose(m.transparent_tint, (1.0, 1.0, 0.5)) and m.warnings
