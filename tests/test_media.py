"""Homogeneous absorbing media inside objects (engine/media.py): light that crosses a
distance s of an object's medium keeps exp(-sigma_a s) per channel (Beer-Lambert), for
shadow rays, camera paths and photons alike. Analytic scenes: a volume-only box (no
surface: no Fresnel) and absorbing glass (two refractions' (1 - F)^2 as well)."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.bsdf import surface_hit
from engine.geometry import MaterialTable
from engine.integrator import Counters, direct_irradiance
from engine.media import NO_SIGMA, absorption_table
from engine.photons import CAUSTIC, DIRECT, trace_photons
from engine.render import prepare_context, render
from engine.scene import Material, SceneError

from test_transparent_shadows import _floor_hits

SIGMA = np.array([0.5, 2.0, 6.0])  # 1/m per channel
IOR = 1.5


def _floor_hits_at(ctx, n, x0, half=0.4):
    """Floor hits (z = 0) of n rays straight down around (x0, 0)."""
    rng = np.random.default_rng(0)
    o = np.column_stack([x0 + rng.uniform(-half, half, n), rng.uniform(-half, half, n),
                         np.full(n, 0.05)]) - ctx.geo.offset
    d = np.tile([0.0, 0.0, -1.0], (n, 1))
    _, prim, u, v = ctx.accel.intersect(o, d)
    keep = prim >= 0
    return surface_hit(ctx.geo, ctx.table, prim[keep], u[keep], v[keep], d[keep])


def _fresnel0(ior):
    return ((ior - 1.0) / (ior + 1.0)) ** 2


def _medium(kind):
    if kind == "volume":
        return Material("medium", volume_only=True, absorption=SIGMA)
    return Material("medium", (1.0, 1.0, 1.0), transmission=1.0, ior=IOR, node="glass",
                    multiscatter=False, absorption=SIGMA)


def _sun_under_box(kind, thickness, height=1.0):
    """A white floor at z = 0 under a straight-down sun of 2 W/m^2 and a 2 x 2 m box of
    the given thickness centred at z = height: a volume-only medium or absorbing glass."""
    s = PaperScene(8, 6)
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
    s.add_box((0, 0, height), (2.0, 2.0, thickness), _medium(kind), name="box")
    s.add_sun((0, 0, -1), 2.0)
    s.set_camera((0, -6, 3), (0, 0, 0))
    return prepare_context(s, RenderSettings(workers=1))


def test_material_checks_and_the_table():
    m = Material("m", (0.5, 0.5, 0.5), volume_only=True, absorption=(1.0, 2.0, 3.0),
                 emission=(1.0, 1.0, 1.0))
    # No surface: a clear transparent pass that emits nothing.
    assert m.alpha == 0.0 and np.all(m.transparent_tint == 1.0)
    assert not m.is_emissive and np.all(m.base_color == 0.0)
    with pytest.raises(SceneError, match="absorption"):
        Material("bad", absorption=(-1.0, 0.0, 0.0))
    table = MaterialTable.build([Material("a"), m])
    np.testing.assert_array_equal(absorption_table(table), [[0, 0, 0], [1, 2, 3]])
    assert absorption_table(MaterialTable.build([Material("a")])) is NO_SIGMA


@pytest.mark.parametrize("thickness", [0.1, 0.4])
def test_shadow_rays_through_a_volume_only_box(thickness):
    """The sun's shadow rays cross the box's two invisible faces and its medium:
    E = 2 exp(-sigma_a d) per channel, exact (no noise: the sun has angle 0)."""
    ctx = _sun_under_box("volume", thickness)
    hit = _floor_hits(ctx, 200, half=0.8)
    E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
    np.testing.assert_allclose(E, np.broadcast_to(2.0 * np.exp(-SIGMA * thickness), E.shape),
                               rtol=1e-6)
    # Beside the box the open sun (no medium on the way).
    beside = _floor_hits_at(ctx, 50, x0=2.5)
    E = direct_irradiance(ctx, beside, np.random.default_rng(1), Counters())
    np.testing.assert_allclose(E, 2.0, rtol=1e-6)


def test_shadow_rays_through_a_thin_absorbing_glass_slab():
    """A thin smooth glass slab is a flat passage (engine/shadowtransmittance.py): its
    shadow rays carry the two refractions (1 - F0)^2 and the medium exp(-sigma_a d)."""
    d = 0.02
    ctx = _sun_under_box("glass", d)
    assert ctx.shadow is not None and ctx.shadow.flat_on
    hit = _floor_hits(ctx, 200, half=0.8)
    E = direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())
    expect = 2.0 * (1.0 - _fresnel0(IOR)) ** 2 * np.exp(-SIGMA * d)
    np.testing.assert_allclose(E, np.broadcast_to(expect, E.shape), rtol=2e-3)


def _floor_photon_power(ctx, n, seed):
    ph = trace_photons(ctx, ctx.lights, [n], caustic_only=False, stream=seed)
    pos = ph.position.astype(np.float64) + ctx.geo.offset
    under = (np.abs(pos[:, 2]) < 1e-3) & np.all(np.abs(pos[:, :2]) < 0.8, axis=1)
    # The sun's light straight through the box (its first diffuse hit: direct kind
    # through a volume-only box, a transparent pass; caustic through the glass); photons
    # that bounced off the floor and back cross other lengths.
    first = (ph.kind == DIRECT) | (ph.kind == CAUSTIC)
    return ph.power[under & first].astype(np.float64).sum(axis=0)


@pytest.mark.parametrize("kind", ["volume", "glass"])
def test_photons_through_an_absorbing_box_keep_exp_minus_sigma_d(kind):
    """The sun's photons under a 0.3 m box against the same box without a medium (the
    same seed: the same paths, so the ratio has no roulette noise but the inner
    reflections' share, R^2 e^{-2 sigma d} < 0.2 %): exp(-sigma_a d) per channel."""
    d = 0.3
    a = _floor_photon_power(_sun_under_box(kind, d), 20_000, 3)
    clear = _sun_under_box(kind, d)
    clear.table.absorption[:] = 0.0  # the same scene with a clear medium
    b = _floor_photon_power(clear, 20_000, 3)
    assert b.min() > 0
    np.testing.assert_allclose(a / b, np.exp(-SIGMA * d), rtol=5e-3)


