"""The camera path's per-bounce glue in kernels (issue 13, sixth slice) against the numpy
stages they replaced, kept here as oracles: the closures' set-up (camerakernels.
hit_closures), the compaction of the paths after an Embree call (keep_path_hits), the
film's scatter-add (film_add), and the row views that replaced copied SurfaceHits
(bsdf.HitRows). All bitwise."""
import dataclasses

import numpy as np
import pytest

from engine import RenderSettings
from engine.api import cornell_box
from engine.bsdf import HitRows, SurfaceHit, _hit_alpha, closures, surface_hit
from engine.camerakernels import film_add, keep_path_hits
from engine.closures import principled as pr
from engine.integrator import Accumulator
from engine.render import prepare_context
from engine.sampling import uniform_sphere


def _closures_numpy(table, hit):
    """The numpy set-up bsdf.closures ran around principled.setup before hit_closures."""
    cos_o = np.einsum("ij,ij->i", hit.ns, hit.wo)
    local = np.zeros((len(cos_o), 3))
    pr.glossy_normals(np.ascontiguousarray(hit.ns, np.float64),
                      np.ascontiguousarray(hit.ng, np.float64),
                      np.ascontiguousarray(hit.wo, np.float64), local, cos_o)
    if hit.params is None:
        params, rows = table.closure_params, hit.mat
    else:
        params, rows = hit.params, np.arange(len(hit.mat))
    # Glass, rough or smooth, takes the raised normal as the glossy lobes do
    # (principled.raised_rough_glass).
    prm, alb = pr.setup_np(params, rows, hit.base, cos_o, hit.front, _hit_alpha(table, hit))
    prm[:, pr.P_GN:pr.P_GN + 3] = local
    return prm, alb


def _every_lobe_box():
    """The Cornell box (smooth glass sphere) with materials that have every lobe."""
    s = cornell_box(8, 6, glass_sphere=True)
    used = dict.fromkeys(name for m in s.meshes for name in m.materials)
    mats = [s.materials[name] for name in used]
    kinds = [dict(specular=1.0, roughness=0.4, coat_weight=0.8, coat_roughness=0.1,
                  sheen_weight=1.0), dict(metallic=1.0, roughness=0.3, alpha=0.4),
             dict(transmission=1.0, roughness=0.2), dict(roughness=0.0, metallic=1.0)]
    for m, kw in zip(mats, kinds):
        for k, val in kw.items():
            setattr(m, k, val)
    return s


@pytest.fixture(scope="module")
def box_hits():
    ctx = prepare_context(_every_lobe_box(), RenderSettings(workers=1))
    rng = np.random.default_rng(5)
    lo, hi = ctx.geo.bounds
    n = 20000
    o = lo + (hi - lo) * (0.1 + 0.8 * rng.random((n, 3)))
    d = uniform_sphere(rng.random(n), rng.random(n))
    t, prim, u, v = ctx.accel.intersect(o, d)
    k = prim >= 0
    return ctx, surface_hit(ctx.geo, ctx.table, prim[k], u[k], v[k], d[k])


def _fresh(hit, **fields):
    return dataclasses.replace(hit, prm=None, lobe_albedo=None, **fields)


@pytest.mark.parametrize("variant", ["materials", "per_hit_params", "per_hit_alpha"])
def test_hit_closures_equal_numpy_set_up(box_hits, variant):
    ctx, hit = box_hits
    rng = np.random.default_rng(11)
    n = len(hit.mat)
    fields = {}
    if variant == "per_hit_params":  # texture-driven inputs: a parameter row per hit
        params = np.take(ctx.table.closure_params, hit.mat, axis=0)
        params[:, pr.M_ROUGH] = rng.random(n)
        params[:, pr.M_TRANS] = np.where(rng.random(n) < 0.3, 1.0, 0.0)
        fields["params"] = params
    elif variant == "per_hit_alpha":
        fields["alpha"] = rng.random(n)
    got = closures(ctx.table, _fresh(hit, **fields))
    want = _closures_numpy(ctx.table, _fresh(hit, **fields))
    for g, w in zip(got, want):
        assert g.shape == w.shape and np.array_equal(g, w)
    if variant == "per_hit_params":
        # Non-glass rows of the smooth sphere: the glossy normal was raised somewhere.
        assert np.any(got[0][:, pr.P_GN:pr.P_GN + 3] != 0.0)


def test_hit_rows_view_equals_copied_take(box_hits):
    ctx, hit = box_hits
    full = _fresh(hit)
    closures(ctx.table, full)
    rows = np.random.default_rng(2).choice(len(full.mat), 3000, replace=False)
    view = full.take(rows)
    assert isinstance(view, HitRows)
    assert view.__dict__.keys() == {"_source", "_rows"}  # nothing copied yet
    for name in SurfaceHit.__dataclass_fields__:
        src = getattr(full, name)
        got = getattr(view, name)
        if src is None:
            assert got is None, name
        else:
            assert np.array_equal(got, np.take(src, rows, axis=0)), name
    # A view of a view, and a field assigned on the view (the closures' cache).
    inner = rows[::3]
    nested = view.take(np.arange(0, len(rows), 3))
    assert np.array_equal(nested.p, np.take(full.p, inner, axis=0))
    lazy = _fresh(hit).take(rows)
    prm, alb = closures(ctx.table, lazy)
    assert lazy.prm is prm and np.array_equal(prm, np.take(full.prm, rows, axis=0))
    assert np.array_equal(alb, np.take(full.lobe_albedo, rows, axis=0))


