"""Light Paths > Max Bounces > Transparent counted along the whole camera path, as Cycles
counts it (issue 14, transparent48; docs/design.md, Transparent shadows).

Cycles (intern/cycles/kernel/integrator/path_state.h, path_state_next): every transparent
pass adds one to the path's transparent_bounce; the pass that brings it to
transparent_max_bounce flags PATH_RAY_TERMINATE_ON_NEXT_SURFACE, so the next surface
ends the path after its emission (shade_surface.h, integrate_surface_terminate) and a
ray that misses still sees the world. A hit's shadow rays start from the path's count
(shade_surface.h, integrate_surface_direct_light copies transparent_bounce to the shadow
path) and cross transparent_max_bounce minus it (Blender 5.0.1, measured:
tests/blender/test_transparent_path_limit_cycles.py). So N clear cards in front of an
emitter are crossed iff N <= T, and a floor lit by a sun through the N cards it is seen
through keeps its light iff 2 N <= T.

Scenes: an orthographic camera looking straight down through N horizontal 4 x 4 m cards
(z = 1, 1.1, ...) at a floor at z = 0; every pixel sees the floor through all the cards.
The cards' own lobe is black, so the pixel is the floor's light through them alone.
"""
import numpy as np
import pytest

from engine import RenderSettings
from engine.render import render
from engine.scene import Camera, Material
from engine.api import PaperScene

LE = 1.5             # W m^-2 sr^-1, the emitting floor's radiance
SUN, ALBEDO = 2.0, 0.5


def _cards_over(floor, n, alpha, sun=False, background=(0.0, 0.0, 0.0)):
    s = PaperScene(8, 8, background=background)
    if floor == "emitter":
        s.add_material(Material("floor", (0.0, 0.0, 0.0), emission=(LE, LE, LE)))
    else:
        s.add_material(Material("floor", (ALBEDO,) * 3))
    if floor is not None:
        s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "floor", name="floor")
    s.add_material(Material("card", (0.0, 0.0, 0.0), alpha=alpha))
    for i in range(n):
        s.add_plane((0, 0, 1.0 + 0.1 * i), (0, 0, 1), 4.0, "card", name=f"card{i}")
    if sun:
        s.add_sun((0, 0, -1), SUN)
    s.camera = Camera(position=(0, 0, 5), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=2.0)
    return s


def _pixel(scene, transparent, spp=1):
    film = render(scene, RenderSettings(spp=spp, photon_mapping=False, workers=1, seed=1,
                                        transparent_max_bounces=transparent))
    return film.combined[..., :3]


@pytest.mark.parametrize("transparent,n", [(3, 3), (3, 4), (3, 5), (8, 8), (8, 9)])
def test_camera_path_ends_at_the_surface_after_the_limit(transparent, n):
    """Clear cards over an emitter: seen through n <= T cards, not through more (the
    (T+1)-th card ends the path; before transparent48 every card was crossed)."""
    img = _pixel(_cards_over("emitter", n, alpha=0.0), transparent)
    want = LE if n <= transparent else 0.0
    assert np.allclose(img, want, rtol=1e-9, atol=0), (transparent, n, img.mean())


@pytest.mark.parametrize("n", [3, 4])
def test_the_world_is_seen_right_after_the_last_pass(n):
    """No floor: after T = 3 passes the ray that misses sees the world; a fourth card
    ends the path first."""
    img = _pixel(_cards_over(None, n, alpha=0.0, background=(0.25, 0.5, 1.0)), 3)
    want = np.array([0.25, 0.5, 1.0]) * (n <= 3)
    assert np.allclose(img, want, rtol=1e-9, atol=0), (n, img.mean(axis=(0, 1)))


@pytest.mark.parametrize("transparent,n,lit", [(3, 1, True), (3, 2, False), (3, 5, False),
                                               (5, 2, True), (5, 3, False),
                                               (8, 4, True), (8, 5, False)])
def test_shadow_rays_cross_only_the_passes_left(transparent, n, lit):
    """A sunlit floor seen through the n clear cards the sun shines through: the camera
    path crosses n, its shadow rays T - n more: lit iff 2 n <= T."""
    img = _pixel(_cards_over("lit", n, alpha=0.0, sun=True), transparent)
    want = ALBEDO / np.pi * SUN if lit else 0.0
    assert np.allclose(img, want, rtol=1e-9, atol=0), (transparent, n, img.mean())


