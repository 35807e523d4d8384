"""Sunlight through a single-plane glass pane by next-event estimation (engine/panelight.py,
issue 14: "light through thin glass as smooth as direct light").

A floor under a horizontal single-plane pane under a sun with an angle: the floor's
irradiance is E_sun cos(theta_i) T(theta_i) / n^2 (the refraction convention shared with
the photons, docs/units.md "Refraction"; T the smooth interface's transmittance), evenly.
Before, shadow rays stopped at the pane (Direct pass 0) and the light came from the
caustic map (blotchy). The photons the pane's shadow rays now carry are direct-kind, so
the image keeps its brightness (the photons' own estimate, ENABLED off, on average).
"""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine import panelight
from engine.accel import Accel
from engine.api import PaperScene
from engine.bsdf import fresnel_dielectric
from engine.geometry import prepare
from engine.lights import allocate_photons, prepare_lights
from engine.photons import CAUSTIC, DIRECT, trace_photons
from engine.render import Context
from engine.scene import Camera, Material

SUN_E = 3.0
ALBEDO = 0.5
IOR = 1.5
TILT = 30.0      # the sun's direction from the zenith, degrees
ANGLE = 3.0      # its angular diameter, degrees


def _floor_under_pane(view=1.5, pane=6.0, tilt=TILT, angle=ANGLE, pane_normal=(0, 0, 1)):
    """A 10 x 10 m floor (albedo 0.5) under a `pane` m single-plane glass pane at z = 1
    (normal up), a sun from `tilt` degrees off the zenith; an orthographic camera inside
    (z = 0.8) looking straight down at the middle `view` m."""
    s = PaperScene(width=32, height=32)
    s.add_material(Material("floor", (ALBEDO,) * 3))
    s.add_material(Material("glass", (1.0, 1.0, 1.0), transmission=1.0, ior=IOR,
                            roughness=0.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 10.0, "floor", name="floor")
    s.add_plane((0, 0, 1.0), pane_normal, pane, "glass", name="pane")
    t = math.radians(tilt)
    s.add_sun((math.sin(t), 0.0, -math.cos(t)), strength=SUN_E, angle_degrees=angle,
              name="sun")
    s.camera = Camera(position=(0, 0, 0.8), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=view)
    return s


def _expected_radiance(tilt=TILT):
    c = math.cos(math.radians(tilt))
    F = float(fresnel_dielectric(np.array([c]), np.array([IOR]))[0])
    return ALBEDO / math.pi * SUN_E * c * (1.0 - F) / IOR ** 2


def test_pane_classification():
    """The single plane is a pane; a slab and a cube are not."""
    s = _floor_under_pane()
    s.add_box((3.0, 3.0, 0.5), (0.5, 0.5, 0.5), "glass", name="cube")
    geo, table = prepare(s)
    lights = prepare_lights(s, geo, table)
    panes = panelight.find_panes(geo, table, lights)
    assert panes is not None and [p.name for p in panes.panes] == ["pane"]
    rows = np.nonzero(panes.pane_tri >= 0)[0]
    assert set(np.asarray(geo.object_names)[geo.object_id[rows]]) == {"pane"}


def test_floor_under_pane_is_lit_by_shadow_rays_evenly():
    """Direct pass = rho / pi E_sun cos T / n^2 within 2 %, pixel to pixel within 1 %
    (the caustic pass was the whole light: blotches of +-10 % and more), no caustic."""
    film = _floor_under_pane().render(RenderSettings(spp=4, photons=50_000,
                                                     caustic_photons=50_000, seed=2))
    want = _expected_radiance()
    direct = film.direct.astype(np.float64).mean(axis=2)
    assert direct.mean() == pytest.approx(want, rel=0.02), (direct.mean(), want)
    assert direct.std() / direct.mean() < 0.01
    assert film.caustic.astype(np.float64).mean() < 0.01 * want


def _floor_photons(scene, photons=200_000):
    scene.validate()
    settings = RenderSettings(photons=photons, seed=3)
    geo, table = prepare(scene)
    accel = Accel(geo.vertices32, geo.faces32, 1)
    lights = prepare_lights(scene, geo, table)
    ctx = Context(scene, settings, geo, table, accel, lights)
    ph = trace_photons(ctx, lights, allocate_photons(lights, photons), False, 1)
    floor = np.abs(ph.position[:, 2] - ph.position[:, 2].min()) < 1e-3
    xy = ph.position[:, :2].astype(np.float64) + geo.offset[:2]
    return ph, floor & np.all(np.abs(xy) < 2.0, axis=1)  # under the 4 x 4 m pane


def test_photons_through_a_pane_are_direct_and_keep_their_power():
    """The sun's photons refracted through the pane reach the floor as direct photons
    (the shadow rays' light), with the same power as the caustic photons before."""
    got = {}
    for on in (True, False):
        old = panelight.ENABLED
        panelight.ENABLED = on
        try:
            ph, floor = _floor_photons(_floor_under_pane(pane=4.0, angle=0.0, tilt=0.0))
        finally:
            panelight.ENABLED = old
        got[on] = ph, floor
    ph, floor = got[True]
    ph0, floor0 = got[False]
    assert not np.any(floor & (ph.kind == CAUSTIC))
    assert np.any(floor0 & (ph0.kind == CAUSTIC))
    on_power = float(ph.power[floor & (ph.kind == DIRECT)].astype(np.float64).sum())
    off_power = float(ph0.power[floor0 & (ph0.kind == CAUSTIC)].astype(np.float64).sum())
    F0 = float(fresnel_dielectric(np.array([1.0]), np.array([IOR]))[0])
    want = 3 * SUN_E * 16.0 * (1 - F0) / IOR ** 2  # RGB summed, 4 x 4 m pane
    assert on_power == pytest.approx(want, rel=0.02)
    assert off_power == pytest.approx(want, rel=0.02)


def test_image_keeps_its_brightness_near_the_pane_edge():
    """A view across the pane's lit footprint edge: next-event estimation and the caustic
    photons it replaces agree on the image mean (no light counted twice or lost at the
    edge), and the direct pass is brightness the caustic pass no longer holds."""
    means = {}
    for on in (True, False):
        old = panelight.ENABLED
        panelight.ENABLED = on
        try:
            # The lit footprint is the pane shifted by tan(theta_t) m: its edge at
            # x = -1 + 0.354 in view.
            film = _floor_under_pane(view=3.0, pane=2.0).render(
                RenderSettings(spp=8, photons=100_000, caustic_photons=400_000, seed=4))
        finally:
            panelight.ENABLED = old
        means[on] = (film.combined.astype(np.float64).mean(), film.direct.mean(),
                     film.caustic.mean())
    on, off = means[True], means[False]
    assert on[1] > 1.2 * off[1]  # the light under the pane: direct now
    assert on[2] < 0.02 * on[0]
    print("on (combined, direct, caustic):", on, "off:", off)
    assert on[0] == pytest.approx(off[0], rel=0.03), (on, off)


@pytest.mark.parametrize("case", ["rough", "bent", "area light"])
def test_scenes_without_a_sun_pane_render_the_same_bits(case):
    """Rough glass (not smooth), a bent sheet (two planes) or a pane under an area light
    instead of a sun: no pane, the film is bit for bit the one with panes switched off."""
    films = []
    for on in (True, False):
        old = panelight.ENABLED
        panelight.ENABLED = on
        try:
            s = PaperScene(width=16, height=16)
            s.add_material(Material("floor", (ALBEDO,) * 3))
            s.add_material(Material("glass", (1.0, 1.0, 1.0), transmission=1.0, ior=IOR,
                                    roughness=0.3 if case == "rough" else 0.0))
            s.add_plane((0, 0, 0), (0, 0, 1), 10.0, "floor", name="floor")
            if case == "bent":
                # One object of two faces folded 17 degrees along y = 0 (a roof ridge).
                v = np.array([[-2, -2, 1.0], [0, -2, 1.3], [0, 2, 1.3], [-2, 2, 1.0],
                              [2, -2, 1.0], [2, 2, 1.0]])
                s.add_triangles(v, np.array([[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]]),
                                "glass", name="pane")
            else:
                s.add_plane((0, 0, 1.0), (0, 0, 1), 4.0, "glass", name="pane")
            if case == "area light":
                s.add_rect_area_light((0.5, 0, 3.0), (1.0, 1.0), power=300.0,
                                      direction=(0, 0, -1), name="lamp")
            else:
                s.add_sun((0.3, 0.0, -1.0), strength=SUN_E, angle_degrees=ANGLE)
            s.camera = Camera(position=(0, 0, 0.8), rotation=np.eye(3), kind="ORTHO",
                              ortho_scale=2.0)
            films.append(s.render(RenderSettings(spp=2, photons=20_000,
                                                 caustic_photons=20_000, seed=1)).combined)
        finally:
            panelight.ENABLED = old
    assert films[0].mean() > 0
    assert np.array_equal(films[0], films[1])


def test_aimed_sun_photons_through_a_pane_are_direct():
    """Visual importance wraps the sun in a RegionEmitter (photons aimed at the camera's
    region): those photons through the pane are direct too. (They stayed caustic at
    first: the window room of bench/bench_window_pane.py read its sun patch twice,
    table 1.85x Cycles.)"""
    from engine.visualimportance import Region, RegionEmitter
    scene = _floor_under_pane(pane=4.0, angle=0.0, tilt=0.0)
    scene.validate()
    geo, table = prepare(scene)
    accel = Accel(geo.vertices32, geo.faces32, 1)
    lights = prepare_lights(scene, geo, table)
    ctx = Context(scene, RenderSettings(photons=50_000, seed=3), geo, table, accel, lights)
    region = Region(np.array([[0.0, 0.0, 0.0]]) - geo.offset, np.array([1.0]), 0.9, 100)
    ph = trace_photons(ctx, [RegionEmitter(lights[0], region, 0.5)], [50_000], False, 1)
    floor = np.abs(ph.position[:, 2] - ph.position[:, 2].min()) < 1e-3
    xy = ph.position[:, :2].astype(np.float64) + geo.offset[:2]
    under = floor & np.all(np.abs(xy) < 2.0, axis=1)
    assert np.count_nonzero(under & (ph.kind == DIRECT)) > 1000
    assert not np.any(under & (ph.kind == CAUSTIC))


def _effect_line(film, start):
    return next(line for line in film.stats["effects"] if line.startswith(start))


def test_effect_report_says_the_sun_comes_through_the_pane():
    film = _floor_under_pane().render(RenderSettings(spp=1, photons=2_000,
                                                     caustic_photons=2_000, seed=1))
    line = _effect_line(film, "sun through glass 'sun'")
    assert ": on - reaches through single-plane glass 'pane' by shadow rays" in line
    # The bend and the dimming, and what makes a window (a single plane is a block's
    # surface): 30 degrees -> asin(sin 30 / 1.5) = 19.5, T (1 / 1.5)^2.
    bent = math.degrees(math.asin(math.sin(math.radians(TILT)) / IOR))
    c = math.cos(math.radians(TILT))
    F = float(fresnel_dielectric(np.array([c]), np.array([IOR]))[0])
    assert (f"'pane': from {TILT:.0f} to {bent:.0f} degrees off its normal, "
            f"{(1.0 - F) / IOR ** 2:.2f} of the sun's radiance") in line
    assert "Solidify" in line


def test_effect_report_names_a_pane_that_totally_reflects_the_sun():
    """A pane whose glass side faces a sun beyond the critical angle (a window plane
    turned into a wall with its normal into the room, pane31's bench): physically no
    sunlight gets through, in Cycles too; the report says why and how to flip it."""
    s = _floor_under_pane(tilt=60.0, pane_normal=(0, 0, -1))  # the glass side up
    film = s.render(RenderSettings(spp=1, photons=2_000, caustic_photons=2_000, seed=1))
    line = _effect_line(film, "sun through glass 'sun'")
    crit = math.degrees(math.asin(1.0 / IOR))
    assert ": off - single-plane glass 'pane' faces away from the sun" in line
    assert f"at 60 degrees, beyond the critical angle {crit:.1f} degrees (IOR 1.5)" in line
    assert "Normals > Flip" in line
    # Physically right: nothing comes through (the Direct pass is dark).
    assert float(film.direct.mean()) == 0.0


def test_local_illumination_traces_no_pane_shadow_rays():
    """Method 'local' has no shadow rays and no refraction (effects.METHOD_TEXT): the floor
    under the pane reads the sun's unoccluded rho / pi E cos, with panes as without, and
    no shadow ray is traced (the pane's refracted light is not added on top: it read
    rho / pi E cos + rho / pi E cos T / n^2, 0.589 for 0.413)."""
    s = _floor_under_pane()
    film = s.render(RenderSettings(method="local", spp=2, seed=2))
    want = ALBEDO / math.pi * SUN_E * math.cos(math.radians(TILT))
    assert float(film.direct.mean()) == pytest.approx(want, rel=1e-3)
    assert film.stats["shadow_rays"] == 0


def test_a_lamp_beside_the_sun_keeps_its_aimed_caustic_photons():
    """A sun and a dim area lamp over a pane: the pane stays a caustic caster for the
    lamp, and the caustic shot's photons go to the lamp (the sun's through the pane are
    direct, which the caustic shot does not keep: 68 of 100,000 were stored before)."""
    s = _floor_under_pane()
    s.add_rect_area_light((3.0, 3.0, 3.0), (0.2, 0.2), power=1.0, direction=(0, 0, -1),
                          name="lamp")
    film = s.render(RenderSettings(spp=1, photons=20_000, caustic_photons=100_000, seed=2))
    assert film.stats["caustic_photons"] > 20_000
    want = _expected_radiance()
    assert float(film.direct.astype(np.float64).mean()) == pytest.approx(want, rel=0.02)


@pytest.mark.parametrize("receivers", [["floor"], ["floor", "pane"], ["pane"]])
def test_light_linking_through_a_pane_follows_the_pane(receivers):
    """Light Linking (docs/compatibility.md fogfloor39): Cycles counts a sun met through
    the glass only if it lights the object the path last bounced from, the pane
    (light_link_receiver_forward), so the pane's link decides, not the floor's: the sun
    linked to the floor alone gives no direct light under the pane (its photons end at
    the pane too; before, the Direct pass read the full light; what remains is the
    indirect light of the floor lit beyond the pane, reflected by the pane: 0.0415 of
    the unlinked 0.0745), linked to the pane (with or without the floor) the floor's
    direct light as without links."""
    s = _floor_under_pane()
    s.lights[0].receivers = receivers
    film = s.render(RenderSettings(spp=4, photons=50_000, caustic_photons=50_000, seed=2))
    direct = film.direct.astype(np.float64).mean()
    if "pane" in receivers:
        assert direct == pytest.approx(_expected_radiance(), rel=0.02)
    else:
        assert direct == 0.0
        assert film.caustic.astype(np.float64).mean() == 0.0
        assert film.combined.astype(np.float64).mean() < 0.3 * _expected_radiance()
