"""The direct stage on a camera bounce's shaded rows read in place (issue 13, eleventh
slice: shade_diffuse / direct_irradiance rows=, directlight.sample_lights and
accumulate_bsdf hrow): bitwise the same as the compacted copy (SurfaceHit.take) it
replaces, with every light kind, several samples per light, the light tree, shadow
terminator lifts and shading offsets, bent normals (bump shadowing), and the
BSDF-weighted path with multiple importance sampling."""
import numpy as np
import pytest

import engine.directlight as dl
from engine import RenderSettings
from engine.api import PaperScene, cornell_box
from engine.bsdf import closures, surface_hit
from engine.closures import principled as pr
from engine.integrator import Counters, direct_irradiance, lobe_choice, shade_diffuse
from engine.normalmap import NormalMap
from engine.render import prepare_context
from engine.sampling import max3
from engine.scene import Material
from engine.textures import ImageTexture
from helpers import hits_from_inside


def _mixed_box(many_lights=False):
    """The Cornell box with its (smooth: terminator lift) glass sphere, layered and rough
    metal walls (glossy shadow rays), a shading offset on one object, a point, a spot and
    an emissive sphere; with many_lights 20 more point lights (the light tree)."""
    s = cornell_box(8, 6, glass_sphere=True)
    s.add_material(Material("layered", (0.6, 0.3, 0.2), specular=1.0, roughness=0.4,
                            coat_weight=0.8, coat_roughness=0.1, sheen_weight=1.0))
    s.add_material(Material("rough_metal", (0.9, 0.7, 0.3), metallic=1.0, roughness=0.3))
    for mesh in s.meshes:
        new = {"back": "layered", "block": "rough_metal"}.get(getattr(mesh, "name", ""))
        if new is not None:
            mesh.materials = [new for _ in mesh.materials]
    s.meshes[0].shadow_terminator_shading_offset = 0.3
    s.add_point_light((-1.0, 0.5, 3.0), 30.0, radius=0.05)
    s.add_spot_light((1.0, -0.5, 3.5), (0, 0, 0), 60.0, radius=0.1)
    s.add_sphere((-1.2, 1.2, 2.5), 0.2, Material("glow", emission=(4, 4, 4)), name="glow",
                 segments=8)
    if many_lights:
        rng = np.random.default_rng(2)
        for i in range(20):
            s.add_point_light(tuple(rng.uniform([-1.5, -1.5, 2.0], [1.5, 1.5, 3.5])), 5.0,
                              radius=0.02, name=f"p{i}")
    return s


def _bent_floor():
    s = PaperScene(width=8, height=8)
    tex = ImageTexture(np.array([[[0.7, 0.5, 0.9], [0.5, 0.5, 1.0]]], np.float32))
    s.add_material(Material("bent", (0.8, 0.8, 0.8), specular=1.0, roughness=0.3,
                            normal_map=NormalMap(tex, 1.0, "WORLD")))
    s.add_plane((0, 0, 0), size=4.0, material="bent", name="floor")
    s.add_sun(direction=(0.5, 0.1, -1.0), strength=3.0)
    s.add_point_light((0.5, 0.5, 1.0), 20.0, radius=0.1)
    s.set_camera((0, 0, 3), (0, 0, 0), view_angle=30)
    return s


def _hits(ctx, n, seed, floor=False):
    if not floor:
        return hits_from_inside(ctx, n, seed)
    rng = np.random.default_rng(seed)
    o = np.column_stack([rng.uniform(-1.9, 1.9, n), rng.uniform(-1.9, 1.9, n), np.ones(n)])
    d = np.tile([0.0, 0.0, -1.0], (n, 1))
    t, prim, u, v = ctx.accel.intersect(o, d)
    k = prim >= 0
    return surface_hit(ctx.geo, ctx.table, prim[k], u[k], v[k], d[k])


@pytest.mark.parametrize("scene", ["mixed", "tree", "bent"])
@pytest.mark.parametrize("glossy_rays", [True, False])
def test_shaded_rows_in_place_equal_their_copy(scene, glossy_rays):
    build = {"mixed": _mixed_box, "tree": lambda: _mixed_box(True), "bent": _bent_floor}
    ctx = prepare_context(build[scene](), RenderSettings(light_samples=2, workers=1,
                                                         photon_mapping=False))
    hit = _hits(ctx, 6000, 3, floor=scene == "bent")
    n = len(hit.p)
    if scene == "bent":
        assert hit.n_smooth is not None  # bump terms written and read
    if scene == "tree":
        from engine.lights.selection import selector_for
        assert selector_for(ctx) is not None  # one light per hit and sample, by the tree
    if scene == "mixed":
        assert (ctx.geo.object_terminator > 0).any()
        assert ctx.geo.object_terminator_shading.view(np.uint32).any()
    prm, alb = closures(ctx.table, hit)
    hit.prm = prm
    tp = 10.0 ** (-2.0 * np.random.default_rng(4).random((n, 3)))
    sel = lobe_choice(alb, tp)[0]
    glossy = np.zeros(n, bool)
    if glossy_rays:
        pr.rough_reflection_rows(prm, glossy)
        assert glossy.any()
    wd_all = alb[:, 0]
    # The rows a bounce shades, thinned so that the rows are not the whole batch.
    rows = np.nonzero((max3(wd_all) > 0) | glossy)[0]
    rows = rows[np.random.default_rng(5).random(len(rows)) < 0.7]
    assert 0 < len(rows) < n
    wd, g = wd_all[rows], glossy[rows]
    sub = hit.take(rows)
    for seed in (1, 2):
        want = shade_diffuse(ctx, sub, wd, np.random.default_rng(seed), Counters(),
                             glossy=g, sel=sel[rows] if g.any() else None)[0].copy()
        buffers = dl.DirectLightBuffers()
        got = shade_diffuse(ctx, hit, wd, np.random.default_rng(seed), Counters(), glossy=g,
                            sel=sel if g.any() else None, buffers=buffers, rows=rows)[0]
        assert np.array_equal(got, want)
        assert got.shape == (len(rows), 3) and got[:, 0].max() > 0
        # direct_irradiance alone (the regathers' call), fresh arrays
        a = direct_irradiance(ctx, sub, np.random.default_rng(seed), Counters())
        b = direct_irradiance(ctx, hit, np.random.default_rng(seed), Counters(), rows=rows)
        assert np.array_equal(a, b)


