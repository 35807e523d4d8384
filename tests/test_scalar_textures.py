"""Texture-driven scalar inputs (Roughness, Metallic, ... maps): evaluated per hit and fed
to the closure set-up, camera and photon pass alike (docs/textures.md)."""
import numpy as np
import pytest

from engine import RenderSettings
from engine import shadernodes as sn
from engine.accel import Accel
from engine.bsdf import closures, surface_hit
from engine.closures import principled as pr
from engine.geometry import prepare
from engine.lights import allocate_photons, prepare_lights
from engine.photons import trace_photons
from engine.render import Context
from engine.scene import Camera, Light, Material, Mesh, Scene, SceneError


def _split(lo, hi):
    """Factor node: lo where u < 0.5, hi elsewhere (a Checker of scale 1 on UV would do
    the same in one row; this keeps the test's geometry obvious)."""
    u = sn.SeparateChannel(sn.UVCoord(), 0)
    step = sn.Math("GREATER_THAN", u, 0.5)
    return sn.Math("ADD", sn.Math("MULTIPLY", step, hi - lo), lo)


def _quad_scene(**material):
    s = Scene()
    s.add_material(Material("m", (0.8, 0.8, 0.8), specular=1.0, **material))
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float)
    s.add_mesh(Mesh("quad", v, np.array([[0, 1, 2], [0, 2, 3]]), uvs=(v[:, :2] + 1) / 2,
                    materials=["m"]))
    return s


def _hits(geo, table, xs):
    """Hits straight down at points (x, -0.9) of the quad's triangle 0 (x >= y)."""
    xs = np.asarray(xs, float)
    # Triangle 0: corners (-1,-1), (1,-1), (1,1); p = c0 + u e1 + v e2.
    v = np.full(len(xs), 0.05)
    u = (xs + 1) / 2 - v
    prim = np.zeros(len(xs), np.int64)
    return surface_hit(geo, table, prim, u, v, np.tile([0.0, 0.0, -1.0], (len(xs), 1)))


def test_roughness_map_reaches_the_closures_per_hit():
    s = _quad_scene(roughness=0.5, scalar_textures={"roughness": _split(0.1, 0.8)})
    geo, table = prepare(s)
    hit = _hits(geo, table, [-0.5, 0.5])
    np.testing.assert_allclose(hit.params[:, pr.M_ROUGH], [0.1, 0.8], atol=1e-12)
    prm, _ = closures(table, hit)
    # The dielectric specular lobe's GGX alpha is roughness squared, per hit.
    np.testing.assert_allclose(prm[:, pr.P_SPEC_ALPHA], [0.01, 0.64], atol=1e-12)
    # One value per material for the effect analysis: the sharpest roughness found.
    assert table.roughness[0] == pytest.approx(0.1)


def test_metallic_map_splits_diffuse_and_metal_and_clamps_like_cycles():
    # Metallic 0 / 1.7 (Cycles clamps to 1): the metal half has no diffuse lobe.
    s = _quad_scene(scalar_textures={"metallic": _split(0.0, 1.7)})
    geo, table = prepare(s)
    hit = _hits(geo, table, [-0.5, 0.5])
    np.testing.assert_allclose(hit.params[:, pr.M_METALLIC], [0.0, 1.0])
    _, alb = closures(table, hit)
    assert alb[0, pr.L_DIFFUSE].max() > 0.5 and alb[1, pr.L_DIFFUSE].max() == 0.0
    assert alb[1, pr.L_METAL].max() > 0.5 and alb[0, pr.L_METAL].max() == 0.0
    # The effect analysis sees both: a metal lobe somewhere, a diffuse lobe somewhere.
    assert table.metallic[0] == 1.0 and table.has_diffuse[0] and table.has_specular[0]


