"""Shadow rays to emissive meshes pick the triangle by a light tree over the triangles at
the shading point (issue 14, meshlight: MeshLight.triangle_tree, directlight.sample_lights,
Cycles' light tree / pbrt-v4's BVHLightSampler), and every place that weighs a mesh
light's sample by its probability takes the same pmf (MeshLight.triangle_pmf: the MIS
weight of BSDF rays that meet an emitter, integrator._mesh_mis_weight).

Three small emitting quads (six triangles) of different radiance, one low and close, one
high and far, one facing up (two-sided emission: the floor sees its back), over a floor,
direct light only: the pmf over the triangles sums to one at any point and normal, the
walk's choices over many numbers follow the pmf, and the irradiance's mean matches
Lambert's closed form for the three polygons.
"""
import math

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.integrator import Counters, direct_irradiance
from engine.lights.selection import NINF, select_many
from engine.render import prepare_context
from engine.scene import Camera, Material, Mesh

from test_ray_offsets import DIRECT_ONLY, _floor_hits, _lambert_polygon

# (centre, tilt about y in degrees (0: facing down, 180: facing up), size, radiance)
QUADS = [((0.0, 0.0, 0.4), 20.0, 0.3, 30.0),
         ((3.0, 1.0, 2.5), 0.0, 0.8, 10.0),
         ((-1.5, -0.5, 1.0), 150.0, 0.5, 20.0)]
POINTS_X = np.array([0.0, 0.4, 2.5, -1.2, 1.0])
POINTS_Y = np.array([0.0, 0.1, 1.0, -0.3, -1.0])


def _quad(center, tilt_deg, size):
    t = math.radians(tilt_deg)
    ax = np.array([math.cos(t), 0.0, math.sin(t)])
    ay = np.array([0.0, 1.0, 0.0])
    c = np.asarray(center, float)
    h = size / 2
    return np.array([c - h * ax - h * ay, c + h * ax - h * ay, c + h * ax + h * ay,
                     c - h * ax + h * ay])


@pytest.fixture(scope="module")
def ctx():
    s = PaperScene(width=4, height=4)
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, "white_diffuse", name="floor")
    for i, (c, tilt, size, L) in enumerate(QUADS):
        s.add_material(Material(f"lamp{i}", (0.0, 0.0, 0.0), emission=(L, L, L)))
        s.add_mesh(Mesh(f"quad{i}", _quad(c, tilt, size), [[0, 1, 2], [0, 2, 3]],
                        materials=[f"lamp{i}"]))
    s.camera = Camera(position=(0, -10, 3), rotation=np.eye(3))
    ctx = prepare_context(s, RenderSettings(**DIRECT_ONLY))
    assert len(ctx.lights) == 1 and len(ctx.lights[0].tri_area) == 6
    yield ctx
    ctx.accel.close()


def _points(ctx, rng, n):
    """Points round the quads (recentred as the geometry) and random unit normals."""
    p = rng.uniform([-3, -2, -0.5], [4, 2, 3], size=(n, 3)) - ctx.geo.offset
    nrm = rng.normal(size=(n, 3))
    return p, nrm / np.linalg.norm(nrm, axis=1, keepdims=True)


def test_triangle_pmf_sums_to_one(ctx):
    light = ctx.lights[0]
    p, nrm = _points(ctx, np.random.default_rng(1), 500)
    T = len(light.tri_area)
    total = sum(light.triangle_pmf(p, nrm, np.full(len(p), k)) for k in range(T))
    assert np.allclose(total, 1.0, rtol=0, atol=1e-12), total.min()
    # without a normal (volumes): the same
    total = sum(light.triangle_pmf(p, 0 * nrm, np.full(len(p), k)) for k in range(T))
    assert np.allclose(total, 1.0, rtol=0, atol=1e-12)


