"""Camera paths through thin glass (issue 14: the window pane seen from a room).

A camera looking through a smooth, non-absorbing glass slab sees the world behind it with
the slab's transmittance and what lies in front of it with the slab's reflectance, both
summed over the light's internal reflections. With F the unpolarised Fresnel reflectance
of one interface at the incidence angle (the exit's equals the entry's at the refracted
angle):

    T_slab = (1 - F)^2 (1 + F^2 + F^4 + ...) = (1 - F) / (1 + F)
    R_slab = F + (1 - F)^2 F (1 + F^2 + ...) = 2 F / (1 + F)       (T_slab + R_slab = 1)

Each case puts an opaque plane where the reflected rays go: black with a white world
behind the slab (the pixel is T_slab x world), or emitting with a black world (the pixel
is R_slab x emission). The camera's specular chain picks one lobe per interface at random
and ends paths by Russian roulette; both are unbiased, so the image mean over the slab
matches to its noise (a few tenths of a percent at these samples)."""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.integrator import camera_rays
from engine.scene import Material

IOR = 1.5
THICKNESS = 0.02
W, H = 24, 18


def _fresnel(cos_i, eta=IOR):
    """Unpolarised dielectric Fresnel reflectance from outside (eta = n_t / n_i)."""
    s2 = (1.0 - cos_i * cos_i) / (eta * eta)
    ct = np.sqrt(1.0 - s2)
    rs = (cos_i - eta * ct) / (cos_i + eta * ct)
    rp = (eta * cos_i - ct) / (eta * cos_i + ct)
    return 0.5 * (rs * rs + rp * rp)


def _glass():
    return Material("glass", (1.0, 1.0, 1.0), transmission=1.0, roughness=0.0, ior=IOR,
                    node="glass", multiscatter=False)


def _slab_scene(theta_deg, mode, level=1.0, glass=None):
    """A 1 x 1 m slab (2 cm) at the origin, its normal theta_deg from the camera's view
    axis (+y), seen from 5 m with a 6-degree view; the plane 8 m along the mirror
    direction: black with a uniform world of `level` (mode "transmit") or emitting
    `level` with a black world (mode "reflect"); mode "furnace": no plane, the uniform
    world only. glass: the slab's material (default _glass())."""
    th = math.radians(theta_deg)
    n = np.array([-math.sin(th), -math.cos(th), 0.0])  # toward the camera
    s = PaperScene(W, H, background=(0.0,) * 3 if mode == "reflect" else (level,) * 3)
    glass = glass or _glass()
    # The two faces as planes facing out of the slab (one object: a flat passage).
    up = (0.0, 0.0, 1.0)
    c0, c1 = n * (0.5 * THICKNESS), -n * (0.5 * THICKNESS)
    v = []
    for c, nn in ((c0, n), (c1, -n)):
        u = np.cross(up, nn)
        u /= np.linalg.norm(u)
        z = np.array(up)
        v.append([c - 0.5 * u - 0.5 * z, c + 0.5 * u - 0.5 * z, c + 0.5 * u + 0.5 * z,
                  c - 0.5 * u + 0.5 * z])
    verts = np.array(v, np.float64).reshape(-1, 3)
    faces = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]])
    # Each face's winding so its geometric normal points out of the slab.
    for k, nn in ((0, n), (1, -n)):
        a, b, c = verts[faces[2 * k]]
        if np.dot(np.cross(b - a, c - a), nn) < 0:
            faces[2 * k:2 * k + 2] = faces[2 * k:2 * k + 2][:, ::-1]
    s.add_triangles(verts, faces, glass, name="slab")
    d = np.array([0.0, 1.0, 0.0])
    r = d - 2.0 * np.dot(d, n) * n  # the mirror direction
    if mode == "furnace":
        s.set_camera((0.0, -5.0, 0.0), (0.0, 0.0, 0.0), view_angle=6.0)
        return s, n
    if mode == "transmit":
        back = Material("black", (0.0, 0.0, 0.0))
    else:
        back = Material("lamp", (0.0, 0.0, 0.0), emission=(level,) * 3)
    s.add_plane(tuple(8.0 * r), tuple(-r), 30.0, back, name="back")
    s.set_camera((0.0, -5.0, 0.0), (0.0, 0.0, 0.0), view_angle=6.0)
    return s, n


