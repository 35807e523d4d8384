"""The camera bounce's light samples in the fused surface kernel (issue 13, twelfth slice:
camerakernels.surface_lobes' light stage, bsdf.surface_hit_lobes(lights=)) against the
path it replaces: surface_hit_lobes without lights, then the direct stage sampling the
shaded rows (directlight.sample_lights through direct_irradiance), with the same numbers
(drawn for every hit by integrator.light_numbers and read at the shaded rows). Bitwise:
the surface data and lobes, the sums, the entries and their float32 shadow rays; with
every light kind, two samples per light, the light tree, shadow-terminator lifts, a
shading offset, glossy shadow rays (the directions written from the first glossy block
on, the earlier blocks sampled again) and without."""
import numpy as np
import pytest

import engine.directlight as dl
from engine import RenderSettings
from engine.api import cornell_box
from engine.bsdf import plain_surfaces, surface_hit_lobes
from engine.camerakernels import SURFACE_BLOCK
from engine.closures import principled as pr
from engine.integrator import BounceBuffers, Counters, light_numbers, shade_diffuse
from engine.lights.packing import pack_lights
from engine.lights.selection import empty_tree
from engine.render import prepare_context
from engine.scene import Material
from helpers import rays_from_inside


def _lit_box(many_lights=False):
    """The Cornell box with its smooth glass sphere (terminator lift, unshaded rows),
    layered and rough metal walls (glossy rows), a shading offset, a point light with a
    radius, a spot light and an emissive sphere (a mesh light); with many_lights 20
    more point lights (the light tree picks one per hit and sample)."""
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


def _entries(buf, m_all):
    """The entries of a direct_light call sorted by (hit, sample), with their shadow rays
    (NaN for an untraced one)."""
    row, kidx, ray = buf.row[:m_all], buf.kidx[:m_all], buf.ray[:m_all]
    order = np.lexsort((kidx, row))
    ray = ray[order]
    traced = ray >= 0
    o = np.full((m_all, 3), np.nan, np.float32)
    d = np.full((m_all, 3), np.nan, np.float32)
    t = np.full(m_all, np.nan, np.float32)
    o[traced], d[traced], t[traced] = (buf.o32[ray[traced]], buf.d32[ray[traced]],
                                       buf.t32[ray[traced]])
    return row[order], kidx[order], buf.contrib[:m_all][order], traced, o, d, t


