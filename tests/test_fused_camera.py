"""The camera bounce's fused lobe kernel (issue 13, eighth slice: camerakernels.shade_lobes)
against the kernels it replaced in integrator._trace_paths, kept as oracles:
hit_closures (bsdf.closures), choose_lobes (integrator.lobe_choice), the glossy rows
(principled.rough_reflection_rows) and the diffuse selection ((max3(wd) > 0) | glossy).
All bitwise, on a box whose materials mix diffuse-only ones (set-up skipped) with every
other lobe, per-hit parameter and alpha rows, and Russian roulette."""
import dataclasses

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import cornell_box
from engine.bsdf import closures, surface_hit
from engine.camerakernels import shade_lobes
from engine.closures import principled as pr
from engine.integrator import lobe_choice
from engine.render import prepare_context
from engine.sampling import max3, uniform_sphere
from helpers import rays_from_inside
from engine.scene import Material


def _mixed_box():
    """The Cornell box with its glass sphere; the back wall and the block get layered
    lobes, the floor a transparent diffuse material (a pass lobe without set-up), the side
    walls stay diffuse-only."""
    s = cornell_box(8, 6, glass_sphere=True)
    s.add_material(Material("layered", (0.6, 0.3, 0.2), specular=1.0, roughness=0.4,
                            coat_weight=0.8, coat_roughness=0.1, sheen_weight=1.0))
    s.add_material(Material("rough_metal", (0.9, 0.7, 0.3), metallic=1.0, roughness=0.3))
    s.add_material(Material("see_through", (0.7, 0.7, 0.7), alpha=0.4))
    for mesh in s.meshes:
        name = getattr(mesh, "name", "")
        new = {"back": "layered", "block": "rough_metal", "floor": "see_through"}.get(name)
        if new is not None:
            mesh.materials = [new for _ in mesh.materials]
    return s


@pytest.fixture(scope="module")
def box_hits():
    ctx = prepare_context(_mixed_box(), RenderSettings(workers=1))
    rng = np.random.default_rng(7)
    lo, hi = ctx.geo.bounds
    n = 20000
    o = lo + (hi - lo) * (0.1 + 0.8 * rng.random((n, 3)))
    d = uniform_sphere(rng.random(n), rng.random(n))
    t, prim, u, v = ctx.accel.intersect(o, d)
    k = prim >= 0
    return ctx, surface_hit(ctx.geo, ctx.table, prim[k], u[k], v[k], d[k])


def _oracle(table, hit, tp, want_glossy):
    prm, alb = closures(table, hit)
    sel, q, p, psum = lobe_choice(alb, tp)
    glossy = np.zeros(len(q), bool)
    if want_glossy:
        pr.rough_reflection_rows(prm, glossy)
    wd = alb[:, 0]
    rows = np.nonzero((max3(wd) > 0) | glossy)[0]
    return prm, sel, q, p, psum, glossy, rows, wd[rows]


def _fused(table, hit, tp, want_glossy):
    n = len(hit.mat)
    # NaN where the kernel writes nothing (it takes np.empty in the render).
    prm = np.full((n, pr.N_PACK), np.nan)
    sel, p = np.full((n, pr.N_LOBES), np.nan), np.full((n, pr.N_LOBES - 1), np.nan)
    q, psum, glossy = np.empty(n), np.empty(n), np.empty(n, np.bool_)
    rows, wd = np.empty(n, np.int64), np.empty((n, 3))
    per_hit = hit.params is not None
    k = shade_lobes(hit.ns, hit.ng, hit.wo, hit.mat,
                    hit.params if per_hit else table.closure_params, per_hit, hit.base,
                    hit.front, np.ascontiguousarray(table.alpha, np.float64),
                    np.zeros(0) if hit.alpha is None else hit.alpha, tp, want_glossy, prm,
                    sel, q, p, psum, glossy, rows, wd, np.zeros(0), False)
    return prm, sel, q, p, psum, glossy, rows[:k], wd[:k]