def _expected_and_mask(s, n):
    """Per pixel (H, W): the cosine of incidence of its centre ray, and whether the ray
    meets the slab 0.1 m or more inside its edges (the lateral walk inside 2 cm of glass
    stays far from them)."""
    py, px = np.mgrid[0:H, 0:W]
    px, py = px.ravel().astype(np.int64), py.ravel().astype(np.int64)
    half = np.full(len(px), 0.5)
    o, d, _ = camera_rays(s.camera, np.zeros(3), W, H, px, py, half, half)
    cos_i = np.abs(d @ n)
    t = -(o @ n) / (d @ n)
    p = o + t[:, None] * d
    u = np.cross((0.0, 0.0, 1.0), n)
    u /= np.linalg.norm(u)
    inside = (np.abs(p @ u) < 0.4) & (np.abs(p[:, 2]) < 0.4)
    return cos_i.reshape(H, W), inside.reshape(H, W)


def _render(s, **kw):
    film = s.render(RenderSettings(workers=1, spp=kw.pop("spp", 256), seed=kw.pop("seed", 1),
                                   photon_mapping=False, **kw))
    img = sum(np.asarray(getattr(film, k), np.float64)
              for k in ("direct", "caustic", "indirect", "specular", "emission"))
    return img


@pytest.mark.parametrize("theta_deg", [0.0, 45.0])
def test_pane_transmits_the_world_behind_it(theta_deg):
    """A white world behind the slab, a black plane where the reflections go: the pixel
    is T_slab = (1 - F) / (1 + F) (0.923 at 0 degrees, 0.905 at 45)."""
    s, n = _slab_scene(theta_deg, "transmit")
    cos_i, inside = _expected_and_mask(s, n)
    assert inside.sum() > 100
    F = _fresnel(cos_i)
    expect = (1.0 - F) / (1.0 + F)
    img = _render(s)
    got = img[inside].mean(axis=0)
    # Grey: every channel the same
    np.testing.assert_allclose(got, got[0], rtol=1e-12)
    # Each sample carries 0 or 1 (one lobe per interface): binomial noise over >= 100
    # pixels x 256 samples, ~0.2 %.
    assert got[0] == pytest.approx(expect[inside].mean(), rel=0.01), (theta_deg, got[0])
    # Not the single interface's transmittance 1 - F (both faces take their share; the
    # internal reflections' part, (1 - F)^2 F^2 / (1 - F^2) = 0.15 %, is below the noise).
    assert abs(got[0] - (1.0 - F[inside]).mean()) > 0.02


@pytest.mark.parametrize("theta_deg", [0.0, 45.0])
def test_pane_reflects_what_is_in_front_of_it(theta_deg):
    """A black world, an emitting plane (radiance 10) where the reflections go: the pixel
    is 10 x R_slab = 10 x 2F / (1 + F) (0.77 at 0 degrees, 0.96 at 45): both faces'
    reflections and the internal ones, nearly twice one interface's F."""
    s, n = _slab_scene(theta_deg, "reflect", level=10.0)
    cos_i, inside = _expected_and_mask(s, n)
    F = _fresnel(cos_i)
    expect = 10.0 * 2.0 * F / (1.0 + F)
    img = _render(s)
    got = img[inside, 0].mean()
    # A sample carries 10 with probability ~R_slab (8-10 %): relative noise
    # sqrt((1 - R) / (R N)) ~ 0.6 % over >= 100 pixels x 256 samples.
    assert got == pytest.approx(expect[inside].mean(), rel=0.035), (theta_deg, got)
    assert got > 1.5 * 10.0 * F[inside].mean()  # the back face's reflection is there


# --- The first glass hits split (integrator.SPLIT_GLASS_HITS) ---------
# A camera path's first glass hits continue both the reflection and the refraction, each
# with its Fresnel weight (camerakernels.glass_both), instead of one chosen with it.

def _tinted_glass(base):
    return Material("tinted", base, transmission=1.0, roughness=0.0, ior=IOR,
                    node="principled", multiscatter=False)


def _furnace_slab(theta_deg, base):
    """The 2 cm slab of _slab_scene, of Principled glass with base colour `base`, in a
    uniform white world (radiance 1) with nothing else in it."""
    return _slab_scene(theta_deg, "furnace", glass=_tinted_glass(base))


