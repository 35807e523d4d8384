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