def _camera_through(kind, thickness, spp):
    """Looking straight down (orthographic, 1 m wide) through a 2 x 2 m box of the given
    thickness centred at z = 1 onto an emissive floor (radiance 1, black world): the
    camera sees Le x exp(-sigma_a d) (x (1 - F0)^2 for glass)."""
    s = PaperScene(8, 8)
    s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0)))
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "glow", name="floor")
    s.add_box((0, 0, 1.0), (2.0, 2.0, thickness), _medium(kind), name="box")
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    film = render(s, RenderSettings(workers=1, spp=spp, photon_mapping=False, seed=2))
    return np.asarray(film.combined, np.float64)[..., :3]


def test_camera_rays_through_a_volume_only_box():
    img = _camera_through("volume", 0.25, 1)
    np.testing.assert_allclose(img, np.broadcast_to(np.exp(-SIGMA * 0.25), img.shape),
                               rtol=1e-6)


def test_camera_rays_through_an_absorbing_glass_box():
    """Two refractions ((1 - F0)^2, each path's lobe chosen by its weight: noise) and the
    medium; the inner reflections' share is < 0.2 %."""
    img = _camera_through("glass", 0.25, 64)
    expect = (1.0 - _fresnel0(IOR)) ** 2 * np.exp(-SIGMA * 0.25)
    np.testing.assert_allclose(img.reshape(-1, 3).mean(axis=0), expect, rtol=0.01)


