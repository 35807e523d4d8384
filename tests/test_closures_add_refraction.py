"""Add Shader's closure weight and the Refraction BSDF's lobe (issue 14), in the engine.

- Material.closure_weight (Cycles' closure weight; 2 for an Add Shader of two surfaces)
  scales every BSDF lobe: a sun-lit plane of the even mix of Diffuse and Glossy at weight 2
  renders as the sum of the two renders (direct light from a delta sun: one BSDF
  evaluation per pixel, no noise), and weight 2 on a diffuse material is its base colour
  doubled, in the camera pass and in the photon pass (the diffuse-only fast paths honour
  it).
- node="refraction" transmits only, colour x refraction without Fresnel (Cycles'
  Refraction BSDF): a smooth slab seen in front of an emissive backdrop shows colour^2 x
  its radiance (camera pass), where a Glass slab loses its Fresnel reflections (~7 % at
  IOR 1.45); the floor under a slab lit by a sun through it takes colour^2 in every
  channel and more light than under Glass (photon pass, the caustic map).
"""
import numpy as np

from engine.api import PaperScene
from engine.closures import principled as pr
from engine.geometry import closure_params
from engine.scene import Material
from engine.settings import RenderSettings


def _plane(material, size=16, spp=4, photons=False, seed=3):
    """Mean-free check scene: the plane under a delta sun; with photons, a white wall
    behind it (in its shadow side) lit only by light the plane reflects."""
    s = PaperScene(width=size, height=size)
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, material, name="plane")
    if photons:
        s.add_plane((3, 0, 1), (-1, 0, 0), 6.0, Material("white", (0.8, 0.8, 0.8)),
                    name="wall")
    s.add_sun(direction=(-0.5, 0.0, -0.8), strength=3.0)
    s.set_camera((-4.0, 0.0, 4.0), (0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), view_angle=40.0)
    film = s.render(RenderSettings(spp=spp, photon_mapping=photons, seed=seed, workers=1,
                                   **({"photons": 20_000} if photons else {})))
    return film.combined.reshape(-1, 3)


def test_closure_weight_is_the_sum_of_diffuse_and_glossy():
    diffuse = Material("d", (0.6, 0.3, 0.1), specular=0.0)
    glossy = Material("g", (0.3, 0.5, 0.8), metallic=1.0, roughness=0.3, node="glossy")
    # The even mix of the two (addon/materials.py _blend) at closure weight 2.
    added = Material("a", (0.6, 0.3, 0.1), metallic=0.5, roughness=0.3, node="glossy",
                     glossy_color=(0.3, 0.5, 0.8), closure_weight=2.0)
    want = _plane(diffuse) + _plane(glossy)
    got = _plane(added)
    assert want.mean() > 0.05
    np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-9)  # float32 films


def test_closure_weight_on_diffuse_is_the_colour_doubled_in_both_passes():
    one = Material("d", (0.8, 0.4, 0.2), specular=0.0)
    row = closure_params([one, Material("w", (0.4, 0.2, 0.1), specular=0.0,
                                        closure_weight=2.0)])
    assert row[0, pr.M_ADD] == 0.0 and row[1, pr.M_ADD] == 1.0
    for photons in (False, True):
        a = _plane(one, photons=photons)
        b = _plane(Material("w", (0.4, 0.2, 0.1), specular=0.0, closure_weight=2.0),
                   photons=photons)
        assert a.mean() > 0.05
        np.testing.assert_allclose(b, a, rtol=1e-6, atol=1e-9)  # float32 films


def test_closure_setup_scales_every_bsdf_lobe_not_the_pass_lobe():
    m = Material("p", (0.5, 0.4, 0.3), metallic=0.3, roughness=0.4, transmission=0.2,
                 specular=1.0, coat_weight=0.5, sheen_weight=0.4, alpha=0.7, translucent=0.2)
    q1 = closure_params([m])
    m.closure_weight = 2.0
    q2 = closure_params([m])
    args = (np.zeros(1, np.int64), np.full((1, 3), 0.5), np.full(1, 0.7), np.ones(1, bool))
    p1, w1 = pr.setup_np(q1, *args)
    p2, w2 = pr.setup_np(q2, *args)
    lobes = [lb for lb in range(pr.N_LOBES) if lb != pr.L_PASS]
    assert np.all(w1[0, lobes] > 0)
    np.testing.assert_allclose(w2[0, lobes], 2.0 * w1[0, lobes], rtol=1e-12)
    np.testing.assert_array_equal(w2[0, pr.L_PASS], w1[0, pr.L_PASS])