@pytest.mark.parametrize("want_glossy", [True, False])
@pytest.mark.parametrize("variant", ["materials", "per_hit_params", "per_hit_alpha"])
def test_shade_lobes_equals_the_kernels_it_fuses(box_hits, variant, want_glossy):
    ctx, hit = box_hits
    rng = np.random.default_rng(13)
    n = len(hit.mat)
    fields = {}
    if variant == "per_hit_params":  # texture-driven inputs: a parameter row per hit
        params = np.take(ctx.table.closure_params, hit.mat, axis=0)
        params[:, pr.M_ROUGH] = rng.random(n)
        params[:, pr.M_TRANS] = np.where(rng.random(n) < 0.2, 1.0, 0.0)
        params[:, pr.M_SPEC] = np.where(rng.random(n) < 0.3, 0.0, params[:, pr.M_SPEC])
        fields["params"] = params
    elif variant == "per_hit_alpha":
        fields["alpha"] = np.where(rng.random(n) < 0.5, 1.0, rng.random(n))
    # Throughputs from 1 down to 1e-4: Russian roulette (q < 1) on many rows.
    tp = np.ascontiguousarray(10.0 ** (-4.0 * rng.random((n, 3))))
    want = _oracle(ctx.table, dataclasses.replace(hit, prm=None, lobe_albedo=None, **fields),
                   tp, want_glossy)
    got = _fused(ctx.table, dataclasses.replace(hit, prm=None, lobe_albedo=None, **fields),
                 tp, want_glossy)
    prm_w, sel_w, q_w, p_w, psum_w, glossy_w, rows_w, wd_w = want
    prm_g, sel_g, q_g, p_g, psum_g, glossy_g, rows_g, wd_g = got
    assert np.array_equal(q_g, q_w) and np.array_equal(psum_g, psum_w)
    assert np.array_equal(glossy_g, glossy_w)
    assert np.array_equal(rows_g, rows_w) and np.array_equal(wd_g, wd_w)
    pick = psum_w > 0  # the rows a continuation may pick
    assert np.array_equal(p_g[pick], p_w[pick]) and np.array_equal(sel_g[pick], sel_w[pick])
    # Diffuse-only rows are left unwritten unless the direct stage reads them.
    plain = ~np.any(np.take(fields.get("params", ctx.table.closure_params),
                            np.arange(n) if "params" in fields else hit.mat, axis=0)
                    [:, [pr.M_SHEEN_W, pr.M_COAT_W, pr.M_METALLIC, pr.M_TRANS, pr.M_SPEC]]
                    > 0.0, axis=1)
    assert plain.any() and (~plain).any()
    assert np.array_equal(prm_g[~plain], prm_w[~plain])
    if glossy_w.any():
        assert np.array_equal(prm_g, prm_w) and np.array_equal(sel_g, sel_w)
    else:
        assert np.isnan(prm_g[plain]).all()
    assert glossy_w.any() == want_glossy  # the rough lobes are there to find


def test_surface_hit_emission_without_emitters_is_zero_and_shared(box_hits):
    ctx, hit = box_hits
    assert not ctx.table.emission.any()
    Le = hit.emission
    assert Le.shape == (len(hit.mat), 3) and Le.strides[0] == 0 and not Le.any()
    # Subsets (the diffuse rows' views) copy zeros.
    assert not hit.take(np.arange(0, len(hit.mat), 7)).emission.any()


@pytest.mark.parametrize("start, n, spp, rw, x0, y0", [(0, 5000, 64, 40, 0, 0),
                                                       (131, 4000, 20, 7, 3, 5),
                                                       (777, 3001, 1, 13, 0, 2),
                                                       (5, 3000, 50, 11, 1, 1)])
