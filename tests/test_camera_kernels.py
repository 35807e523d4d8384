"""The camera pass's shading kernels (engine/camerakernels.py) against the numpy stages
they replaced, kept here as oracles: surface data at hits and the continuation's lobe
choice are bitwise the same, on the Cornell box (smooth glass sphere, blocks) and on
tilted, far, huge and sliver triangles."""
import numpy as np
import pytest

from engine import RenderSettings
from engine.api import cornell_box
from engine.bsdf import LOBE_NAMES, SPEC_LOBES, closures, surface_hit
from engine.geometry import prepare
from engine.integrator import lobe_choice
from engine.render import prepare_context
from engine.sampling import dot, max3, uniform_sphere
from helpers import rays_from_inside
from engine.scene import Material, Mesh, Scene


def _surface_hit_numpy(geo, table, prim, u, v, d):
    """The numpy stage bsdf.surface_hit replaced (geometry and base colour; textures and
    normal maps run the same numpy code after the kernel)."""
    p = geo.hit_points(prim, u, v)
    ng = np.take(geo.ng, prim, axis=0)
    front = dot(d, ng) < 0.0
    sign = np.where(front, 1.0, -1.0)[:, None]
    ng = ng * sign
    ns = geo.shading_normals(prim, u, v) * sign
    wo = -d
    bad = dot(ns, wo) <= 1e-6
    if bad.any():
        ns[bad] = ng[bad]
    base = np.take(table.base_color, np.take(geo.material, prim), axis=0)
    return dict(p=p, ng=ng, ns=ns, front=front, mat=np.take(geo.material, prim), base=base,
                offset=geo.origin_offset(prim, u, v, p, ng))


def _lobe_choice_numpy(w, tp):
    """The numpy lobe_choice the kernel choose_lobes replaced."""
    cols = [w[k] for k in SPEC_LOBES]
    p = np.stack([max3(c) for c in cols], axis=1)
    psum = p.sum(axis=1)
    wsum = cols[0]
    for c in cols[1:]:
        wsum = wsum + c
    q = np.clip(10.0 * max3(tp * wsum), 0.0, 1.0)
    sel = np.zeros((len(p), len(SPEC_LOBES) + 1))
    ok = psum > 0
    sel[ok, 1:] = p[ok] / psum[ok, None] * q[ok, None]
    return sel, q, p, psum


def _box_hits(n=20000, seed=3):
    ctx = prepare_context(cornell_box(8, 6, glass_sphere=True), RenderSettings(workers=1))
    return (ctx, *rays_from_inside(ctx, n, seed))


def _tris(kind, rng, T=300):
    if kind == "tilted":
        return rng.normal(size=(T, 3, 3))
    if kind == "far":
        return rng.normal(size=(T, 1, 3)) * 1e4 + rng.normal(size=(T, 3, 3)) * 0.01
    if kind == "huge":
        return rng.normal(size=(T, 1, 3)) * 1e3 + rng.normal(size=(T, 3, 3)) * 1e5
    a = rng.normal(size=(T, 3)) * 10  # slivers 100 m long, 1 mm wide
    b = a + rng.normal(size=(T, 3)) * 100
    c = a + rng.normal(size=(T, 3)) * 1e-3 + (b - a) * rng.random((T, 1))
    return np.stack([a, b, c], axis=1)


def _assert_same(hit, ref):
    for name, want in ref.items():
        got = getattr(hit, name)
        assert got.shape == want.shape, name
        assert np.array_equal(got, want.astype(got.dtype)), name


def test_surface_hit_kernel_equals_numpy_stage_in_the_box():
    ctx, prim, u, v, d = _box_hits()
    assert ctx.geo.smooth.any() and len(prim) > 15000
    hit = surface_hit(ctx.geo, ctx.table, prim, u, v, d)
    _assert_same(hit, _surface_hit_numpy(ctx.geo, ctx.table, prim, u, v, d))
    assert np.array_equal(hit.wo, -d)
    assert hit.front.any() and not hit.front.all()  # glass sphere: hits from inside too


