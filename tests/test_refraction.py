"""Refraction convention (docs/units.md, "Refraction: radiance across an interface"):
photons and camera paths both treat radiance as invariant across a refracting surface,
as Cycles does, so a photon's power takes (eta_i / eta_t)^2 when it refracts.

The Cycles numbers are stored in tests/references/refraction.json
(tools/make_refraction_references.py, 1024 spp); this file never renders Cycles.
"""
import json
import os

import numpy as np
import pytest

from engine import RenderSettings
from engine.accel import Accel
from engine.api import PaperScene
from engine.bsdf import fresnel_dielectric
from engine.geometry import prepare
from engine.lights import allocate_photons, prepare_lights
from engine.photons import CAUSTIC, DIRECT, trace_photons
from engine.render import Context
from engine.scene import Material

import refraction_scenes as R

REF = os.path.join(os.path.dirname(os.path.abspath(__file__)), "references", "refraction.json")
SUN_E = 3.0   # W/m^2
PANE = 4.0    # side of the glass pane, m


def _sun_through(ior, slab):
    """A sun straight down onto a floor (8 x 8 m) under a 4 x 4 m pane of glass: a single
    plane (slab=False) or a 5 cm slab."""
    s = PaperScene(width=8, height=8)
    s.add_material(Material("floor", (0.5, 0.5, 0.5)))
    s.add_material(Material("glass", (1, 1, 1), transmission=1.0, ior=ior))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "floor", name="floor")
    if slab:
        s.add_box((0, 0, 1.025), (PANE, PANE, 0.05), "glass", name="pane")
    else:
        s.add_plane((0, 0, 1.0), (0, 0, 1), PANE, "glass", name="pane")
    s.add_sun((0, 0, -1), strength=SUN_E)
    s.set_camera((0, -5, 3), (0, 0, 0))
    return s


def _caustic_power(scene, photons=200_000):
    # 200k photons: the floor's caustic power has a 0.65 % standard error (40k: 1.4 %,
    # measured over 10 seeds, against the tests' 2 % tolerance).
    scene.validate()
    settings = RenderSettings(photons=photons, seed=3)
    geo, table = prepare(scene)
    accel = Accel(geo.vertices32, geo.faces32, 1)
    lights = prepare_lights(scene, geo, table)
    ctx = Context(scene, settings, geo, table, accel, lights)
    ph = trace_photons(ctx, lights, allocate_photons(lights, photons), False, 1)
    # Floor photons that came through the glass without touching the floor before: caustic,
    # or direct under the pane (a thin slab's straight passages keep the direct kind:
    # docs/design.md, Transparent shadows, flat passages).
    xy = ph.position[:, :2].astype(np.float64) + geo.offset[:2]
    under = np.all(np.abs(xy) < 0.5 * PANE, axis=1)
    sel = (((ph.kind == CAUSTIC) | ((ph.kind == DIRECT) & under))
           & (np.abs(ph.position[:, 2] - ph.position[:, 2].min()) < 1e-3))
    return float(ph.power[sel].astype(np.float64).sum(axis=0).mean())


@pytest.mark.parametrize("ior", [1.33, 1.5])
def test_photon_power_into_a_denser_medium_is_scaled_by_eta_squared(ior):
    """Single plane at normal incidence: the floor under it receives the pane's flux
    times (1 - F0) / n^2 (radiance invariance), not (1 - F0) (flux conservation)."""
    f0 = float(fresnel_dielectric(np.array([1.0]), np.array([ior]))[0])
    expected = SUN_E * PANE * PANE * (1 - f0) / ior ** 2
    got = _caustic_power(_sun_through(ior, slab=False))
    assert got == pytest.approx(expected, rel=0.02)


def test_photon_power_through_a_slab_has_no_net_factor():
    """Two interfaces: 1/n^2 in, n^2 out; with the slab's inner reflections the
    transmittance is (1 - F0) / (1 + F0) (incoherent sum of the multiple reflections)."""
    ior = 1.5
    f0 = float(fresnel_dielectric(np.array([1.0]), np.array([ior]))[0])
    expected = SUN_E * PANE * PANE * (1 - f0) / (1 + f0)
    got = _caustic_power(_sun_through(ior, slab=True))
    assert got == pytest.approx(expected, rel=0.02)


def _reference():
    with open(REF) as f:
        return json.load(f)


@pytest.mark.parametrize("name", sorted(R.SCENES))
def test_floor_brightness_matches_cycles(name):
    """Pool floor through a water plane, a room behind a single-plane window and behind a
    slab, the dry pool: floor brightness within 3 % of Cycles (before this convention
    the pool was 1.73x and the window 2.2x Cycles)."""
    ref = _reference()
    assert (ref["width"], ref["height"]) == (R.WIDTH, R.HEIGHT)
    scene = R.SCENES[name]()
    film = scene.render(RenderSettings(spp=16, photons=100_000, seed=1))
    ratio = R.floor_mean(film.combined) / ref["floor_mean"][name]
    assert ratio == pytest.approx(1.0, abs=0.03), f"{name}: {ratio:.3f} x Cycles"