def test_keep_path_hits_compacts_like_boolean_indexing():
    rng = np.random.default_rng(4)
    n = 5000
    prim = rng.integers(-3, 50, n)
    o, d, tp = rng.random((n, 3)), rng.random((n, 3)), rng.random((n, 3))
    pix, sid, cls = rng.integers(0, 99, n), rng.integers(0, 64, n), rng.integers(1, 9, n)
    u, v, t, trav = rng.random(n), rng.random(n), rng.random(n) * 7, rng.random(n) * 3
    pdf = np.where(rng.random(n) < 0.5, np.inf, rng.random(n))
    got = keep_path_hits(prim, o, d, tp, pix, u, v, t, sid, trav, cls, pdf)
    m = prim >= 0
    want = (np.nonzero(m)[0], o[m], d[m], tp[m], pix[m], prim[m], u[m], v[m], t[m], sid[m],
            trav[m] + t[m], cls[m], pdf[m])
    assert 0 < m.sum() < n
    for g, w in zip(got, want):
        assert g.dtype == w.dtype and np.array_equal(g, w)
    none = keep_path_hits(np.full(4, -1), o[:4], d[:4], tp[:4], pix[:4], u[:4], v[:4], t[:4],
                          sid[:4], trav[:4], cls[:4], pdf[:4])
    assert all(len(a) == 0 for a in none)


def _bincount_add(buf, lo, pix, rgb):
    """The Accumulator.add film_add replaced."""
    for c in range(3):
        buf[:, c] += np.bincount(pix - lo, weights=rgb[:, c], minlength=len(buf))


def test_film_add_equals_bincount_accumulation():
    rng = np.random.default_rng(8)
    n, lo, npix = 4000, 37, 120
    pix = lo + rng.integers(0, npix, n)  # many rows per pixel: the summation order counts
    tp = rng.random((n, 3)) * np.exp(rng.normal(size=(n, 1)) * 4)
    rows = np.sort(rng.choice(n, 1500, replace=False))
    rgb = rng.random((len(rows), 3)) * np.exp(rng.normal(size=(len(rows), 1)) * 4)
    start = rng.random((npix, 3))
    want, got = start.copy(), start.copy()
    _bincount_add(want, lo, pix[rows], tp[rows] * rgb)
    film_add(got, lo, pix, rows, tp, rgb)
    assert np.array_equal(got, want)
    full = rng.random((n, 3))
    _bincount_add(want, lo, pix, tp * full)
    film_add(got, lo, pix, np.zeros(0, np.int64), tp, full)
    assert np.array_equal(got, want)
    _bincount_add(want, lo, pix, full)
    film_add(got, lo, pix, np.zeros(0, np.int64), np.zeros((0, 3)), full)
    assert np.array_equal(got, want)
    acc = Accumulator(npix, lo)
    acc.buf["direct"][:] = start
    ref = start.copy()
    acc.add("direct", pix, rgb, tp, rows)
    _bincount_add(ref, lo, pix[rows], tp[rows] * rgb)
    acc.add("direct", pix[rows], rgb)
    _bincount_add(ref, lo, pix[rows], rgb)
    assert np.array_equal(acc.buf["direct"], ref)


def _uv_numpy(sampler, dim, scrambled):
    """The numpy StratifiedSampler._uv that _stratified_uv replaced."""
    n = len(sampler.sub)
    cells = sampler.m * sampler.m
    if scrambled:
        x = (sampler.pix.astype(np.uint64) * np.uint64(0x9E3779B97F4A7C15)
             + np.uint64((dim + 1) * 0xBF58476D1CE4E5B9 % (1 << 64))
             + np.uint64(sampler.salt * 0xD6E8FEB86659FD93 % (1 << 64)))
        x ^= x >> np.uint64(31)
        x *= np.uint64(0x94D049BB133111EB)
        x ^= x >> np.uint64(29)
        shift = x % np.uint64(cells)
    else:
        shift = (sampler.pix.astype(np.uint64) * np.uint64(2654435761)
                 + np.uint64(dim * 40503 + 12345)) % np.uint64(cells)
    cell = ((sampler.sub.astype(np.uint64) + shift) % np.uint64(cells)).astype(np.int64)
    u1 = (cell % sampler.m + sampler.rng.random(n)) / sampler.m
    u2 = (cell // sampler.m + sampler.rng.random(n)) / sampler.m
    rest = sampler.sub >= sampler.full
    if rest.any():
        u1[rest] = sampler.rng.random(int(rest.sum()))
        u2[rest] = sampler.rng.random(int(rest.sum()))
    return u1, u2


@pytest.mark.parametrize("spp", [16, 20, 128])
@pytest.mark.parametrize("scrambled", [False, True])
def test_stratified_uv_kernel_equals_numpy_stage(spp, scrambled):
    from engine.sampling import SampleDimensions, StratifiedSampler
    sample = np.arange(3 * spp, 3 * spp + 4000)
    pix, sub = sample // spp, sample % spp
    dims = SampleDimensions([(("gather", 0), 1), (("bsdf",), None)])
    for key in dims.numbers():
        a = StratifiedSampler(sub, pix, spp, np.random.default_rng(3), dims, salt=2**40 + 7)
        b = StratifiedSampler(sub, pix, spp, np.random.default_rng(3), dims, salt=2**40 + 7)
        got = a.uv(key, scrambled=scrambled)
        want = _uv_numpy(b, dims[key], scrambled)
        assert all(np.array_equal(g, w) for g, w in zip(got, want))
        # The generator advanced alike (the next stage's numbers stay the same).
        assert a.rng.random() == b.rng.random()