def test_no_bump_terms_when_no_normal_is_bent():
    """Without a bent normal (nsm is ns) sample_lights writes no bump terms and
    accumulate reads none: the same sums as with a row of ones."""
    from engine.integrator import _hit_arrays
    from engine.lights.packing import pack_lights
    from engine.lights.selection import empty_tree

    ctx = prepare_context(_mixed_box(), RenderSettings(workers=1, photon_mapping=False))
    hit = _hits(ctx, 3000, 8)
    arrays = _hit_arrays(ctx.geo, hit)
    assert arrays[8] is arrays[1]
    codes, params, mesh = pack_lights(ctx.lights)
    L = len(codes)
    n = len(hit.p)
    U1, U2, SEL = np.random.default_rng(3).random((3, L, n))
    sums = []
    for bump_out in (True, False):
        b = dl.DirectLightBuffers().ensure(L * n)
        b.bump[:] = np.nan
        m_all, m_rays = dl.sample_lights(*arrays, codes, params, *mesh, *empty_tree(),
                                         np.ones(L, np.bool_), np.arange(L),
                                         np.ones(L, np.bool_), U1, U2, SEL, b.contrib,
                                         b.row, b.kidx, b.ray, b.o32, b.d32, b.t32,
                                         dl.NO_ROWS3, dl.NO_ROWS,
                                         b.bump if bump_out else dl.NO_ROWS, dl.NO_HROWS,
                                         dl.NO_ROWS3)
        if bump_out:
            assert np.all(b.bump[:m_all] == 1.0)
        else:
            assert np.isnan(b.bump[:m_all]).all()  # unwritten
        E = np.zeros((n, 3))
        dl.accumulate(E, b.contrib, b.row, b.kidx, b.ray, np.ones(L),
                      np.zeros(max(m_rays, 1), np.bool_), m_all,
                      b.bump if bump_out else dl.NO_ROWS)
        sums.append(E)
    assert m_all > n and np.array_equal(sums[0], sums[1])


def _lit_side_normals(geo, hit):
    """The numpy stage the kernel's own choice replaced (integrator._lit_side_normals, an
    (N,3) array per batch): ns on smooth triangles whose object has a terminator offset,
    else ng."""
    if hit.bary is None or not len(hit.prim) or not (geo.object_terminator > 0).any():
        return hit.ng
    smooth = np.take(geo.smooth, hit.prim) & (np.take(geo.terminator, hit.prim) > 0)
    return np.where(smooth[:, None], hit.ns, hit.ng)


@pytest.mark.parametrize("terminator", [0.1, 0.0])
def test_lit_side_chosen_in_the_kernel_equals_the_numpy_gate(terminator):
    """sample_lights' gate (0,3) (the lit side chosen from the terminator cut-off per hit)
    writes the same entries and shadow rays as the explicit (N,3) gate of the numpy
    stage, on a box whose smooth glass sphere has a terminator offset (or none)."""
    from engine.integrator import _hit_arrays
    from engine.lights.packing import pack_lights
    from engine.lights.selection import empty_tree

    s = _mixed_box()
    for mesh in s.meshes:
        mesh.shadow_terminator_offset = terminator
    ctx = prepare_context(s, RenderSettings(workers=1, photon_mapping=False))
    hit = _hits(ctx, 8000, 9)
    arrays = list(_hit_arrays(ctx.geo, hit))
    assert arrays[2].shape == (0, 3)
    gate = np.ascontiguousarray(_lit_side_normals(ctx.geo, hit), np.float64)
    if terminator > 0:
        smooth = np.take(ctx.geo.smooth, hit.prim)
        assert smooth.any() and (~smooth).any()
        assert not np.array_equal(gate, hit.ng)  # the choice matters somewhere
    explicit = list(arrays)
    explicit[2] = gate
    codes, params, mesh = pack_lights(ctx.lights)
    L = len(codes)
    n = len(hit.p)
    U1, U2, SEL = np.random.default_rng(4).random((3, L, n))
    out = []
    for hit_arrays in (explicit, arrays):
        b = dl.DirectLightBuffers().ensure(L * n)
        m = dl.sample_lights(*hit_arrays, codes, params, *mesh, *empty_tree(),
                             np.ones(L, np.bool_), np.arange(L), np.ones(L, np.bool_),
                             U1, U2, SEL, b.contrib, b.row, b.kidx, b.ray, b.o32, b.d32,
                             b.t32, b.wdir, b.lpdf, dl.NO_ROWS, dl.NO_HROWS, dl.NO_ROWS3)
        out.append((m, b))
    (m0, a), (m1, b) = out
    assert m0 == m1 and m0[1] > n
    j, r = m0
    for name, k in (("contrib", j), ("row", j), ("kidx", j), ("ray", j), ("wdir", j),
                    ("lpdf", j), ("o32", r), ("d32", r), ("t32", r)):
        assert np.array_equal(getattr(a, name)[:k], getattr(b, name)[:k]), name