@pytest.mark.parametrize("scene", ["lit", "tree"])
@pytest.mark.parametrize("order", ["as_traced", "glossy_last", "no_glossy_rays"])
def test_light_stage_in_the_surface_kernel_equals_the_direct_stage(scene, order):
    ctx = prepare_context(_lit_box(scene == "tree"),
                          RenderSettings(light_samples=2, workers=1, photon_mapping=False))
    assert plain_surfaces(ctx.table) and ctx.geo.shared is None
    assert (ctx.geo.object_terminator > 0).any()
    assert ctx.geo.object_terminator_shading.view(np.uint32).any()
    prim, u, v, d = rays_from_inside(ctx, 30000, 11)
    if order == "glossy_last":
        # Whole blocks without a glossy row first: the directions are switched on late
        # and the earlier blocks' lights sampled again.
        rough = np.any(np.take(ctx.table.closure_params, np.take(ctx.geo.material, prim),
                               axis=0)[:, [pr.M_SHEEN_W, pr.M_COAT_W, pr.M_METALLIC,
                                           pr.M_SPEC]] > 0.0, axis=1)
        k = np.argsort(rough, kind="stable")
        prim, u, v, d = prim[k], u[k], v[k], d[k]
        assert (~rough).sum() > 3 * SURFACE_BLOCK
    n = len(prim)
    want_glossy = order != "no_glossy_rays"
    tp = np.ascontiguousarray(10.0 ** (-2.0 * np.random.default_rng(4).random((n, 3))))
    samples, chosen = light_numbers(ctx, n, np.random.default_rng(3))
    if scene == "tree":
        assert chosen is not None and len(samples) == 2 and samples[0][0] == -1
    else:
        assert chosen is None and len(samples) >= 8  # 4+ lights x 2 samples
    packed = ctx.packed_lights or pack_lights(ctx.lights)
    tree = (chosen[1] if chosen is not None else
            (*empty_tree(), np.ones(len(packed[0]), np.bool_)))
    results = []
    for fused in (True, False):
        bounce = BounceBuffers()
        out = bounce.take(n)
        for a in out:
            if a.dtype.kind == "f":
                a.fill(np.nan)
        buf = bounce.direct
        sampled = None
        if fused:
            group = dl.sample_arrays(samples, n, buf)
            hit, k, sampled = surface_hit_lobes(ctx.geo, ctx.table, prim, u, v, d, tp,
                                                want_glossy, out,
                                                lights=(packed, tree, group, buf))
        else:
            hit, k = surface_hit_lobes(ctx.geo, ctx.table, prim, u, v, d, tp, want_glossy,
                                       out)
        prm, sel, p, q, psum, glossy, rows, wd = out
        assert 0 < k < n  # the glass sphere's hits are not shaded
        dsel = rows[:k]
        g = glossy[dsel]
        assert g.any() == want_glossy
        counters = Counters()
        E = shade_diffuse(ctx, hit, wd[:k], np.random.default_rng(9), counters, glossy=g,
                          sel=sel if g.any() else None, buffers=buf, rows=dsel,
                          drawn=(samples, chosen, sampled))[0].copy()
        m_all = sampled[0] if fused else None
        results.append((hit, k, [a.copy() for a in out], E, counters.shadow_rays, buf,
                        m_all))
    (hf, kf, of, Ef, rf, bf, mf), (ho, ko, oo, Eo, ro, bo, _) = results
    for name in ("p", "ng", "ns", "wo", "front", "mat", "base", "offset", "bary"):
        assert np.array_equal(getattr(hf, name), getattr(ho, name)), name
    assert kf == ko
    for i, (a, b) in enumerate(zip(of, oo)):
        if i >= 6:  # rows, wd: the first K are written
            a, b = a[:kf], b[:kf]
        assert np.array_equal(a, b, equal_nan=True)
    assert np.array_equal(Ef, Eo) and Ef[:, 0].max() > 0
    assert rf == ro > 0
    # The same entries and shadow rays (the fused kernel writes them block by block).
    m_all = mf
    got, want = _entries(bf, m_all), _entries(bo, m_all)
    for a, b in zip(got, want):
        assert np.array_equal(a, b, equal_nan=True)
    if want_glossy:
        # The BSDF-weighted sums read every entry's direction and pdf.
        order_f = np.lexsort((bf.kidx[:m_all], bf.row[:m_all]))
        order_o = np.lexsort((bo.kidx[:m_all], bo.row[:m_all]))
        assert np.array_equal(bf.wdir[:m_all][order_f], bo.wdir[:m_all][order_o])
        assert np.array_equal(bf.lpdf[:m_all][order_f], bo.lpdf[:m_all][order_o])


def test_light_stage_off_writes_no_entries():
    """Without lights (klight (0,)) the kernel is the surface + lobes kernel alone: the
    same outputs as before this slice's light stage (the test above's oracle path) and no
    entry."""
    ctx = prepare_context(_lit_box(), RenderSettings(workers=1, photon_mapping=False))
    prim, u, v, d = rays_from_inside(ctx, 3000, 5)
    n = len(prim)
    tp = np.ones((n, 3))
    buf = dl.DirectLightBuffers()
    out = BounceBuffers().take(n)
    packed = pack_lights([])
    tree = (*empty_tree(), np.zeros(0, np.bool_))
    group = dl.sample_arrays([], n, buf)
    hit, k, sampled = surface_hit_lobes(ctx.geo, ctx.table, prim, u, v, d, tp, True, out,
                                        lights=(packed, tree, group, buf))
    out2 = BounceBuffers().take(n)
    hit2, k2 = surface_hit_lobes(ctx.geo, ctx.table, prim, u, v, d, tp, True, out2)
    assert sampled == (0, 0) and k == k2 > 0
    assert np.array_equal(hit.p, hit2.p) and np.array_equal(out[6][:k], out2[6][:k])