def test_tree_choices_follow_the_pmf(ctx):
    """The walk the kernel takes (selection.select_light, here through select_many) picks
    triangle k with frequency triangle_pmf(k) and reports that pmf."""
    light = ctx.lights[0]
    tf, ti, _ = light.triangle_tree()
    rng = np.random.default_rng(2)
    p, nrm = _points(ctx, rng, 6)
    N = 100_000
    T = len(light.tri_area)
    for i in range(len(p)):
        P, Nn = np.repeat(p[i:i + 1], N, axis=0), np.repeat(nrm[i:i + 1], N, axis=0)
        tri = np.empty(N, np.int64)
        pmf = np.empty(N)
        select_many(P, Nn, rng.random(N), tf, ti, np.zeros(0, np.int64),
                    np.zeros((0, NINF)), tri, pmf)
        want = np.array([light.triangle_pmf(P[:1], Nn[:1], [k])[0] for k in range(T)])
        assert (tri >= 0).all()
        assert np.allclose(pmf, want[tri], rtol=1e-12, atol=0)
        freq = np.bincount(tri, minlength=T) / N
        se = np.sqrt(want * (1 - want) / N)
        assert (np.abs(freq - want) <= 5 * se + 1e-12).all(), (freq, want)


def test_tree_prefers_the_near_facing_triangles(ctx):
    """Below the low quad its triangles take most of the choices, far more than their
    share of the power (the area x brightness choice before)."""
    light = ctx.lights[0]
    p = np.array([[0.0, 0.0, 0.0]]) - ctx.geo.offset
    up = np.array([[0.0, 0.0, 1.0]])
    near = [k for k in range(6) if light.v0[k, 2] + ctx.geo.offset[2] < 0.6]
    assert len(near) == 2
    share = light.prob[near].sum()
    picked = sum(light.triangle_pmf(p, up, [k])[0] for k in near)
    assert picked > 0.9 and picked > 3 * share, (picked, share)


def test_direct_light_matches_lambert(ctx):
    """Unbiased: the mean irradiance over many samples matches the three polygons'
    closed form (two-sided: the upward quad lights the floor with its back)."""
    reps = 20_000
    hit = _floor_hits(ctx, POINTS_X, POINTS_Y, reps)
    E = direct_irradiance(ctx, hit, np.random.default_rng(3), Counters())[:, 1]
    E = E.reshape(len(POINTS_X), reps)
    mean, se = E.mean(axis=1), E.std(axis=1) / math.sqrt(reps)
    up = np.array([0.0, 0.0, 1.0])
    ref = np.array([sum(L * _lambert_polygon(np.array([x, y, 0.0]), up, _quad(c, t, s))
                        for c, t, s, L in QUADS) for x, y in zip(POINTS_X, POINTS_Y)])
    assert (np.abs(mean - ref) <= np.maximum(4 * se, 0.003 * ref)).all(), (mean / ref, se / ref)