def test_camera_inside_the_medium():
    """A camera inside a volume-only box (a diver in a liquid): its first segment leaves
    through the box's back face and is attenuated over the way from the camera."""
    s = PaperScene(8, 8)
    s.add_material(Material("glow", (0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0)))
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "glow", name="floor")
    s.add_box((0, 0, 1.0), (3.0, 3.0, 1.0), _medium("volume"), name="box")  # z 0.5..1.5
    s.set_camera((0, 0, 1.2), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    film = render(s, RenderSettings(workers=1, spp=1, photon_mapping=False, seed=2))
    img = np.asarray(film.combined, np.float64)[..., :3]
    np.testing.assert_allclose(img, np.broadcast_to(np.exp(-SIGMA * 0.7), img.shape),
                               rtol=1e-6)


def test_a_surface_inside_the_medium_is_seen_and_lit_through_it():
    """A floor running through a volume-only box (z -0.2 .. 0.3: a submerged surface)
    under a straight-down sun: the camera path enters the box through its top face and
    meets the floor inside, the medium carried from the crossing (engine/media.py); the
    sun's shadow rays leave through the top (a back face), its photons enter through
    it. Both ways 0.3 m: the floor reads 0.8 / pi x 2 x exp(-2 sigma_a 0.3)."""
    s = PaperScene(8, 8)
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "white_diffuse", name="floor")
    s.add_box((0, 0, 0.05), (2.0, 2.0, 0.5), _medium("volume"), name="box")
    s.add_sun((0, 0, -1), 2.0)
    s.set_camera((0, 0, 3.0), (0, 0, 0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
    film = render(s, RenderSettings(workers=1, spp=1, photon_mapping=False, seed=2))
    img = np.asarray(film.combined, np.float64)[..., :3]
    expect = 0.8 / math.pi * 2.0 * np.exp(-2 * SIGMA * 0.3)
    np.testing.assert_allclose(img, np.broadcast_to(expect, img.shape), rtol=1e-5)
    ctx = prepare_context(s, RenderSettings(workers=1))
    ph = trace_photons(ctx, ctx.lights, [20_000], caustic_only=False, stream=3)
    pos = ph.position.astype(np.float64) + ctx.geo.offset
    under = (np.abs(pos[:, 2]) < 1e-3) & np.all(np.abs(pos[:, :2]) < 0.8, axis=1)
    first = under & (ph.kind == DIRECT)
    # Every photon that reached the floor there first crossed the same 0.3 m of medium.
    power = ph.power[first].astype(np.float64)
    beside = (np.abs(pos[:, 2]) < 1e-3) & (np.abs(pos[:, 0]) > 1.2) & (ph.kind == DIRECT)
    ratio = power.mean(axis=0) / ph.power[beside].astype(np.float64).mean(axis=0)
    np.testing.assert_allclose(ratio, np.exp(-SIGMA * 0.3), rtol=1e-5)


def test_the_effect_report_names_the_media():
    ctx = _sun_under_box("volume", 0.2)
    lines = [e for e in ctx.plan.decisions if e.effect == "volume absorption"]
    assert len(lines) == 1 and lines[0].enabled and "'medium'" in lines[0].reason
    assert "0.5, 2, 6 /m" in lines[0].reason  # sigma_a per channel


def test_final_gather_through_a_medium_matches_the_photon_estimate():
    """A ceiling lit only by a floor that runs through a volume-only slab (z -0.1 .. 0.3)
    under a spot pointing down: its gather rays enter the slab through its top and meet
    the floor inside (the medium carried, engine/media.py). Final gathering and the
    photons' own estimate at the ceiling (photons attenuated both ways) agree per
    channel; a gather ray not attenuated inside would read exp(0.3 sigma_a) = 1.35 /
    1.82 / 2.46 brighter."""
    def ceiling(final_gather):
        s = PaperScene(8, 8)
        s.add_plane((0, 0, 0), (0, 0, 1), 6.0, "white_diffuse", name="floor")
        s.add_plane((0, 0, 2.0), (0, 0, -1), 6.0, "white_diffuse", name="ceiling")
        s.add_material(Material("medium", volume_only=True, absorption=(1.0, 2.0, 3.0)))
        s.add_box((0, 0, 0.1), (6.0, 6.0, 0.4), "medium", name="slab")
        s.add_spot_light((0, 0, 1.5), (0, 0, 0), power=500.0, spot_size_degrees=60.0,
                         blend=0.0)
        s.set_camera((0, 0, 1.0), (0, 0, 2.0), up=(0, 1, 0), kind="ORTHO", ortho_scale=1.0)
        # (The cosine gather: the mechanism under test is the medium carried by gather
        # rays; "auto" guides this spot-lit ceiling, whose guided gathers differ from the
        # cosine ones by their noise, 1.0115 +- 0.012 over 10 seeds, not by a bias.)
        film = render(s, RenderSettings(workers=1, spp=8, photons=200_000, caustic_photons=0,
                                        seed=1, final_gather=final_gather, gather_rays=8,
                                        gather_guiding=False))
        return np.asarray(film.combined, np.float64)[..., :3].mean(axis=(0, 1))
    gathered, photons = ceiling(True), ceiling(False)
    np.testing.assert_allclose(gathered, photons, rtol=0.02)