@pytest.mark.parametrize("theta_deg", [0.0, 45.0, 70.0])
def test_tinted_slab_in_a_uniform_world_is_the_fresnel_sum(theta_deg):
    """Principled glass tints each crossing by sqrt(base) and reflects untinted, so a slab
    in a uniform world L = 1 shows F (the front's reflection) plus the light that crosses
    both faces after k internal reflections, (1 - F)^2 base F^k summed over k:
    pixel = F + (1 - F) base per channel (0.04 + 0.96 base at 0 degrees, 0.18 + 0.82 base
    at 70). Every path ends in the world, so the mean is this sum whatever the lobe
    choices; the split makes the front's F exact per sample."""
    base = np.array([0.25, 0.5, 1.0])
    s, n = _furnace_slab(theta_deg, tuple(base))
    cos_i, inside = _expected_and_mask(s, n)
    assert inside.sum() > 50
    F = _fresnel(cos_i)[inside]
    expect = (F[:, None] + (1.0 - F[:, None]) * base[None, :]).mean(axis=0)
    img = _render(s, spp=64)
    got = img[inside].mean(axis=0)
    # The split's front reflection and first crossing are exact per sample; what is
    # random (the lobe choices at the third hit and beyond) carries ~F^2 of the light.
    np.testing.assert_allclose(got, expect, rtol=2e-3)
    # Not the old single interface (1 - F) base + F, not the untinted 1.
    assert abs(got[0] - 1.0) > 0.5


def test_first_glass_hit_reflection_carries_its_fresnel_weight_in_every_sample():
    """The slab reflecting an emitter of radiance 10 toward the camera (black world): with
    the first hit split, every sample of every pixel carries the front's reflection
    10 F (the back face's and the internal ones add to it), so at 1 sample a pixel no
    pixel is below 10 F; choosing one lobe at random, ~96 % of them would be 0."""
    s, n = _slab_scene(0.0, "reflect", level=10.0)
    cos_i, inside = _expected_and_mask(s, n)
    F = _fresnel(cos_i)
    img = _render(s, spp=1)
    assert img[inside, 0].min() >= 0.999 * 10.0 * F[inside].min()
    # (The mean, 10 x 2F / (1 + F), is test_pane_reflects_what_is_in_front_of_it's.)


@pytest.mark.parametrize("roughness", [0.0, 0.3])
@pytest.mark.parametrize("front", [True, False])
def test_glass_both_is_the_choice_times_its_probability(roughness, front):
    """For one microfacet normal (the same u1, u2) glass_both's reflection and refraction
    are principled._glass_sample's two outcomes (u3 below / above the reflection share
    p_r) with their weights times p_r and 1 - p_r: term by term the same expectation."""
    from engine.camerakernels import glass_both
    from engine.closures import principled as pr
    from engine.geometry import closure_params

    m = Material("g", (0.9, 0.7, 0.5), transmission=1.0, roughness=roughness, ior=IOR,
                 node="principled")
    rng = np.random.default_rng(3)
    checked = 0
    for _ in range(200):
        mu = rng.uniform(0.05, 1.0)
        prm, _ = pr.setup_np(closure_params([m]), np.zeros(1, np.int64), np.full((1, 3), 0.6),
                             np.full(1, mu), np.full(1, front))
        o = (math.sqrt(1.0 - mu * mu), 0.0, mu)
        u1, u2 = rng.random(2)
        both = glass_both(prm, 0, *o, u1, u2)
        refl = pr._glass_sample(prm, 0, *o, u1, u2, 0.0)
        refr = pr._glass_sample(prm, 0, *o, u1, u2, 1.0 - 1e-12)
        r_w, t_w = np.array(both[3:6]), np.array(both[9:12])
        if refl[3:6] != (0.0, 0.0, 0.0) and not refl[6]:
            np.testing.assert_allclose(both[0:3], refl[0:3], rtol=1e-12, atol=1e-15)
            p_r = r_w[0] / refl[3]
            np.testing.assert_allclose(r_w, p_r * np.array(refl[3:6]), rtol=1e-12)
        else:
            p_r = None
            assert not r_w.any() or not refl[3:6] != (0.0, 0.0, 0.0)
        if refr[6] and refr[3:6] != (0.0, 0.0, 0.0):
            np.testing.assert_allclose(both[6:9], refr[0:3], rtol=1e-12, atol=1e-15)
            p_t = t_w[0] / refr[3]
            np.testing.assert_allclose(t_w, p_t * np.array(refr[3:6]), rtol=1e-12)
            if p_r is not None:
                assert p_r + p_t == pytest.approx(1.0, abs=1e-12)
                checked += 1
        else:
            assert not t_w.any()
    # (From inside, below mu ~0.75 every normal reflects totally: no refraction to pair.)
    assert checked > (100 if front else 30)