def test_chunk_samples_equals_the_numpy_stage(start, n, spp, rw, x0, y0):
    # spp 64, 20, 1: a power-of-two grid side m (masks and shifts); 50: m = 7 (divisions).
    from engine.camerarays import chunk_samples
    m = max(1, int(np.sqrt(spp)))
    order = np.random.default_rng(0x5EED).permutation(m * m)
    jitter = np.random.default_rng(3).random((2, n))
    out = [np.empty(n, np.int64) for _ in range(4)] + [np.empty(n), np.empty(n)]
    chunk_samples(start, spp, m, order, jitter, rw, x0, y0, *out)
    # The numpy stage integrator._render_chunk ran before the kernel.
    sample = np.arange(start, start + n)
    pix, sub = sample // spp, sample % spp
    cell = order[sub % (m * m)]
    want = (pix, sub, x0 + pix % rw, y0 + pix // rw, (cell % m + jitter[0]) / m,
            (cell // m + jitter[1]) / m)
    for g, w in zip(out, want):
        assert g.dtype == w.dtype and np.array_equal(g, w)


def _plain_rays(ctx, n, seed):
    """n rays from inside the box in every direction, and their hits (prim, u, v, d)."""
    return rays_from_inside(ctx, n, seed)


@pytest.mark.parametrize("order", ["as_traced", "glossy_last"])
@pytest.mark.parametrize("want_glossy", [True, False])
def test_surface_hit_lobes_equals_surface_hit_then_shade_lobes(order, want_glossy):
    """bsdf.surface_hit_lobes (camerakernels.surface_lobes: hit_geometry, the turned
    shading normals and shade_lobes block by block) against surface_hit then shade_lobes,
    bitwise: every SurfaceHit field, and shade_lobes' outputs on the rows it writes.
    glossy_last: the diffuse-only hits first, so whole blocks have no glossy row and the
    unread rows of those blocks are filled in afterwards."""
    from engine.bsdf import plain_surfaces, surface_hit_lobes
    from engine.camerakernels import SURFACE_BLOCK
    ctx = prepare_context(_mixed_box(), RenderSettings(workers=1))
    assert plain_surfaces(ctx.table)
    prim, u, v, d = _plain_rays(ctx, 30000, 11)
    if order == "glossy_last":
        plain = ~np.any(np.take(ctx.table.closure_params, np.take(ctx.geo.material, prim),
                                axis=0)[:, [pr.M_SHEEN_W, pr.M_COAT_W, pr.M_METALLIC,
                                            pr.M_TRANS, pr.M_SPEC]] > 0.0, axis=1)
        k = np.argsort(~plain, kind="stable")
        prim, u, v, d = prim[k], u[k], v[k], d[k]
        assert plain.sum() > 3 * SURFACE_BLOCK
    n = len(prim)
    assert n > 8 * SURFACE_BLOCK
    rng = np.random.default_rng(5)
    tp = np.ascontiguousarray(10.0 ** (-4.0 * rng.random((n, 3))))
    hit = surface_hit(ctx.geo, ctx.table, prim, u, v, d)
    want = _fused(ctx.table, hit, tp, want_glossy)
    out = (np.full((n, pr.N_PACK), np.nan), np.full((n, pr.N_LOBES), np.nan),
           np.full((n, pr.N_LOBES - 1), np.nan), np.full(n, np.nan), np.full(n, np.nan),
           np.empty(n, np.bool_), np.empty(n, np.int64), np.empty((n, 3)))
    got_hit, k = surface_hit_lobes(ctx.geo, ctx.table, prim, u, v, d, tp, want_glossy, out)
    for name in ("p", "ng", "ns", "wo", "front", "mat", "base", "prim", "offset", "bary",
                 "emission"):
        a, b = getattr(got_hit, name), getattr(hit, name)
        assert a.dtype == b.dtype and np.array_equal(a, b), name
    assert got_hit.alpha is None and got_hit.params is None and got_hit.n_smooth is None
    prm_w, sel_w, q_w, p_w, psum_w, glossy_w, rows_w, wd_w = want
    prm_g, sel_g, p_g, q_g, psum_g, glossy_g, rows_g, wd_g = out
    assert got_hit.prm is prm_g
    assert k == len(rows_w)
    assert np.array_equal(rows_g[:k], rows_w) and np.array_equal(wd_g[:k], wd_w)
    assert np.array_equal(q_g, q_w) and np.array_equal(psum_g, psum_w)
    assert np.array_equal(glossy_g, glossy_w)
    pick = psum_w > 0
    assert np.array_equal(p_g[pick], p_w[pick]), "p"
    # NaN in both where neither writes (diffuse-only rows without a glossy row anywhere).
    assert np.array_equal(prm_g, prm_w, equal_nan=True)
    assert np.array_equal(sel_g[pick], sel_w[pick])
    if glossy_w.any():
        assert np.array_equal(sel_g, sel_w) and not np.isnan(prm_g).any()
    assert glossy_w.any() == want_glossy


@pytest.mark.parametrize("n, start", [(1, 0), (7, 1), (4099, 3), (100000, 0)])
def test_view_depth_equals_the_einsum_dot(n, start):
    """camerakernels.view_depth against sampling.dot(p - cam_pos, forward) (np.einsum),
    bitwise, on unaligned slices and sizes around numpy's SIMD blocks."""
    from engine.camerakernels import view_depth
    from engine.sampling import dot
    rng = np.random.default_rng(n)
    p = (rng.normal(size=(n + start, 3)) * np.array([3.0, 1e-3, 50.0]))[start:]
    p = np.ascontiguousarray(p)
    cam = rng.normal(size=3)
    forward = rng.normal(size=3)
    forward /= np.linalg.norm(forward)
    depth = np.empty(n)
    view_depth(p, cam, forward, depth)
    assert np.array_equal(depth, dot(p - cam, forward))
