"""The sun's caustic photons through a rough single-plane glass pane carry the pane's
transmittance (roughphoton47, docs/accuracy.md "roughphoton47").

A floor under a horizontal rough pane (Glass BSDF, GGX, IOR 1.5) far wider than the view,
a sun 30 degrees off the zenith (a point sun: one direction). Far from the pane's edges
the floor's irradiance is, by translation invariance, the sun's irradiance times the
pane's directional transmittance seen from the floor's (dense) side,

    E = E_sun T,  T = integral f_t(w_floor, w_sun) |cos_floor| |cos_sun| dw_floor

over the floor's hemisphere (which includes the sun's cosine and the refraction's
1 / n^2, docs/units.md "Refraction"), f_t the closure's own eval
(principled.eval_transmission_many) over Walter et al.'s valid pairs alone: the pairs the
photons' sampler makes (Cycles' light sampling evaluates more, docs/accuracy.md
"roughglass47"). The photons that land on the floor under the pane's middle must carry
that flux per m^2.

roughglass47 saw the Caustic pass of tests/blender/test_pane_sun_cycles.py's scene made
rough read +4 to +9 % above E_sun T rho / pi at seed 0; that was the caustic map's
sampling noise at 100,000 photons (the same seed at every roughness: the same emission),
not a bias: these tests pass on main as they do here.
"""
import math
import os
import sys

import numpy as np
import pytest

from engine import RenderSettings
from engine.accel import Accel
from engine.api import PaperScene
from engine.closures import principled as pr
from engine.geometry import prepare
from engine.lights import allocate_photons, prepare_lights
from engine.photons import CAUSTIC, trace_photons
from engine.render import Context
from engine.scene import Camera, Material

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_rough_glass_cycles_eval import _packed, _valid  # noqa: E402

SUN_E, IOR, TILT, ALBEDO = 3.0, 1.5, 30.0, 0.5


def _scene(roughness, angle=0.0):
    s = PaperScene(width=16, height=16)
    s.add_material(Material("floor", (ALBEDO,) * 3))
    s.add_material(Material("glass", (1.0,) * 3, transmission=1.0, ior=IOR,
                            roughness=roughness, node="glass", multiscatter=False))
    s.add_plane((0, 0, 0), (0, 0, 1), 20.0, "floor", name="floor")
    s.add_plane((0, 0, 1.0), (0, 0, 1), 8.0, "glass", name="pane")
    t = math.radians(TILT)
    s.add_sun((math.sin(t), 0.0, -math.cos(t)), strength=SUN_E, angle_degrees=angle,
              name="sun")
    s.camera = Camera(position=(0, 0, 0.8), rotation=np.eye(3), kind="ORTHO",
                      ortho_scale=2.0)
    return s


def _transmittance(roughness, n=400):
    """T of the docstring: midpoint quadrature, equal solid angle cells (n x 2n)."""
    u = (np.arange(n) + 0.5) / n
    th = np.arccos(1.0 - u)
    ph = 2 * math.pi * (np.arange(2 * n) + 0.5) / (2 * n)
    T, P = np.meshgrid(th, ph, indexing="ij")
    wi = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)],
                  -1).reshape(-1, 3)
    dw = 2 * math.pi / (n * 2 * n)
    t = math.radians(TILT)
    wo = np.tile([math.sin(t), 0.0, -math.cos(t)], (len(wi), 1))
    ev = np.empty((len(wi), 4))
    pr.eval_transmission_many(np.repeat(_packed(roughness, IOR, 1.0, False), len(wi), axis=0),
                              np.tile([0.0, 0.0, 1.0], (len(wi), 1)), wi, wo, ev)
    keep = _valid(wi, wo, 1.0 / IOR)
    return float((np.where(keep, ev[:, 0], 0.0) * wi[:, 2]).sum() * dw)


@pytest.mark.parametrize("roughness", [0.3, 1.0])
def test_caustic_photons_under_a_rough_pane_carry_its_transmittance(roughness):
    """The caustic shot's photons on the floor within 2 m of the middle: their power per
    m^2 is E_sun T within 3 % (about 3 sigma: ~13,000 photons of nearly equal power)."""
    T = _transmittance(roughness)
    # (roughglass47's figures for the valid pairs at 30 degrees.)
    assert T == pytest.approx({0.3: 0.3683, 1.0: 0.3233}[roughness], abs=0.002)
    scene = _scene(roughness)
    scene.validate()
    settings = RenderSettings(photons=600_000, seed=5)
    geo, table = prepare(scene)
    accel = Accel(geo.vertices32, geo.faces32, 1)
    lights = prepare_lights(scene, geo, table)
    ctx = Context(scene, settings, geo, table, accel, lights)
    ph = trace_photons(ctx, lights, allocate_photons(lights, 600_000), True, 1)
    z = ph.position[:, 2].astype(np.float64) + geo.offset[2]
    xy = ph.position[:, :2].astype(np.float64) + geo.offset[:2]
    under = (np.abs(z) < 1e-3) & np.all(np.abs(xy) < 2.0, axis=1)
    assert np.all(ph.kind[under] == CAUSTIC)
    got = ph.power[under].astype(np.float64).sum(axis=0) / 16.0
    print(f"roughness {roughness}: {int(under.sum())} photons, E {got[0]:.4f}, "
          f"E_sun T {SUN_E * T:.4f} ({got[0] / (SUN_E * T):.4f})")
    assert got == pytest.approx(np.full(3, SUN_E * T), rel=0.03)