def test_photons_store_on_both_sides_of_a_metallic_map():
    # The flux a photon stores arrives whatever lobes its hit has: a camera hit on the
    # diffuse half near the edge (or on a map finer than the photon radius) reads the
    # density of the photons around it, metal texels included (issue 14, mixfix).
    s = _quad_scene(scalar_textures={"metallic": _split(0.0, 1.0)})
    s.add_light(Light("lamp", "POINT", 50.0, position=(0.0, 0.0, 1.0)))
    s.camera = Camera.look_at((0.0, -3.0, 2.0), (0.0, 0.0, 0.0))
    s.validate()
    settings = RenderSettings(photons=200_000, seed=3)
    geo, table = prepare(s)
    accel = Accel(geo.vertices32, geo.faces32, 1)
    lights = prepare_lights(s, geo, table)
    ctx = Context(s, settings, geo, table, accel, lights)
    ph = trace_photons(ctx, lights, allocate_photons(lights, settings.photons), False, 1)
    x = ph.position[:, 0] + geo.offset[0]
    assert len(x) > 1000
    # UV u = (x + 1) / 2: metal (no diffuse) where x > 0. The lamp sits over x = 0: each
    # half receives half of the flux (~17k photons each: 1.1 % standard deviation of the
    # ratio). Storing only where the hit's own diffuse lobe is: no photon at x > 0.
    metal = ph.power[x > 0, 1].astype(np.float64).sum()
    dielectric = ph.power[x < 0, 1].astype(np.float64).sum()
    assert metal / dielectric == pytest.approx(1.0, abs=0.045)


def test_unknown_scalar_input_names_the_material():
    with pytest.raises(SceneError, match="'m' scalar_textures.*'shininess'"):
        Material("m", scalar_textures={"shininess": sn.UVCoord()})
    with pytest.raises(SceneError, match="'m' scalar_textures\\['roughness'\\]"):
        Material("m", scalar_textures={"roughness": 0.3})


def test_layer_weight_and_fresnel_follow_cycles_per_hit_view():
    s = _quad_scene()
    geo, _ = prepare(s)
    n = np.tile([0.0, 0.0, 1.0], (3, 1))
    cos = np.array([1.0, 0.5, 0.1])
    wi = np.stack([np.sqrt(1 - cos ** 2), np.zeros(3), cos], axis=1)
    sg = sn.ShadingGeometry(geo, n, wi, np.zeros(3, bool))
    prim, u, v = np.zeros(3, np.int64), np.full(3, 0.2), np.full(3, 0.2)
    # Facing, blend 0.5: 1 - |cos|; blend 0.25: 1 - |cos|^0.5; blend 0.75: 1 - |cos|^2.
    for blend, power in ((0.5, 1.0), (0.25, 0.5), (0.75, 2.0)):
        got = sn.LayerWeight(blend, "FACING").evaluate(sg, prim, u, v)
        np.testing.assert_allclose(got, 1 - cos ** power, atol=1e-12)
    # Fresnel at normal incidence: ((eta - 1) / (eta + 1))^2; Layer Weight's eta = 1 / (1 - blend).
    f = sn.Fresnel(1.5).evaluate(sg, prim, u, v)
    assert f[0] == pytest.approx(0.04) and f[0] < f[1] < f[2] < 1
    lw = sn.LayerWeight(0.5, "FRESNEL").evaluate(sg, prim, u, v)
    assert lw[0] == pytest.approx(1 / 9)
    # A back face: the ray leaves the denser side (eta inverted): total reflection at 0.1.
    back = sn.ShadingGeometry(geo, n, wi, np.ones(3, bool))
    assert sn.Fresnel(1.5).evaluate(back, prim, u, v)[2] == 1.0


def test_mix_factor_from_the_view_reaches_the_closures():
    # Metallic driven by Layer Weight Facing (what a Mix Shader of a Diffuse and a Glossy
    # BSDF by that factor becomes): 0 seen head-on, near 1 at grazing views.
    s = _quad_scene(scalar_textures={"metallic": sn.LayerWeight(0.5, "FACING")})
    geo, table = prepare(s)
    d = np.array([[0.0, 0.0, -1.0], [np.sqrt(1 - 0.01), 0.0, -0.1]])
    hit = surface_hit(geo, table, np.zeros(2, np.int64), np.full(2, 0.3), np.full(2, 0.2), d)
    np.testing.assert_allclose(hit.params[:, pr.M_METALLIC], [0.0, 0.9], atol=1e-9)


