"""Cycles' bump shadowing term (engine/normalmap.py, Blender 5.0 kernel/closure/bsdf.h):
analytic values of the term, and that the direct-light kernel, the photons and the
camera-side hits apply it only where a Normal Map / Bump node bent the normal."""
import math

import numpy as np

from engine import RenderSettings
from engine.api import PaperScene
from engine.integrator import Counters, direct_irradiance
from engine.normalmap import NormalMap, bump_shadowing
from engine.render import prepare_context
from engine.scene import Material
from engine.textures import ImageTexture
from engine.bsdf import surface_hit


def _dir(theta_deg, phi_deg=0.0):
    t, p = math.radians(theta_deg), math.radians(phi_deg)
    return np.array([math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)])


def _ggx_g1(alpha2, cos_i):
    """Smith G1 of GGX in Walter et al. 2007's form 2 / (1 + sqrt(1 + a^2 tan^2))."""
    tan2 = 1.0 / cos_i ** 2 - 1.0
    return 2.0 / (1.0 + math.sqrt(1.0 + alpha2 * tan2))


def test_term_is_ggx_shadowing_of_the_normals_divergence():
    m = np.array([[0.0, 0.0, 1.0]])
    n = _dir(35.0)[None]  # bent 35 degrees towards +x
    a2 = 0.125 * math.tan(math.radians(35.0)) ** 2
    for theta in (10.0, 45.0, 70.0, 85.0):
        wi = _dir(theta)[None]
        got = bump_shadowing(m, n, wi)[0]
        assert abs(got - _ggx_g1(a2, math.cos(math.radians(theta)))) < 1e-12
    # docs/textures.md: about 0.9 at a 70 degree light on a 35 degree tilt.
    assert abs(bump_shadowing(m, n, _dir(70.0)[None])[0] - 0.905) < 2e-3
    # Only the normal's divergence and the light's angle to the smooth normal count:
    # the same light turned sideways of the bend gets the same factor.
    assert abs(bump_shadowing(m, n, _dir(70.0, 90.0)[None])[0]
               - bump_shadowing(m, n, _dir(70.0)[None])[0]) < 1e-12
    # No bend, no dimming (bit-equal normals), even at grazing light.
    assert bump_shadowing(m, m, _dir(89.9)[None])[0] == 1.0


def test_light_below_the_smooth_surface_is_refused_for_every_lobe():
    m = np.array([[0.0, 0.0, 1.0]])
    n = _dir(35.0)[None]
    below = _dir(110.0)[None]  # 20 degrees under the smooth horizon, 75 from n: n faces it
    assert float(n[0] @ below[0]) > 0
    assert bump_shadowing(m, n, below, diffuse=True)[0] == 0.0
    assert bump_shadowing(m, n, below, diffuse=False)[0] == 0.0
    above = _dir(60.0)[None]
    assert bump_shadowing(m, n, above, diffuse=False)[0] == 1.0
    assert 0.0 < bump_shadowing(m, n, above, diffuse=True)[0] < 1.0


def _bent_floor(tilt_deg, sun_theta_deg, strength=1.0):
    """A floor whose world-space normal map leans tilt_deg towards +x, lit by a sun
    sun_theta_deg from the zenith on the +x side; camera above."""
    s = PaperScene(width=8, height=8)
    nrm = _dir(tilt_deg)
    tex = ImageTexture(np.array([[0.5 + 0.5 * nrm]], np.float32))
    s.add_material(Material("bent", (0.8, 0.8, 0.8),
                            normal_map=NormalMap(tex, strength, "WORLD")))
    s.add_plane((0, 0, 0), size=4.0, material="bent", name="floor")
    s.add_sun(direction=-_dir(sun_theta_deg), strength=3.0)
    s.set_camera((0, 0, 3), (0, 0, 0), view_angle=30)
    return s, nrm


def _floor_irradiance(scene):
    ctx = prepare_context(scene, RenderSettings(light_samples=1, workers=1))
    n = 64
    o = np.column_stack([np.linspace(-1, 1, n), np.zeros(n), np.full(n, 1.0)])
    d = np.tile([0.0, 0.0, -1.0], (n, 1))
    _, prim, u, v = ctx.accel.intersect(o, d)
    assert (prim >= 0).all()
    hit = surface_hit(ctx.geo, ctx.table, prim, u, v, d)
    return hit, direct_irradiance(ctx, hit, np.random.default_rng(1), Counters())


def test_direct_light_on_a_bent_normal_is_dimmed_by_the_term():
    tilt, theta = 35.0, 70.0
    scene, nrm = _bent_floor(tilt, theta)
    hit, E = _floor_irradiance(scene)
    np.testing.assert_allclose(hit.ns, np.tile(nrm, (len(hit.ns), 1)), atol=1e-6)
    np.testing.assert_allclose(hit.n_smooth, [[0, 0, 1]] * len(hit.ns), atol=1e-12)
    wi = _dir(theta)
    cos_ns = float(nrm @ wi)
    a2 = 0.125 * math.tan(math.radians(tilt)) ** 2
    expect = 3.0 * cos_ns * _ggx_g1(a2, math.cos(math.radians(theta)))
    np.testing.assert_allclose(E, expect, rtol=1e-6)  # the map stores the normal in float32
    # Strength 0 leaves the smooth normal: no term, E = sun x cos.
    hit0, E0 = _floor_irradiance(_bent_floor(tilt, theta, strength=0.0)[0])
    assert hit0.n_smooth is not None
    np.testing.assert_allclose(E0, 3.0 * math.cos(math.radians(theta)), rtol=1e-6)  # the map stores the normal in float32


def test_hits_without_normal_maps_carry_no_smooth_normal():
    s = PaperScene(width=8, height=8)
    s.add_material(Material("plain", (0.8, 0.8, 0.8)))
    s.add_plane((0, 0, 0), size=4.0, material="plain", name="floor")
    s.add_sun(direction=-_dir(70.0), strength=3.0)
    s.set_camera((0, 0, 3), (0, 0, 0), view_angle=30)
    hit, E = _floor_irradiance(s)
    assert hit.n_smooth is None
    np.testing.assert_allclose(E, 3.0 * math.cos(math.radians(70.0)), rtol=1e-6)  # the map stores the normal in float32


def test_both_terms_from_one_evaluation_are_the_two_terms():
    """bump_shadowing_terms (the direct-light kernel's one call per light sample) gives
    bump_shadowing_term(..., False) and (..., True) bit for bit: unbent normals, light on
    the far side of the smooth surface, grazing and ordinary light."""
    from engine.normalmap import bump_shadowing_term, bump_shadowing_terms
    rng = np.random.default_rng(5)
    cases = [(_dir(0.0), _dir(0.0), _dir(30.0)), (_dir(0.0), _dir(35.0), _dir(95.0)),
             (_dir(0.0), _dir(35.0), _dir(89.99999)), (_dir(0.0), _dir(80.0), _dir(60.0))]
    for _ in range(200):
        m, n, i = (v / np.linalg.norm(v) for v in rng.normal(size=(3, 3)))
        cases.append((m, n, i))
    for m, n, i in cases:
        args = (*m, *n, *i)
        assert bump_shadowing_terms(*args) == (bump_shadowing_term(*args, False),
                                               bump_shadowing_term(*args, True))