def test_smooth_dielectric_mirror_lobe_is_not_roulette_at_the_first_hit():
    """A smooth Principled dielectric (black base: its specular layer alone) at 45 degrees
    reflecting an emitter of radiance 10 (black world): the layer's albedo is F (~5 %), so
    Russian roulette would continue 10 F x 10 of the samples at weight 1 / (10 F) and
    leave the rest 0; at the camera's first hit a mirror-only continuation always goes on
    (integrator.MIRROR_NO_ROULETTE), so at 1 sample a pixel every pixel is 10 F."""
    plastic = Material("plastic", (0.0, 0.0, 0.0), roughness=0.0, ior=IOR, specular=1.0,
                       multiscatter=False)
    s, n = _slab_scene(45.0, "reflect", level=10.0, glass=plastic)
    cos_i, inside = _expected_and_mask(s, n)
    F = _fresnel(cos_i)[inside]
    img = _render(s, spp=1)[inside, 0]
    assert img.min() >= 0.995 * 10.0 * F.min()
    assert img.max() <= 1.005 * 10.0 * F.max()


def test_rough_glass_split_keeps_the_mean_of_the_choice():
    """Rough glass (roughness 0.3, Principled, base 0.25 / 0.5 / 1) in a uniform world at
    60 degrees: the split at one microfacet normal (SPLIT_ROUGH_GLASS) and the random
    choice it replaces give the same mean (measured over 3 seeds x 64 spp: within 0.6
    standard errors per channel; here one seed each, 256 spp: ~0.5 % noise)."""
    import engine.integrator as integrator

    m = Material("rough", (0.25, 0.5, 1.0), transmission=1.0, roughness=0.3, ior=IOR,
                 node="principled", multiscatter=False)
    s, n = _slab_scene(60.0, "furnace", glass=m)
    _, inside = _expected_and_mask(s, n)
    got = {}
    saved = integrator.SPLIT_GLASS_HITS
    try:
        for split in (False, True):
            integrator.SPLIT_GLASS_HITS = saved if split else 0
            got[split] = _render(s, spp=256, seed=2)[inside].mean(axis=0)
    finally:
        integrator.SPLIT_GLASS_HITS = saved
    assert integrator.SPLIT_ROUGH_GLASS
    np.testing.assert_allclose(got[True], got[False], rtol=0.02)
    assert got[True][0] > 0.2  # (light reaches the pixels)


@pytest.mark.parametrize("mode", ["transmit", "reflect"])
def test_camera_paths_start_from_buffers_they_never_write(mode, monkeypatch):
    """integrator.BounceBuffers.paths_start hands each chunk the zeros its paths start
    from (travelled, the origin's shading normal and point, the chain's bounces) without
    refilling them: _trace_paths must only read them. Rendered through glass (a flat
    passage, its Fresnel split, the mirror's emission; photon mapping on, small chunks
    on two threads so each thread's buffers serve many chunks), every buffer a chunk
    started from is still all zeros at the end."""
    import engine.integrator as integrator
    seen = []
    start = integrator.BounceBuffers.paths_start

    def recorded(self, n):
        out = start(self, n)
        seen.append(self)
        return out

    monkeypatch.setattr(integrator.BounceBuffers, "paths_start", recorded)
    s, _ = _slab_scene(20.0, mode)
    s.add_plane((0.0, 0.0, -0.6), (0.0, 0.0, 1.0), 20.0, Material("grey", (0.5,) * 3),
                name="floor")
    s.add_point_light((0.0, -1.0, 1.0), 50.0, radius=0.1)
    s.render(RenderSettings(workers=2, spp=16, seed=3, chunk_size=512, photons=5000))
    assert len(seen) > 4
    for b in {id(x): x for x in seen}.values():
        for a in (b.travelled, b.org_ns, b.org_p, b.chain):
            assert not a.any()
