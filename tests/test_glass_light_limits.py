"""Light Paths limits on light through panes and shades (review32).

Light that reaches a diffuse point through a single-plane glass pane (engine/panelight.py)
or a Translucent BSDF shade (engine/shadelight.py) is, to Cycles, a diffuse bounce at the
point that BSDF sampling continues through the glass or onto the shade: Light Paths'
Diffuse 0 (or Max 0) leaves none of it (a live Cycles render of the pane box and the shade
panel read 0.000 there), and at Diffuse 1 a regathered point (reached by one diffuse
bounce already) must not add its own pane light (it did: the pane box read +17 % over
the analytic value). The shadow-ray estimators therefore take the hit's camera-side
bounce counts like the final gather does (integrator.direct_irradiance).
"""
import math

from engine import RenderSettings

import test_pane_sun as sun
import test_pane_world as world
import test_shade_light as shade


def _world_want():
    return world.ALBEDO * world.L * world._t_mean() / world.IOR ** 2


def test_world_through_a_pane_respects_diffuse_and_max_bounces():
    want = _world_want()
    for kw in (dict(diffuse_bounces=0), dict(max_bounces=0)):
        film = world._render(world._box_under_pane(), **kw)
        assert film.combined.max() == 0.0, kw
    # Diffuse 1: the camera's diffuse hit takes its light through the pane; the final
    # gather's regathered points (one diffuse bounce in) do not add theirs on top.
    film = world._render(world._box_under_pane(), diffuse_bounces=1)
    assert abs(film.direct.mean() / want - 1.0) < 0.02
    assert abs(film.combined.mean() / film.direct.mean() - 1.0) < 0.01


def test_sun_through_a_pane_respects_diffuse_bounces():
    film = sun._floor_under_pane().render(
        RenderSettings(spp=2, photons=50_000, seed=1, diffuse_bounces=0))
    assert film.combined.max() == 0.0
    film = sun._floor_under_pane().render(RenderSettings(spp=2, photons=50_000, seed=1))
    assert film.direct.mean() > 0.1


def test_lamp_through_a_shade_respects_diffuse_and_max_bounces():
    for kw in (dict(diffuse_bounces=0), dict(max_bounces=0)):
        film = shade._scene().render(RenderSettings(spp=4, seed=1, **kw))
        assert film.combined.max() == 0.0, kw
    film = shade._scene().render(RenderSettings(spp=8, seed=1, diffuse_bounces=1))
    img = film.combined.reshape(shade.W, shade.W, 3)
    want = shade.RHO / math.pi * shade._reference()[..., None] * shade.T
    assert abs((img / want).mean() - 1.0) < 0.04