def test_half_transparent_cards_at_the_default_limit():
    """Five cards of alpha 0.5 (a Mix of a Transparent BSDF and a black lobe): the
    camera path crosses all five with 0.5^5 of its throughput on average; at the default T = 8 the
    floor's shadow rays have 3 passes left and the sun is cut (Cycles: black), at
    T = 10 it comes through with 0.5^5 of it."""
    assert np.all(_pixel(_cards_over("lit", 5, alpha=0.5, sun=True), 8) == 0.0)
    # (The passes are chosen by Russian roulette: 64 px x 64 samples, ~2.5 % noise.)
    img = _pixel(_cards_over("lit", 5, alpha=0.5, sun=True), 10, spp=64)
    want = ALBEDO / np.pi * SUN * 0.5 ** 5 * 0.5 ** 5
    assert abs(img.mean() / want - 1.0) < 0.1, img.mean() / want


# The final gather (translimit49): a gather ray's chain is the camera path's next bounce,
# so it counts its passes from the camera path's and its end's shadow rays cross the
# passes left. Scenes: a camera at z = 0.5 looking down (orthographic) through k clear
# 8 x 8 m cards (z = 0.1, 0.2, ...) at a grey floor; a grey ceiling at z = 1 facing down,
# a point light at z = 0.7 and nc clear cards between them (z = 0.8, 0.9, ...). The
# floor's gather rays cross its k cards again (and the nc ones) to the ceiling; the cards
# span the floor's hemisphere but for ~0.3 % of its cosine-weighted rays.