def _slab_scene(node, color, backdrop):
    """A 0.3 m smooth slab (IOR 1.45) between a camera straight above and an emissive
    floor (backdrop) or a sun-lit white floor."""
    s = PaperScene(width=8, height=8)
    slab = Material("slab", color, transmission=1.0, roughness=0.0, ior=1.45, node=node,
                    multiscatter=False)
    if backdrop:
        s.add_plane((0, 0, 0), (0, 0, 1), 20.0,
                    Material("emit", (0, 0, 0), emission=(1.0, 1.0, 1.0)), name="floor")
        s.add_box((0, 0, 1.0), (6.0, 6.0, 0.3), slab, name="slab")
        s.set_camera((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), view_angle=10.0)
    else:
        s.add_plane((0, 0, 0), (0, 0, 1), 40.0, Material("white", (0.8, 0.8, 0.8)),
                    name="floor")
        s.add_box((0, 0, 2.0), (8.0, 8.0, 0.3), slab, name="slab")
        s.add_sun(direction=(0.0, 0.0, -1.0), strength=3.0)
    return s


def test_refraction_transmits_colour_squared_in_the_camera_pass():
    for color in ((1.0, 1.0, 1.0), (0.9, 0.6, 0.3)):
        s = _slab_scene("refraction", color, backdrop=True)
        img = s.render(RenderSettings(spp=2, photon_mapping=False, seed=1, workers=1))
        rgb = img.combined.reshape(-1, 3).mean(axis=0)
        np.testing.assert_allclose(rgb, np.square(color), rtol=1e-6)
    glass = _slab_scene("glass", (1.0, 1.0, 1.0), backdrop=True).render(
        RenderSettings(spp=2, photon_mapping=False, seed=1, workers=1))
    assert glass.combined.mean() < 0.95  # Glass loses its Fresnel reflections


def test_refraction_photons_take_colour_per_crossing_and_no_fresnel():
    """The photon pass: the floor under a smooth slab lit by a sun through it (the caustic
    map: the slab blocks shadow rays), seen from 1.5 m with a wide view (~2.2 m of floor,
    many photon search discs: one k = 64 caustic estimate scatters by ~17 %, so a narrow
    view reads a single draw), against the floor in the open sun (direct light, exact).
    Refraction: colour x refraction at each crossing, so the ratio divided by colour^2 is
    1 in every channel (measured 0.997-1.014 over seeds 1, 2, 5); and no Fresnel, so the
    caustic pass under it is brighter than under a Glass slab by 1 / T_slab = 1.070 (T = (1 -
    R) / (1 + R), R = 0.034 at IOR 1.45; measured 1.068-1.072). The caustic passes are
    compared, not the combined images: under Glass the floor also gets ~4 % of light
    reflected between floor and slab."""
    color = np.array([0.9, 0.6, 0.3])
    means, caustic = {}, {}
    for node in ("refraction", "glass"):
        for x in (0.0, 8.0):  # under the slab's middle; in the open sun
            s = _slab_scene(node, tuple(color), backdrop=False)
            s.set_camera((x - 0.05, 0.0, 1.5), (x, 0.0, 0.0), up=(0.0, 0.0, 1.0),
                         view_angle=72.0)
            film = s.render(RenderSettings(spp=2, photons=200_000, caustic_photons=400_000,
                                           seed=5, workers=1))
            means[node, x] = film.combined.reshape(-1, 3).mean(axis=0).astype(np.float64)
            caustic[node, x] = film.caustic.reshape(-1, 3).mean(axis=0).astype(np.float64)
    assert means["refraction", 8.0].min() > 0.5
    per_crossing = means["refraction", 0.0] / means["refraction", 8.0] / color ** 2
    np.testing.assert_allclose(per_crossing, 1.0, rtol=0.04)
    t_slab = (1 - 0.034) / (1 + 0.034)
    no_fresnel = caustic["refraction", 0.0] / caustic["glass", 0.0]
    np.testing.assert_allclose(no_fresnel, 1.0 / t_slab, rtol=0.02)