@pytest.mark.parametrize("kind", ["tilted", "far", "huge", "sliver"])
def test_surface_hit_kernel_equals_numpy_stage_on_hard_triangles(kind):
    rng = np.random.default_rng(11)
    tris = _tris(kind, rng)
    sc = Scene(width=4, height=4)
    sc.materials["default"] = Material("default", (0.5, 0.25, 0.125))
    sc.meshes.append(Mesh("m", tris.reshape(-1, 3), np.arange(tris.size // 3).reshape(-1, 3)))
    geo, table = prepare(sc)
    n = 20000
    prim = rng.integers(0, geo.count, n)
    b = rng.random((n, 2))
    b = np.where(b.sum(axis=1, keepdims=True) > 1, 1 - b, b)
    d = uniform_sphere(rng.random(n), rng.random(n))
    hit = surface_hit(geo, table, prim, b[:, 0], b[:, 1], d)
    ref = _surface_hit_numpy(geo, table, prim, b[:, 0], b[:, 1], d)
    _assert_same(hit, ref)
    assert np.all(hit.offset > 0)


def test_lobe_choice_kernel_equals_numpy_stage():
    ctx, prim, u, v, d = _box_hits(8000, seed=5)
    hit = surface_hit(ctx.geo, ctx.table, prim, u, v, d)
    _, alb = closures(ctx.table, hit)
    w = {name: alb[:, i] for i, name in enumerate(LOBE_NAMES)}
    rng = np.random.default_rng(1)
    tp = rng.random((len(prim), 3)) * np.where(rng.random((len(prim), 1)) < 0.3, 0.01, 1.0)
    got = lobe_choice(alb, tp)
    want = _lobe_choice_numpy(w, tp)
    for g, r in zip(got, want):
        assert np.array_equal(g, r)
    q = got[1]
    assert (q < 1).any() and (q == 1).any() and (got[3] > 0).any() and (got[3] == 0).any()


def _continue_specular_numpy(ctx, hit, tp, rng, ray_cls, choice):
    """The numpy continuation the kernels pick_lobes / continue_lobes replaced (with
    bsdf.sample_specular, the numpy stage's sampler)."""
    from engine.bsdf import GLASS_R, GLASS_T, sample_specular
    from engine.closures import principled as pr
    from engine.visibility import continued_class
    sel, q, p, psum = choice
    go = (psum > 0) & (rng.random(len(p)) < q)
    idx = np.nonzero(go)[0]
    cdf = np.cumsum(p[idx] / psum[idx, None], axis=1)
    lobe = np.minimum(np.count_nonzero(rng.random(len(idx))[:, None] >= cdf, axis=1),
                      len(SPEC_LOBES) - 1)
    glass = (lobe == GLASS_R) | (lobe == GLASS_T)
    p_sel = np.where(glass, p[idx, GLASS_R] + p[idx, GLASS_T], p[idx, lobe])
    prob = p_sel / psum[idx] * q[idx]
    sub = hit.take(idx)
    nd, valid, transmitted, weight = sample_specular(ctx.table, sub, lobe, rng)
    lobe = np.where(glass, np.where(transmitted, GLASS_T, GLASS_R), lobe)
    new_tp = tp[idx] * weight / np.maximum(prob, 1e-300)[:, None]
    keep = valid & np.isfinite(new_tp[:, 0] + new_tp[:, 1] + new_tp[:, 2]) & (max3(new_tp) > 0)
    o = sub.clear(keep, nd[keep])
    inc = ray_cls if np.ndim(ray_cls) == 0 else np.asarray(ray_cls)[idx]
    new_cls = continued_class(lobe, inc)[keep]
    pdf = np.full(len(idx), np.inf)
    prm = np.ascontiguousarray(sub.prm)
    rough = pr.lobe_is_rough(prm, (lobe + 1).astype(np.int64)) & ~transmitted & valid
    r = np.nonzero(rough)[0]
    if len(r):
        pb = np.empty(len(r))
        pr.bsdf_pdf_many(np.ascontiguousarray(prm[r]), np.ascontiguousarray(sel[idx[r]]),
                         np.ascontiguousarray(sub.ns[r], np.float64),
                         np.ascontiguousarray(sub.wo[r], np.float64),
                         np.ascontiguousarray(nd[r], np.float64), pb)
        pdf[r] = pb
    # Rough glass's refraction: the glass lobe's choice x its refraction pdf
    # (principled.transmission_pdf; inf where it has no density).
    through = pr.lobe_is_rough(prm, (lobe + 1).astype(np.int64)) & transmitted & valid
    r = np.nonzero(through)[0]
    if len(r):
        ev = np.empty((len(r), 4))
        pr.eval_transmission_many(np.ascontiguousarray(prm[r]),
                                  np.ascontiguousarray(sub.ns[r], np.float64),
                                  np.ascontiguousarray(sub.wo[r], np.float64),
                                  np.ascontiguousarray(nd[r], np.float64), ev)
        s_glass = sel[idx[r], pr.L_GLASS_R] + sel[idx[r], pr.L_GLASS_T]
        dense = ((np.abs(prm[r, pr.P_GLASS_ETA] - 1.0) >= 1e-4)
                 & np.any(prm[r, pr.P_GLASS_TW:pr.P_GLASS_TW + 3] > 0, axis=1))
        pdf[r] = np.where(dense, s_glass * ev[:, 3], np.inf)
    return idx[keep], o, nd[keep], new_tp[keep], new_cls, pdf[keep]


def _every_lobe_box():
    """The Cornell box with materials that have every lobe: metal, rough glass, coat,
    sheen, alpha (pass) and specular."""
    s = cornell_box(8, 6, glass_sphere=True)
    used = dict.fromkeys(name for m in s.meshes for name in m.materials)
    mats = [s.materials[name] for name in used]
    kinds = [dict(specular=1.0, roughness=0.4, coat_weight=0.8, coat_roughness=0.1,
                  sheen_weight=1.0), dict(metallic=1.0, roughness=0.3, alpha=0.4),
             dict(transmission=1.0, roughness=0.2), dict(roughness=0.0, metallic=1.0)]
    assert len(mats) >= len(kinds)
    for m, kw in zip(mats, kinds):
        for k, val in kw.items():
            setattr(m, k, val)
    return s


@pytest.mark.parametrize("ray_cls", ["scalar", "per_ray"])
def test_continuation_kernels_equal_numpy_stage(ray_cls):
    from engine.integrator import continue_specular
    from engine.visibility import CAMERA, DIFFUSE, GLOSSY
    ctx = prepare_context(_every_lobe_box(), RenderSettings(workers=1))
    rng = np.random.default_rng(9)
    lo, hi = ctx.geo.bounds
    n = 20000
    o = lo + (hi - lo) * (0.1 + 0.8 * rng.random((n, 3)))
    d = uniform_sphere(rng.random(n), rng.random(n))
    t, prim, u, v = ctx.accel.intersect(o, d)
    k = prim >= 0
    hit = surface_hit(ctx.geo, ctx.table, prim[k], u[k], v[k], d[k])
    _, alb = closures(ctx.table, hit)
    m = len(hit.p)
    tp = rng.random((m, 3)) * np.where(rng.random((m, 1)) < 0.3, 0.01, 1.0)
    choice = lobe_choice(alb, tp)
    cls = (CAMERA if ray_cls == "scalar"
           else rng.choice(np.array([CAMERA, DIFFUSE, GLOSSY]), m))
    got = continue_specular(ctx, hit, tp, np.random.default_rng(2), cls, choice=choice,
                            want_pdf=True)
    want = _continue_specular_numpy(ctx, hit, tp, np.random.default_rng(2), cls, choice)
    for name, g, w in zip(("rows", "o", "d", "tp", "cls", "pdf"), got, want):
        assert g.shape == w.shape and np.array_equal(g, w), name
    assert np.count_nonzero((choice[0][:, 1:] > 0.05).any(axis=0)) >= 6  # lobes exercised
    assert np.isfinite(got[5]).any() and np.isinf(got[5]).any()
    short = continue_specular(ctx, hit, tp, np.random.default_rng(2), cls, choice=choice)
    assert len(short) == 5 and all(np.array_equal(a, b) for a, b in zip(short, got))


def test_gather_rays_kernel_equals_numpy_stage():
    from engine.camerakernels import gather_rays
    from engine.sampling import cosine_hemisphere, to_world
    ctx, prim, u, v, d = _box_hits(20000, seed=8)
    hit = surface_hit(ctx.geo, ctx.table, prim, u, v, d)
    rng = np.random.default_rng(4)
    u1, u2 = rng.random(len(prim)), rng.random(len(prim))
    # The numpy stage gather_indirect used.
    dn = to_world(cosine_hemisphere(u1, u2), hit.ns)
    idx = np.nonzero(dot(dn, hit.ng) > 0)[0]
    o_ref = hit.clear(idx, dn[idx])
    n = len(prim)
    rows, o, dk = np.empty(n, np.int64), np.empty((n, 3)), np.empty((n, 3))
    k = gather_rays(u1, u2, hit.ns, hit.ng, hit.p, hit.offset, rows, o, dk)
    assert 0 < k < n  # smooth normals: some rays fall below ng
    assert np.array_equal(rows[:k], idx)
    assert np.array_equal(dk[:k], dn[idx]) and np.array_equal(o[:k], o_ref)