def test_emission_texture_per_hit_and_per_triangle_average_for_the_light():
    from engine.geometry import emissive_triangles
    # Emission colour red where u < 0.5, blue elsewhere, strength 2.
    u_ = sn.SeparateChannel(sn.UVCoord(), 0)
    colour = sn.MixColor(sn.Math("GREATER_THAN", u_, 0.5), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    s = Scene()
    s.add_material(Material("e", (0, 0, 0), emission=(2.0, 2.0, 2.0), emission_texture=colour))
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    # Triangle 0 (x >= y) is three quarters blue (x > 0.5), triangle 1 one quarter.
    s.add_mesh(Mesh("quad", v, np.array([[0, 1, 2], [0, 2, 3]]), uvs=v[:, :2],
                    materials=["e"]))
    geo, table = prepare(s)
    prim = np.zeros(2, np.int64)
    hit = surface_hit(geo, table, prim, np.array([0.1, 0.7]), np.array([0.05, 0.1]),
                      np.tile([0.0, 0.0, -1.0], (2, 1)))
    np.testing.assert_allclose(hit.emission, [[2, 0, 0], [0, 0, 2]])
    idx, L, _ = emissive_triangles(geo, table)
    np.testing.assert_allclose(L[idx == 0][0], [0.5, 0, 1.5], atol=0.03)
    np.testing.assert_allclose(L[idx == 1][0], [1.5, 0, 0.5], atol=0.03)
    with pytest.raises(SceneError, match="'m' emission_texture"):
        Material("m", emission_texture=(1, 0, 0))


def test_glossy_normal_is_raised_so_the_mirror_direction_stays_above_the_surface():
    """Cycles' ensure_valid_specular_reflection: the glossy lobes' normal N' lifts the
    reflection of wo to height min(0.9 wo.ng, 0.01) over the surface; unchanged where
    the reflection is above already or N = Ng."""
    rng = np.random.default_rng(5)
    n = 400
    ng = np.tile([0.0, 0.0, 1.0], (n, 1))
    ns = rng.normal(size=(n, 3)) * [0.6, 0.6, 0.0] + [0.0, 0.0, 1.0]
    ns /= np.linalg.norm(ns, axis=1, keepdims=True)
    wo = rng.normal(size=(n, 3))
    wo[:, 2] = np.abs(wo[:, 2]) * 0.3
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    ns[0] = ng[0]
    local = np.zeros((n, 3))
    cos_o = np.full(n, -5.0)
    pr.glossy_normals(ns, ng, wo, local, cos_o)
    raised = np.any(local != 0, axis=1)
    refl = 2 * np.einsum("ij,ij->i", ns, wo)[:, None] * ns - wo
    t = np.minimum(0.9 * wo[:, 2], 0.01)
    assert not raised[0]
    np.testing.assert_array_equal(raised[1:], refl[1:, 2] < t[1:])
    assert 20 < raised.sum() < n - 20
    # N' in world space from its local frame about ns (principled.frame_world).
    world = np.array([pr.frame_world(*ns[i], *local[i]) for i in np.nonzero(raised)[0]])
    w = wo[raised]
    r2 = 2 * np.einsum("ij,ij->i", world, w)[:, None] * world - w
    np.testing.assert_allclose(r2[:, 2], t[raised], atol=1e-6)
    np.testing.assert_allclose(np.linalg.norm(world, axis=1), 1.0, atol=1e-9)
    # The set-up's view cosine about N' where raised; untouched elsewhere.
    np.testing.assert_allclose(cos_o[raised], np.einsum("ij,ij->i", world, w), atol=1e-9)
    assert np.all(cos_o[~raised] == -5.0)
