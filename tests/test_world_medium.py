"""The world volume (engine/worldmedium.py; Scene.world_medium): a homogeneous medium
filling all space outside the objects. Analytic checks: a floor under a point light lit
and seen through it (I cos / r^2 exp(-sigma_t r)); the lamps' light it scatters along
camera rays that end on a floor and along rays escaping to infinity, by quadrature as
tests/test_volume_scatter.py; the world's light and suns off (T = 0 at infinity); alpha 1
with Film Transparent (Cycles' average(throughput) at the background: 0); photons dimmed;
the scene file's [world_medium]; the effect report."""
import math

import numpy as np
import pytest

from engine import RenderSettings, WorldMedium
from engine.api import PaperScene
from engine.render import render
from engine.scene import Material, SceneError

LIGHT = np.array([1.2, 0.3, 1.5])  # beside the film: no ray passes within 0.7 m
POWER = 200.0
SIGMA_S = np.array([0.3, 0.5, 0.8])  # 1/m
SIGMA_A = np.array([0.2, 0.1, 0.05])


def _floor_scene(sigma_a, sigma_s=(0.0, 0.0, 0.0), lit_world=False):
    """A white floor at z 0 (4 m), a 100 W point light at z 1 and a perspective camera at
    z 2 looking straight down (view angle 2 degrees), in a world medium; lit_world: a
    white Background of strength 5 and a sun of strength 5 too (both must light nothing)."""
    s = PaperScene(8, 8, background=(5.0, 5.0, 5.0) if lit_world else (0.0, 0.0, 0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "white_diffuse", name="floor")
    s.add_point_light((0.0, 0.0, 1.0), power=100.0)
    if lit_world:
        s.add_sun((0.0, 0.0, -1.0), strength=5.0)
    s.set_camera((0, 0, 2.0), (0, 0, 0), up=(0, 1, 0), view_angle=2.0)
    s.world_medium = WorldMedium(absorption=sigma_a, scattering=sigma_s)
    return s


def _mean(film):
    return np.asarray(film.combined, np.float64)[..., :3].reshape(-1, 3).mean(axis=0)


def test_a_floor_under_a_lamp_is_lit_and_seen_through_the_world_volume():
    """The floor under the lamp takes I / 1 m^2 x exp(-sigma 1) (its shadow rays lie
    wholly in the world medium) and the camera sees it through exp(-sigma 2): 0.8 / pi x
    100 / 4 pi x exp(-3 sigma) within 0.3 % (the 1-degree half view: cos^3 > 0.9995);
    a bright world and a sun change nothing (infinitely far beyond the medium)."""
    sigma = np.array([0.4, 0.2, 0.05])
    expect = 0.8 / math.pi * 100.0 / (4 * math.pi) * np.exp(-3.0 * sigma)
    settings = RenderSettings(workers=1, spp=4, photon_mapping=False, seed=2)
    np.testing.assert_allclose(_mean(render(_floor_scene(sigma), settings)), expect,
                               rtol=3e-3)
    np.testing.assert_allclose(_mean(render(_floor_scene(sigma, lit_world=True), settings)),
                               expect, rtol=3e-3)


def _scattering_quadrature(z_top, z_end, light=LIGHT, n_xy=16, n_s=3000):
    """The mean over an orthographic film (1 m square, pixel centres of an n_xy grid) of
    the point light's single scattering along vertical rays from z_top down to z_end
    (z_end > z_top: up, to infinity when z_end is inf): int e^{-sigma_t s} sigma_s
    p_iso I e^{-sigma_t r} / r^2 ds, I = P / 4 pi, r the distance to the lamp (the
    shadow ray wholly in the medium), midpoint rule in u = 1 - e^{-s / 2} for the
    infinite ray."""
    sig_t = SIGMA_A + SIGMA_S
    I = POWER / (4 * math.pi)
    xs = (np.arange(n_xy) + 0.5) / n_xy - 0.5
    if math.isinf(z_end):
        u = (np.arange(n_s) + 0.5) / n_s
        s = -2.0 * np.log1p(-u)
        ds = 2.0 / (1.0 - u) / n_s
        sign = 1.0
    else:
        S = abs(z_end - z_top)
        s = (np.arange(n_s) + 0.5) * S / n_s
        ds = np.full(n_s, S / n_s)
        sign = 1.0 if z_end > z_top else -1.0
    X, Y, Sg = np.meshgrid(xs, xs, s, indexing="ij")
    Z = z_top + sign * Sg
    v = np.stack([light[0] - X, light[1] - Y, light[2] - Z], axis=-1)
    r = np.linalg.norm(v, axis=-1)
    out = np.zeros(3)
    for c in range(3):
        f = np.exp(-sig_t[c] * (Sg + r)) * SIGMA_S[c] / (4 * math.pi) * I / r ** 2
        out[c] = (f * ds).sum(axis=-1).mean()
    return out


def _ortho_scene(up: bool):
    """Orthographic camera (1 m) at z 0.5 in a scattering world medium (isotropic), a
    200 W point light at LIGHT (beside the film: the quadrature's grid of rays would
    miss a 1 / distance peak of rays passing by the lamp); looking down at a black floor at z 0 (up=False) or up
    into the empty sky (up=True: the floor below is behind it), a white background of
    strength 3 that must read black."""
    s = PaperScene(8, 8, background=(3.0, 3.0, 3.0))
    s.add_material(Material("black", (0.0, 0.0, 0.0)))
    s.add_plane((0, 0, 0), (0, 0, 1), 30.0, "black", name="floor")
    s.add_point_light(tuple(LIGHT), power=POWER)
    target = (0, 0, 2.0) if up else (0, 0, 0)
    s.set_camera((0, 0, 0.5), target, up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    s.world_medium = WorldMedium(absorption=SIGMA_A, scattering=SIGMA_S)
    return s


@pytest.mark.parametrize("up", [False, True], ids=["to-the-floor", "to-infinity"])
def test_single_scattering_along_camera_rays_matches_quadrature(up):
    """Camera rays in the world medium scatter the point light's light towards the
    camera along their whole length: 0.5 m down to a black floor, or up to infinity
    (escaping: the background behind reads black). 8 x 8 pixels x 256 spp: the mean
    within 0.5 % per channel (measured over seeds 0-9 to infinity: 1.0005 +- 0.0005;
    4096 spp 1.0005; to the floor 0.9998)."""
    film = render(_ortho_scene(up), RenderSettings(workers=1, spp=256,
                                                   photon_mapping=False, seed=4))
    expect = _scattering_quadrature(0.5, math.inf if up else 0.0)
    np.testing.assert_allclose(_mean(film), expect, rtol=0.005)


def test_film_transparent_is_opaque_in_the_world_volume():
    """Cycles writes alpha 1 - average(throughput) where a camera ray escapes: 0 after
    an infinite length of the world medium, so every pixel is opaque (measured with
    Cycles 5.0: alpha 1 looking into a Principled Volume world)."""
    film = render(_ortho_scene(True), RenderSettings(workers=1, spp=4, photon_mapping=False,
                                                     seed=4, film_transparent=True))
    np.testing.assert_allclose(np.asarray(film.alpha), 1.0)


def test_photons_are_dimmed_by_the_world_volume():
    """The point light's photons start in the world medium: their first hits on the
    floor under the lamp carry exp(-sigma r) of a clear world's (the same seed: the
    same paths), r ~ 1 m."""
    from test_volume_scatter import floor_photon_dimming
    ratio, expect = floor_photon_dimming(_floor_scene, np.array([0.4, 0.2, 0.05]))
    np.testing.assert_allclose(ratio, expect, rtol=2e-3)


def test_the_world_light_and_suns_are_off_and_the_report_says_so():
    from engine.render import prepare_context
    ctx = prepare_context(_floor_scene((0.1, 0.1, 0.1), lit_world=True),
                          RenderSettings(workers=1))
    assert [li.kind for li in ctx.lights] == ["POINT"]
    lines = [x for x in ctx.plan.report() if "world volume" in x]
    assert lines and "sun" in lines[0] and "black" in lines[0]


def test_a_world_volume_with_only_the_sky_and_suns_warns_that_the_image_is_black():
    """A World Volume with a lit world and a sun but no lamp or emitter: the image is
    black (as in Cycles); one warning says why and what to do (newuser41: only the
    effect report said so). A lamp, an emissive surface or a glowing world volume: no
    such warning."""
    from engine.worldmedium import warnings_for
    s = _floor_scene((0.1, 0.1, 0.1), lit_world=True)
    assert not [w for w in warnings_for(s) if "image is black" in w]
    s.lights = [li for li in s.lights if li.kind == "SUN"]
    hits = [w for w in warnings_for(s) if "image is black" in w]
    assert len(hits) == 1 and "Volume Scatter" in hits[0]
    glowing = _floor_scene((0.1, 0.1, 0.1), lit_world=True)
    glowing.lights = [li for li in glowing.lights if li.kind == "SUN"]
    glowing.world_medium = WorldMedium(absorption=(0.1, 0.1, 0.1), emission=(0.2, 0.2, 0.2))
    assert not [w for w in warnings_for(glowing) if "image is black" in w]


def test_world_medium_checks_and_scene_file(tmp_path):
    with pytest.raises(SceneError, match="world_medium"):
        s = _floor_scene((-1.0, 0.0, 0.0))
        s.validate()
    with pytest.raises(SceneError, match="anisotropy"):
        WorldMedium(scattering=(1, 1, 1), anisotropy=1.0).validate()
    from engine.scenefile import load_scene
    path = tmp_path / "fog.toml"
    path.write_text("""
[camera]
position = [0, -5, 1]
look_at = [0, 0, 0]
[world_medium]
absorption = [0.1, 0.2, 0.3]
scattering = [0.5, 0.5, 0.5]
anisotropy = 0.4
""")
    scene, _ = load_scene(str(path))
    np.testing.assert_allclose(scene.world_medium.absorption, [0.1, 0.2, 0.3])
    np.testing.assert_allclose(scene.world_medium.scattering, 0.5)
    assert scene.world_medium.anisotropy == pytest.approx(0.4)


def _gathering_floor():
    """A grey floor seen from 1 m above (orthographic) in a scattering world medium, a
    point light above it: the floor's final-gather rays escape upward through the fog
    (its glow on the floor, worldmedium.escaping in integrator._gather_escaping)."""
    s = PaperScene(16, 16)
    s.add_material(Material("grey", (0.5, 0.5, 0.5)))
    s.add_plane((0, 0, 0), (0, 0, 1), 30.0, "grey", name="floor")
    s.add_point_light((0.4, 0.2, 2.0), power=POWER)
    s.set_camera((0, 0, 1.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    s.world_medium = WorldMedium(absorption=SIGMA_A, scattering=SIGMA_S, anisotropy=0.3)
    return s


def test_the_same_image_for_any_worker_count_with_gather_rays_into_the_world_volume():
    settings = dict(spp=8, seed=3, photons=20_000)
    a, b = (render(_gathering_floor(), RenderSettings(workers=w, **settings))
            for w in (1, 2))
    np.testing.assert_array_equal(np.asarray(a.combined), np.asarray(b.combined))
    assert np.asarray(a.indirect).mean() > 0  # the fog's glow gathered by the floor


def _card_scene(sigma):
    """A white floor, a 100 W point light at (1, 0, 1) and an alpha-0.5 card (no medium)
    at z 0.5 across the shadow rays from the floor under the camera to the lamp, not
    across the camera's rays (a perspective camera at z 2 looking straight down, view
    angle 2 degrees); a world medium of extinction sigma (None: none)."""
    s = PaperScene(8, 8)
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "white_diffuse", name="floor")
    s.add_material(Material("card", (0.5, 0.5, 0.5), alpha=0.5))
    s.add_plane((0.5, 0, 0.5), (0, 0, 1), 0.4, "card", name="card")
    s.add_point_light((1.0, 0.0, 1.0), power=100.0)
    s.set_camera((0, 0, 2.0), (0, 0, 0), up=(0, 1, 0), view_angle=2.0)
    if sigma is not None:
        s.world_medium = WorldMedium(absorption=sigma)
    return s


def test_shadow_rays_through_a_transparent_card_keep_the_world_volume():
    """The floor's shadow rays cross the alpha-0.5 card (Cycles' transparent shadows)
    and keep exp(-sigma r) of the world volume over their whole length
    (directlight.direct_light's world_sigma; before, only rays meeting no surface were
    dimmed): the floor with the world volume over without it (the same paths) is
    exp(-sigma (r + 2)), r the distance to the lamp, weighted by the irradiance over
    the view (quadrature), within 0.3 %."""
    sigma = np.array([0.4, 0.2, 0.05])
    settings = RenderSettings(workers=1, spp=4, photon_mapping=False, seed=2)
    fog = _mean(render(_card_scene(sigma), settings))
    clear = _mean(render(_card_scene(None), settings))
    h = 2.0 * math.tan(math.radians(1.0))
    xs = (np.arange(64) + 0.5) / 64 * 2 * h - h
    X, Y = np.meshgrid(xs, xs)
    v = np.stack([1.0 - X, -Y, np.ones_like(X)], axis=-1)
    r = np.linalg.norm(v, axis=-1)
    E = (1.0 / r ** 3).ravel()
    cam = np.sqrt(4.0 + X ** 2 + Y ** 2).ravel()  # the camera segment
    expect = np.array([np.sum(E * np.exp(-sg * (r.ravel() + cam))) / E.sum() for sg in sigma])
    np.testing.assert_allclose(fog / clear, expect, rtol=3e-3)


def _fog_behind_card(card: bool):
    """_ortho_scene's camera looking down 0.5 m of scattering world medium to a black
    floor, the 200 W lamp at (3, 0, 0.25) and (card) an alpha-0.5 card, the plane x 1.5,
    across every shadow ray from the fog the camera sees to the lamp, beside the
    camera's rays."""
    s = PaperScene(8, 8)
    s.add_material(Material("black", (0.0, 0.0, 0.0)))
    s.add_plane((0, 0, 0), (0, 0, 1), 30.0, "black", name="floor")
    if card:
        s.add_material(Material("card", (0.5, 0.5, 0.5), alpha=0.5))
        s.add_plane((1.5, 0, 0.5), (1, 0, 0), 6.0, "card", name="card")
    s.add_point_light((3.0, 0.0, 0.25), power=POWER)
    s.set_camera((0, 0, 0.5), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    s.world_medium = WorldMedium(absorption=SIGMA_A, scattering=SIGMA_S)
    return s


def test_the_fogs_shadow_rays_through_a_transparent_card_keep_the_world_volume():
    """The in-scattering's shadow rays from fog points in the world volume cross the
    alpha-0.5 card (x 0.5) and keep the world medium's exp(-sigma_t length) over their
    whole length (volumescatter.in_scattered's world_sigma): the image is half that
    without the card (the same paths) within 0.1 % (without world_sigma: 0.5 exp(+sigma_t
    r), r ~ 3 m)."""
    settings = RenderSettings(workers=1, spp=16, photon_mapping=False, seed=4)
    with_card = _mean(render(_fog_behind_card(True), settings))
    without = _mean(render(_fog_behind_card(False), settings))
    np.testing.assert_allclose(with_card / without, 0.5, rtol=1e-3)