def _floor_under_ceiling(k, nc):
    s = PaperScene(8, 8)
    s.add_material(Material("grey", (ALBEDO,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "grey", name="floor")
    s.add_plane((0, 0, 1.0), (0, 0, -1), 8.0, "grey", name="ceiling")
    s.add_material(Material("card", (0.0, 0.0, 0.0), alpha=0.0))
    for i in range(k):
        s.add_plane((0, 0, 0.1 + 0.1 * i), (0, 0, 1), 8.0, "card", name=f"card{i}")
    for i in range(nc):
        s.add_plane((0, 0, 0.8 + 0.1 * i), (0, 0, 1), 8.0, "card", name=f"top{i}")
    s.add_point_light((0, 0, 0.7), power=100.0)
    s.camera = Camera(position=(0, 0, 0.5), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=0.5)
    return s


def _gathered(scene, transparent, photon_mapping=True, radius=None):
    film = render(scene, RenderSettings(spp=4, photon_mapping=photon_mapping, workers=1,
                                        seed=1, transparent_max_bounces=transparent,
                                        photons=20_000, caustic_photons=2_000,
                                        radius=radius))
    return film.combined[..., :3]


@pytest.mark.parametrize("transparent", [3, 4])
def test_gather_chains_count_on_from_the_camera_path(transparent):
    """k = 2 cards, none at the ceiling: the floor's gather chains reach the ceiling after
    2 + 2 passes, so at T = 3 and 4 they end before it (Cycles' path ends at the surface
    after its T-th pass: no indirect light, the image is the direct-only render's; at
    T = 3 the floor's own shadow rays are cut too); at T = 5 the ceiling's photon-lit
    light comes back. On main the chains counted from 0: T = 3 and 4 read the ceiling."""
    direct = _gathered(_floor_under_ceiling(2, 0), transparent, photon_mapping=False)
    full = _gathered(_floor_under_ceiling(2, 0), transparent)
    assert (direct.mean() > 0) == (transparent == 4), direct.mean()
    assert np.array_equal(full, direct), (full.mean(), direct.mean())
    # (T = 5: the same direct light, the ceiling's added)
    full5 = _gathered(_floor_under_ceiling(2, 0), 5)
    direct5 = _gathered(_floor_under_ceiling(2, 0), 5, photon_mapping=False)
    assert full5.mean() > 1.2 * direct5.mean() > 0, (full5.mean(), direct5.mean())


def test_a_regathered_end_crosses_the_passes_left():
    """k = 1 card over the floor, nc = 2 between the lamp and the ceiling; a 10 m search
    radius makes every gather ray short, so each end gathers again (direct light by
    shadow rays). Its chain arrives with 1 + 1 + 2 = 4 passes: at T = 5 its shadow rays
    have 1 left for the 2 cards (the ceiling is dark to them, and its own gather ray ends
    after one more pass), so the floor keeps its direct light alone; at T = 8 the ceiling
    is lit. On main the end's shadow rays had the full T: lit at both."""
    for transparent, lit_ceiling in ((5, False), (8, True)):
        direct = _gathered(_floor_under_ceiling(1, 2), transparent, photon_mapping=False)
        full = _gathered(_floor_under_ceiling(1, 2), transparent, radius=10.0)
        assert direct.mean() > 0
        if lit_ceiling:
            assert full.mean() > 1.2 * direct.mean(), (transparent, full.mean(), direct.mean())
        else:
            assert np.array_equal(full, direct), (transparent, full.mean(), direct.mean())


def _ao_through_cards(k, transparent):
    """The AO pass (distance 10 m) of a floor seen from above through k clear 40 x 40 m
    cards at z = 1, 1.1, ...: a cosine-weighted AO ray leaving the floor at angle theta
    reaches height z within the distance iff cos(theta) >= z / 10, with probability
    1 - (z / 10)^2."""
    s = PaperScene(8, 8, background=(1.0, 1.0, 1.0))
    s.add_material(Material("floor", (ALBEDO,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, "floor", name="floor")
    s.add_material(Material("card", (0.0, 0.0, 0.0), alpha=0.0))
    for i in range(k):
        s.add_plane((0, 0, 1.0 + 0.1 * i), (0, 0, 1), 40.0, "card", name=f"card{i}")
    s.camera = Camera(position=(0, 0, 5), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=2.0)
    film = render(s, RenderSettings(spp=64, photon_mapping=False, workers=1, seed=1,
                                    transparent_max_bounces=transparent,
                                    data_passes=("ao",), ao_distance=10.0))
    return film.data["ao"][..., 0]


@pytest.mark.parametrize("transparent,k,want", [(3, 2, (1.1 / 10) ** 2), (1, 1, 0.0),
                                                (2, 2, 0.0)])
def test_ao_rays_cross_only_the_passes_left(transparent, k, want):
    """Cycles' AO ray is a shadow path with the camera path's transparent bounces
    (Blender 5.0.1, docs/compatibility.md "### translimit49": 2 clear cards at T = 3
    read 0.013, at T = 4 and 8 1.0; 3 small cards at T = 3: 0.0002, no AO where the
    path ends): at T = 3 behind 2 cards it crosses only the first card (the rays that
    reach z = 1.1 within 10 m are blocked: (1.1 / 10)^2 get through), at T = 4 both; at
    T = 1 behind 1 and T = 2 behind 2 the floor ends the path (no AO sample). On main
    every AO ray crossed them all: 1.0."""
    ao = _ao_through_cards(k, transparent)
    assert abs(ao.mean() - want) < 0.01, (transparent, k, ao.mean(), want)
    if k == 2 and transparent == 3:
        assert abs(_ao_through_cards(2, 4).mean() - 1.0) < 1e-9


def _subsurface_through_cards(transparent):
    """A subsurface box (Cycles' random walk, Radius 0.2 m) seen from above through 2
    clear cards, lit by a sun straight down through the same cards; direct light only."""
    from engine import subsurfacewalk as sw
    from engine.api import box_mesh
    from engine.scene import Mesh
    s = PaperScene(8, 8)
    sp = sw.SubsurfaceParams.make(1.0, (0.8,) * 3, (0.2, 0.2, 0.2), 1.4, 0.0, 0.5)
    s.add_material(Material("skin", tuple(sp.stand_in()), roughness=0.5, specular=0.0,
                            subsurface=sp))
    v, f = box_mesh((0, 0, -0.5), 1.0)
    s.add_mesh(Mesh("box", np.asarray(v, float) * np.array([6.0, 6.0, 1.0]), f,
                    materials=["skin"]))
    s.add_material(Material("card", (0.0, 0.0, 0.0), alpha=0.0))
    for i in range(2):
        s.add_plane((0, 0, 1.0 + 0.1 * i), (0, 0, 1), 8.0, "card", name=f"card{i}")
    s.add_sun((0, 0, -1), SUN)
    s.camera = Camera(position=(0, 0, 5), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=2.0)
    film = render(s, RenderSettings(spp=4, photon_mapping=False, workers=1, seed=1,
                                    transparent_max_bounces=transparent))
    return film.combined[..., :3]


def test_subsurface_exits_cross_only_the_passes_left():
    """The walk keeps the path's transparent bounces (Cycles' subsurface path state), so
    its exits' shadow rays cross T - 2 cards as the entry's do: at T = 3 the sun is cut
    at both (black), at T = 4 it lights both. On main the exits' shadow rays had the
    full T: lit at T = 3."""
    assert np.all(_subsurface_through_cards(3) == 0.0)
    assert _subsurface_through_cards(4).mean() > 0.1


def _floor_under_pane_and_cards(transparent):
    """A floor under a single-plane glass pane (z = 1, IOR 1.5) and 2 clear 10 m cards
    above it (z = 1.1, 1.2), a sun 70 degrees off the zenith; an orthographic camera at
    z = 0.8 sees the middle 0.2 m of the floor through 2 small clear cards (z = 0.3,
    0.35, 0.24 m wide) that the floor's rays towards the pane (refracted to 38.8 degrees)
    pass beside. Direct light only (the pane's next-event estimate, engine/panelight.py)."""
    s = PaperScene(8, 8)
    s.add_material(Material("floor", (ALBEDO,) * 3))
    s.add_material(Material("glass", (1.0, 1.0, 1.0), transmission=1.0, ior=1.5,
                            roughness=0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 10.0, "floor", name="floor")
    s.add_plane((0, 0, 1.0), (0, 0, 1), 10.0, "glass", name="pane")
    s.add_material(Material("card", (0.0, 0.0, 0.0), alpha=0.0))
    for i in range(2):
        s.add_plane((0, 0, 0.3 + 0.05 * i), (0, 0, 1), 0.24, "card", name=f"card{i}")
        s.add_plane((0, 0, 1.1 + 0.1 * i), (0, 0, 1), 10.0, "card", name=f"top{i}")
    t = np.radians(70.0)
    s.add_sun((np.sin(t), 0.0, -np.cos(t)), strength=SUN, angle_degrees=1.0, name="sun")
    s.camera = Camera(position=(0, 0, 0.8), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=0.2)
    film = render(s, RenderSettings(spp=4, photon_mapping=False, workers=1, seed=1,
                                    transparent_max_bounces=transparent))
    return film.combined[..., :3]


def test_pane_light_crosses_only_the_passes_left():
    """The sun's light through the pane is Cycles' continuation through the glass, which
    carries the camera path's 2 passes: the 2 cards past the pane are crossed at T = 4
    (the same light as at T = 8), not at T = 3. On main the rays on from the pane had the
    full T: lit at T = 3."""
    assert np.all(_floor_under_pane_and_cards(3) == 0.0)
    lit = _floor_under_pane_and_cards(4)
    assert lit.mean() > 0.0
    np.testing.assert_array_equal(lit, _floor_under_pane_and_cards(8))


def _floor_under_a_card_and_a_metal_ceiling():
    """A grey floor seen straight down through one clear card (z 0.1); over it a rough
    metal ceiling (z 1, roughness 0.2: a blurred glossy vertex of the Filter Glossy
    split's gather chains), and a point lamp at z 0.7 under two small clear cards (z 0.75,
    0.8): a ceiling point's shadow ray to the lamp crosses both small cards, and the
    gather chain that reaches it has crossed the floor's card twice (down and up)."""
    s = PaperScene(8, 8)
    s.add_material(Material("grey", (0.5,) * 3))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "grey", name="floor")
    s.add_material(Material("metal", (0.9,) * 3, metallic=1.0, roughness=0.2))
    s.add_plane((0, 0, 1.0), (0, 0, -1), 8.0, "metal", name="ceiling")
    s.add_material(Material("card", (0.0, 0.0, 0.0), alpha=0.0))
    s.add_plane((0, 0, 0.1), (0, 0, 1), 8.0, "card", name="card0")
    for i in range(2):
        s.add_plane((0, 0, 0.75 + 0.05 * i), (0, 0, 1), 0.6, "card", name=f"top{i}")
    s.add_point_light((0, 0, 0.7), power=100.0)
    s.camera = Camera(position=(0, 0, 0.5), rotation=np.eye(3), kind="ORTHO", ortho_scale=0.5)
    return s


def test_glossy_chain_vertices_cross_only_the_passes_left(monkeypatch):
    """The Filter Glossy split's chain vertices (glossysplit.GatherChains.vertex) sample
    lights with shadow rays that cross only the transparent passes their path left
    (review49: they crossed the full limit): at T = 3 the ceiling's shadow rays have 1
    pass left and the lamp's two cards block them where they lie between, at T = 8 they
    cross; the same ceiling rows either way."""
    import sys

    from engine import integrator
    calls = []
    real = integrator.direct_irradiance

    def spy(ctx, hit, *a, **kw):
        out = real(ctx, hit, *a, **kw)
        if sys._getframe(1).f_code.co_filename.endswith("glossysplit.py"):
            calls.append((len(out), float(np.asarray(out).sum()), kw.get("used")))
        return out

    monkeypatch.setattr(integrator, "direct_irradiance", spy)
    light = {}
    for t in (3, 8):
        calls.clear()
        render(_floor_under_a_card_and_a_metal_ceiling(),
               RenderSettings(spp=4, workers=1, seed=1, transparent_max_bounces=t,
                              photons=20_000, caustic_photons=2_000,
                              cycles_filter_glossy=1.0))
        # The gather rays' first hits are the floor's card (crossed once, by the camera
        # ray), the next the ceiling (crossed twice: down and up).
        assert calls and all(used is not None for _, _, used in calls)
        ceiling = [(n, v) for n, v, used in calls if np.all(np.asarray(used) == 2)]
        assert ceiling, "the ceiling is no chain vertex"
        light[t] = ceiling[0]  # the first sample pass's ceiling vertices
    assert light[3][0] == light[8][0]
    assert light[3][1] < 0.5 * light[8][1], light


def _emitter_under_ior1_panes(k, transparent, transmission):
    s = PaperScene(8, 8)
    s.add_material(Material("floor", (0.0, 0.0, 0.0), emission=(LE, LE, LE)))
    s.add_plane((0, 0, 0), (0, 0, 1), 20.0, "floor", name="floor")
    s.add_material(Material("pane", (1.0, 1.0, 1.0), transmission=1.0, roughness=0.0,
                            ior=1.0, node="glass"))
    for i in range(k):
        s.add_plane((0, 0, 1.0 + 0.1 * i), (0, 0, 1), 20.0, "pane", name=f"pane{i}")
    s.camera = Camera(position=(0, 0, 5), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=1.0)
    film = render(s, RenderSettings(spp=4, photon_mapping=False, workers=1, seed=1,
                                    transparent_max_bounces=transparent,
                                    transmission_bounces=transmission, max_bounces=12))
    return film.combined[..., :3]


@pytest.mark.parametrize("k,transparent,transmission,seen", [
    (3, 2, 12, True), (10, 8, 12, True), (3, 2, 3, True)])
def test_an_ior_1_refraction_is_a_transmission_bounce(k, transparent, transmission, seen):
    """Smooth Glass / Refraction BSDFs of IOR 1 over an emitter (Blender 5.0.1, 8 x 8,
    docs/compatibility.md "### translimit49"): seen through 3 panes at Transparent 2 or
    Transmission 2 (the 3rd transmission bounce ends the path at the next surface, the
    emitter), through 10 at Transparent 8 / Transmission 12, not through 10 at
    Transmission 2 nor 3 at Max Bounces Transparent 0 / Transmission 0: the unbent
    refraction is a transmission bounce, not a transparent pass. On main it counted as a
    pass: 3 panes at Transparent 2 and 10 at 8 were black."""
    img = _emitter_under_ior1_panes(k, transparent, transmission)
    assert np.allclose(img, LE if seen else 0.0, rtol=1e-6, atol=0), img.mean()
    assert np.all(_emitter_under_ior1_panes(10, 8, 2) == 0.0)
    assert np.all(_emitter_under_ior1_panes(3, 0, 0) == 0.0)