def test_mis_pdf_of_a_bsdf_ray_matches_the_shadow_ray_pdf(ctx):
    """The solid-angle pdf the kernel writes for each shadow-ray sample (tree pmf / area x
    d^2 / |cos|) is the pdf integrator._mesh_mis_weight gives a BSDF ray leaving the same
    point in the same direction and meeting the same triangle: with the BSDF pdf set to
    it, the power heuristic's weight is exactly 1/2."""
    from engine.directlight import NO_HROWS, NO_ROWS3, DirectLightBuffers, sample_lights
    from engine.integrator import MODE_MIS, _hit_arrays, _mesh_mis_weight
    from engine.lights.packing import pack_lights
    from engine.lights.selection import empty_tree
    reps = 400
    hit = _floor_hits(ctx, POINTS_X, POINTS_Y, reps)
    n = len(hit.p)
    rng = np.random.default_rng(4)
    u1, u2, sel = rng.random((3, n))
    buf = DirectLightBuffers().ensure(n)
    codes, params, mesh = pack_lights(ctx.lights)
    m_all, _ = sample_lights(*_hit_arrays(ctx.geo, hit), codes, params, *mesh, *empty_tree(),
                             np.ones(len(codes), np.bool_), np.zeros(1, np.int64),
                             np.ones(1, np.bool_), u1[None], u2[None], sel[None],
                             buf.contrib, buf.row, buf.kidx, buf.ray, buf.o32, buf.d32,
                             buf.t32, buf.wdir, buf.lpdf, buf.bump, NO_HROWS, NO_ROWS3)
    assert m_all > 0.5 * n
    rows = buf.row[:m_all]
    p, ns = hit.p[rows], hit.ns[rows]
    d, lpdf = buf.wdir[:m_all].copy(), buf.lpdf[:m_all].copy()
    o = p + 1e-6 * hit.ng[rows]
    t, prim, _, _ = ctx.accel.intersect(o, d)
    lit = np.isin(prim, ctx.lights[0].tri_index)
    assert lit.mean() > 0.95  # rays that met the floor's edge or another quad: left out
    w = _mesh_mis_weight(ctx, np.array([MODE_MIS]), prim[lit], o[lit], d[lit], t[lit],
                         ctx.geo.ng[prim[lit]], lpdf[lit], p[lit], ns[lit])
    assert np.allclose(w, 0.5, rtol=0, atol=1e-4), (w.min(), w.max())


def test_close_long_strip_sampled_by_solid_angle():
    """A 1.4 m x 2 cm strip (a neon tube's side) 15 cm over the floor: its triangles are
    sampled by solid angle (large against their distance), so the mean matches Lambert
    and a sample's spread is that of the receiver's cosine and the two triangles' pmf
    alone (measured: relative standard deviation 0.25-0.83 at these points); a uniform
    point on the strip spreads 1 / d^2 along its length (1.6-1.95, by quadrature)."""
    s = PaperScene(width=4, height=4)
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, "white_diffuse", name="floor")
    s.add_material(Material("neon", (0.0, 0.0, 0.0), emission=(25.0, 25.0, 25.0)))
    strip = np.array([[-0.7, -0.01, 0.15], [0.7, -0.01, 0.15], [0.7, 0.01, 0.15],
                      [-0.7, 0.01, 0.15]])
    s.add_mesh(Mesh("strip", strip, [[0, 1, 2], [0, 2, 3]], materials=["neon"]))
    s.camera = Camera(position=(0, -10, 3), rotation=np.eye(3))
    c = prepare_context(s, RenderSettings(**DIRECT_ONLY))
    try:
        xs, ys = np.array([0.0, 0.5, 0.9]), np.array([0.0, 0.1, -0.2])
        reps = 20_000
        hit = _floor_hits(c, xs, ys, reps)
        E = direct_irradiance(c, hit, np.random.default_rng(5), Counters())[:, 1]
        E = E.reshape(len(xs), reps)
        mean, sd = E.mean(axis=1), E.std(axis=1)
        up = np.array([0.0, 0.0, 1.0])
        ref = np.array([25.0 * _lambert_polygon(np.array([x, y, 0.0]), up, strip)
                        for x, y in zip(xs, ys)])
        se = sd / math.sqrt(reps)
        assert (np.abs(mean - ref) <= np.maximum(4 * se, 0.003 * ref)).all(), mean / ref
        # A uniform point's relative spread by quadrature along the strip (its width
        # neglected): 1.66, 1.61, 1.95 at these points.
        along = np.linspace(-0.7, 0.7, 14001)
        area_sd = []
        for x, y in zip(xs, ys):
            f = 1.0 / ((along - x) ** 2 + y * y + 0.15 ** 2) ** 2
            area_sd.append(math.sqrt((f * f).mean() / f.mean() ** 2 - 1.0))
        assert (sd / ref < 0.5 * np.array(area_sd)).all(), (sd / ref, area_sd)
    finally:
        c.accel.close()