@pytest.mark.parametrize("shot", ["global", "aimed"])
def test_caustic_pass_under_a_rough_pane_is_rho_over_pi_times_its_irradiance(shot, monkeypatch):
    """The film's Caustic pass (the k-NN estimates at the camera's hits) over a 4 x 4 m
    view under the roughness-1 pane: rho / pi E_sun T within 4 %. global: the pane not
    aimed at (effects.AIM_ROUGH_REFRACTORS off, as before roughcaustic48): the pass reads
    the global shot's caustic-kind photons (engine/effects.py, caustics_from_global):
    400,000 photons, ~32,000 of them caustic, ~8,000 in the view; seeds 0-5 read
    0.986-1.011 of it. aimed: the caustic shot aimed at the pane (its default): 400,000
    caustic photons beside 100,000 global ones."""
    from engine import effects
    monkeypatch.setattr(effects, "AIM_ROUGH_REFRACTORS", shot == "aimed")
    scene = _scene(1.0)
    scene.camera.ortho_scale = 4.0
    film = scene.render(RenderSettings(
        spp=2, photons=400_000 if shot == "global" else 100_000,
        caustic_photons=20_000 if shot == "global" else 400_000, seed=0))
    assert (film.stats.get("caustic_photons_emitted", 0) > 0) == (shot == "aimed")
    want = ALBEDO / math.pi * SUN_E * _transmittance(1.0)
    got = float(film.caustic.astype(np.float64).mean())
    print(f"{shot}: Caustic pass {got:.4f}, rho / pi E_sun T {want:.4f} ({got / want:.4f})")
    assert got == pytest.approx(want, rel=0.04)


def test_caustic_photons_reach_a_rough_panes_light():
    """Caustic Photons cleans the floor under a rough pane (roughcaustic48): the caustic
    shot is aimed at the rough refractor (effects.rough_refractors) and the Caustic pass
    reads it, so its photons there grow with the setting (about half of them land on the
    floor) and the pass's mean at seeds 0 and 1 is rho / pi E_sun T within 3 % at
    400,000 (on main: the global shot's ~6,000 caustic-kind photons whatever the
    setting, seeds 0 / 1 at 1.068 / 0.932 of it; bench/roughcaustic48_pane_noise.py)."""
    want = ALBEDO / math.pi * SUN_E * _transmittance(1.0)
    stored = {}
    for n in (50_000, 400_000):
        for seed in (0, 1):
            film = _scene(1.0, 15.0).render(RenderSettings(
                spp=2, photons=100_000, caustic_photons=n, seed=seed))
            stored[n, seed] = int(film.stats["caustic_photons"])
            got = float(film.caustic.astype(np.float64).mean())
            print(f"caustic photons {n}, seed {seed}: {stored[n, seed]} stored, Caustic "
                  f"pass / rho / pi E_sun T {got / want:.4f}")
            assert stored[n, seed] > 0.4 * n
            if n == 400_000:
                assert got == pytest.approx(want, rel=0.03)
    assert "aimed at 'pane'" in next(ln for ln in film.stats["effects"]
                                     if ln.startswith("caustics:"))


def test_a_rough_pane_is_aimed_at_only_where_its_photons_are_read():
    """At Filter Glossy 1 (the split on, final gathering) no photon is read on the matte
    floor: the final gather's blurred chains carry the light through the pane, no caustic
    shot is traced, and the pane is no caster; at 0, or with no caustic photons asked
    for, as said."""
    from engine.render import prepare_context

    def plan(**kw):
        ctx = prepare_context(_scene(1.0, 15.0), RenderSettings(photons=2000, workers=1, **kw))
        ctx.accel.close()
        return ctx.plan
    assert plan().casters == ["pane"]
    for kw in ({"cycles_filter_glossy": 1.0}, {"caustic_photons": 0}):
        p = plan(**kw)
        assert p.casters == [] and p.rough_specular == ["pane"], kw
