"""hotspots53's compiled stages against the numpy stages they replaced, kept here as
oracles (docs/performance.md, hotspots53): camerakernels.glossy_unguarded_rows
(turnedglossy.camera_unguarded's test) marks exactly the rows the numpy test marked, near
its threshold too; camerakernels.diffuse_pdf_weights (glossysplit.DiffusePdf's lobe
weights) gives numpy's values, NaN and infinities included, and numpy's bits for the sums,
the diffuse weight and the Lambert rows (a lobe weight of zero may carry the other sign:
numpy's maximum of 0.0 and -0.0 is its second argument; every reader tests w > 0.0 and
psum's sum starts at 0.0, so no result bit depends on it); and
camerakernels.bsdf_pdf_rows (DiffusePdf.pdf) gives principled.bsdf_pdf_many's bits on
gathered rows. percost56's photonvisibility.clamp_weights against the numpy stage it replaced
(Clamp Indirect's per-photon weights) and _rejected_lists' mask against the rejected pairs
it replaced."""
from types import SimpleNamespace

import numpy as np

from engine import turnedglossy
from engine.camerakernels import (bsdf_pdf_rows, diffuse_pdf_weights,
                                  glossy_unguarded_rows)
from engine.closures import principled as pr
from engine.geometry import Geometry, _ng_rows
from engine.sampling import normalize, uniform_sphere


def _unguarded_numpy(geo, prim, u, v, d, rows, eps=1e-6):
    """The numpy stage of turnedglossy.camera_unguarded the kernel replaced, on rows."""
    p = prim[rows]
    ns = Geometry.shading_normals(geo, p, u[rows], v[rows])
    ng = _ng_rows(geo, p)
    dd = d[rows]
    side = np.where(np.einsum("ij,ij->i", dd, ng) < 0.0, 1.0, -1.0)
    below = ((side * np.einsum("ij,ij->i", ns, -dd) <= eps)
             & (np.einsum("ij,ij->i", ns, ng) > 0.0))
    out = np.zeros(len(prim), bool)
    out[rows[below]] = True
    return out


def _triangles(rng, t):
    """Random triangle tables (t triangles): edges, and float32 corner normals leaning
    off the face, some zero (degenerate: the face's normal) or NaN."""
    e1, e2 = rng.normal(size=(2, t, 3))
    e1[:5] = 0.0  # degenerate triangles (ng 0)
    cn = (np.cross(e1, e2)[:, None, :] / 3.0 + rng.normal(size=(t, 3, 3))).astype(np.float32)
    cn[5:15] = 0.0
    cn[15:20, 1] = np.nan
    return SimpleNamespace(e1=e1, e2=e2, corner_normals=cn)


def test_glossy_unguarded_kernel_marks_the_numpy_stages_rows():
    rng = np.random.default_rng(53)
    t, n = 500, 200_000
    geo = _triangles(rng, t)
    geo.ng = _ng_rows(geo, np.arange(t))
    prim = rng.integers(0, t, n).astype(np.int64)
    b = rng.random((n, 2))
    b = np.where(b.sum(axis=1, keepdims=True) > 1.0, 1.0 - b, b)
    u, v = b[:, 0].copy(), b[:, 1].copy()
    d = uniform_sphere(rng.random(n), rng.random(n))
    # Half the rays graze the shading normal: ns . wo within a few 1e-6 of the guard's
    # threshold, on either side of the face.
    ns = Geometry.shading_normals(geo, prim, u, v)
    half = np.arange(n) % 2 == 0
    tangent = normalize(np.cross(ns, rng.normal(size=(n, 3))))
    lean = rng.uniform(-3e-6, 4e-6, n)[:, None]
    d[half] = normalize(-(lean * ns + tangent))[half]
    rows = np.flatnonzero(rng.random(n) < 0.9)  # (the rows on the test's materials)
    want = _unguarded_numpy(geo, prim, u, v, d, rows)
    got = np.zeros(n, bool)
    count = glossy_unguarded_rows(rows, prim, u, v, d, geo.e1, geo.e2, geo.corner_normals,
                                  turnedglossy._GUARD_EPS, got)
    np.testing.assert_array_equal(got, want)
    assert count == want.sum()
    graze = want[half]
    assert graze.any() and not graze.all()  # (the threshold is crossed both ways)


def _weights_numpy(albedo):
    """The numpy stage of DiffusePdf.__init__ the kernel replaced: sel, psum, wd, lambert."""
    a = albedo[:, 1:, :]
    p = np.maximum(np.maximum(a[:, :, 0], a[:, :, 1]), a[:, :, 2])
    sel = np.zeros((len(p), pr.N_LOBES))
    sel[:, 1:] = p
    psum = p.sum(axis=1)
    wd = np.maximum(albedo[:, pr.L_DIFFUSE, :].mean(axis=1), 0.0)
    others = [j for j in range(1, pr.N_LOBES) if j != pr.L_PASS]
    lambert = ~(sel[:, others] > 0.0).any(axis=1)
    return sel, psum, wd, lambert


def _same_bits(got, want):
    """Equal values, the same zero signs, NaN where NaN."""
    np.testing.assert_array_equal(got, want)
    np.testing.assert_array_equal(np.signbit(got), np.signbit(want))


def test_diffuse_pdf_weights_kernel_gives_numpys_bits():
    # The kernel writes numpy's pairwise sum of the 8 non-diffuse lobes out by hand: a
    # lobe added to the table must be added there (review of hotspots53).
    assert pr.N_LOBES == 9, "camerakernels.diffuse_pdf_weights sums exactly 8 lobes"
    rng = np.random.default_rng(530)
    n = 100_000
    albedo = rng.random((n, pr.N_LOBES, 3)) * rng.choice([1e-12, 1.0, 1e12], (n, 1, 1))
    for value, share in ((0.0, 0.3), (-0.0, 0.2), (-1e-3, 0.02), (np.nan, 0.002),
                         (np.inf, 0.002), (-np.inf, 0.002)):
        albedo[rng.random(albedo.shape) < share] = value
    albedo[:200, 2:] = 0.0    # Lambert rows (diffuse and pass lobes alone)
    albedo[200:300] = -0.0    # every weight -0.0
    want = _weights_numpy(albedo)
    got = (np.empty((n, pr.N_LOBES)), np.empty(n), np.empty(n), np.empty(n, bool))
    with np.errstate(invalid="ignore"):
        diffuse_pdf_weights(albedo, *got)
    np.testing.assert_array_equal(got[0], want[0])  # (values: zeros of either sign)
    for g, w in zip(got[1:], want[1:]):
        _same_bits(g, w)
    assert got[3][:200].all() and not got[3].all()
    # The zero weights' sign changes no pdf (principled.bsdf_pdf reads sel only through
    # w > 0.0): the numpy weights' and the kernel's give the same bits.
    prm, _ = pr.setup_np(np.full((1, pr.N_MAT), 0.5), np.zeros(300, np.int64),
                         np.full((300, 3), 0.5), np.full(300, 0.8), np.ones(300, bool))
    ns = np.tile([0.0, 0.0, 1.0], (300, 1))
    wo = normalize(np.tile([0.3, 0.0, 1.0], (300, 1)))
    wi = normalize(np.tile([-0.2, 0.1, 1.0], (300, 1)))
    pdfs = []
    for sel in (got[0][200:500], want[0][200:500]):
        out = np.empty(300)
        pr.bsdf_pdf_many(prm, np.ascontiguousarray(sel), ns, wo, wi, out)
        pdfs.append(out)
    _same_bits(pdfs[0], pdfs[1])


def _random_principled(rng, m, n):
    """(mat (n,), prm): n hits of m Principled materials with every lobe, their weights
    drawn from rng (principled.setup_np's set-up of them)."""
    params = np.zeros((m, pr.N_MAT))
    params[:, [pr.M_ALPHA, pr.M_IOR, pr.M_LEVEL, pr.M_COAT_IOR, pr.M_MULTI]] = (
        1.0, 1.5, 0.5, 1.5, 1.0)
    for col in (pr.M_METALLIC, pr.M_ROUGH, pr.M_TRANS, pr.M_SPEC, pr.M_COAT_W,
                pr.M_COAT_ROUGH, pr.M_SHEEN_W, pr.M_SHEEN_ROUGH, pr.M_TL):
        params[:, col] = rng.random(m) * (rng.random(m) < 0.7)
    for col in (pr.M_STINT, pr.M_CTINT, pr.M_SHEEN_TINT, pr.M_TTINT):
        params[:, col:col + 3] = 1.0
    mat = rng.integers(0, m, n)
    prm, _ = pr.setup_np(params, mat, rng.random((n, 3)), rng.uniform(0.05, 1.0, n),
                         rng.random(n) < 0.8)
    return mat, prm


def test_bsdf_pdf_rows_kernel_gives_bsdf_pdf_manys_bits():
    """Hits of materials with every lobe (principled's warm-up material, its weights
    varied), pairs drawn with repeated rows: the in-place reads give the gathered rows'
    pdfs bit for bit."""
    rng = np.random.default_rng(5300)
    m, n, k = 16, 3000, 40_000
    mat, prm = _random_principled(rng, m, n)
    sel = rng.random((n, pr.N_LOBES)) * (rng.random((n, pr.N_LOBES)) < 0.6)
    ns = uniform_sphere(rng.random(n), rng.random(n))
    wo = normalize(ns + 0.9 * uniform_sphere(rng.random(n), rng.random(n)))
    rows = rng.integers(0, n, k).astype(np.int64)
    nsr = np.take(ns, rows, axis=0)
    wi = normalize(nsr + uniform_sphere(rng.random(k), rng.random(k)))
    want = np.empty(k)
    pr.bsdf_pdf_many(np.take(prm, rows, axis=0), np.take(sel, rows, axis=0), nsr,
                     np.take(wo, rows, axis=0), wi, want)
    got = np.empty(k)
    bsdf_pdf_rows(prm, sel, rows, nsr, wo, wi, got)
    _same_bits(got, want)
    assert (want > 0).mean() > 0.5


def _reject_numpy(dp, pmap, sel, rows, photons):
    """The numpy stage of DiffusePdf.reject_for's block the kernel replaced (percost54)."""
    from engine.photonlayout import vectors
    stored = pmap.photons.blur_pdf
    r = np.take(sel, rows)
    out = np.ones(len(r), bool)
    test = np.flatnonzero(np.take(dp.largest, r) >= dp.fg)
    pid = np.take(photons, test)
    wi = -vectors(pmap.photons.direction, pid)
    wi /= np.maximum(np.linalg.norm(wi, axis=1), 1e-300)[:, None]
    pd = dp.pdf(r[test], wi)
    if stored is not None:
        pd = np.minimum(pd, np.take(stored, pid).astype(np.float64))
    out[test] = ~(pd >= dp.fg)
    return out, pd


def test_diffuse_reject_pairs_kernel_rejects_the_numpy_stages_pairs():
    """camerakernels.diffuse_reject_pairs (DiffusePdf.reject_for, percost54) against the
    numpy stage: hits of every lobe, plain and Lambert rows, rows whose bound is below
    Filter Glossy, zero-length and NaN photon directions, NaN and infinite stored and
    camera min pdfs, with and without them, the directions stored as float32 or as
    octahedral codes (read in place since percost55); Filter Glossy set to pdfs the numpy
    stage computed, so a pair exactly at the threshold flips with any change of its
    pdf's bits."""
    from engine.glossysplit import DiffusePdf
    rng = np.random.default_rng(5400)
    m, n, k, p = 16, 2000, 30_000, 5000
    mat, prm = _random_principled(rng, m, n)
    albedo = rng.random((n, pr.N_LOBES, 3)) * (rng.random((n, pr.N_LOBES, 1)) < 0.6)
    albedo[:300, 2:] = 0.0  # Lambert rows
    albedo[:100, pr.L_PASS] = 0.0  # plain rows (cos / pi)
    albedo[300:320, pr.L_DIFFUSE] = 0.0
    albedo[300:310, 1:] = 0.0  # no weight at all: 0 / 0
    dp = object.__new__(DiffusePdf)
    dp.prm = np.ascontiguousarray(prm)
    dp.sel, dp.psum, dp.wd = np.empty((n, pr.N_LOBES)), np.empty(n), np.empty(n)
    dp.lambert = np.empty(n, bool)
    diffuse_pdf_weights(albedo, dp.sel, dp.psum, dp.wd, dp.lambert)
    dp.plain = dp.lambert & ~(dp.psum > 0.0)
    dp.largest = np.where(rng.random(n) < 0.9, np.inf, rng.uniform(0.0, 2.0, n))
    dp.ns = uniform_sphere(rng.random(n), rng.random(n))
    dp.wo = normalize(dp.ns + 0.9 * uniform_sphere(rng.random(n), rng.random(n)))
    direction = (uniform_sphere(rng.random(p), rng.random(p))
                 * rng.uniform(0.5, 2.0, (p, 1))).astype(np.float32)
    direction[:20] = 0.0
    direction[20:25] = np.nan
    blur = rng.uniform(0.0, 20.0, p).astype(np.float32)
    blur[rng.random(p) < 0.3] = np.inf
    blur[:40:3] = np.nan
    camera = rng.uniform(0.0, 20.0, n)
    camera[rng.random(n) < 0.4] = np.inf
    camera[::97] = np.nan
    sel = rng.integers(0, n, 3000).astype(np.int64)
    rows = rng.integers(0, len(sel), k).astype(np.int64)
    photons = rng.integers(0, p, k).astype(np.int64)
    # The compact layout's octahedral codes too (photonlayout.encode_vectors; zero and
    # NaN directions encode to codes of their own), read in place by the kernel.
    from engine.photonlayout import encode_vectors
    with np.errstate(invalid="ignore", divide="ignore"):
        code = encode_vectors(direction)
    checked = 0
    for cam, stored, dirs in ((None, None, direction), (camera, blur, direction),
                              (None, blur, direction), (camera, None, direction),
                              (camera, blur, code), (None, None, code)):
        dp.camera = cam
        pmap = SimpleNamespace(photons=SimpleNamespace(direction=dirs, blur_pdf=stored))
        dp.fg = 1.0
        _, pd = _reject_numpy(dp, pmap, sel, rows, photons)
        finite = np.unique(pd[np.isfinite(pd) & (pd > 0.0)])
        for fg in np.concatenate([[1.0, 1e-3], rng.choice(finite, 25, replace=False)]):
            dp.fg = float(fg)
            want, _ = _reject_numpy(dp, pmap, sel, rows, photons)
            got = dp.reject_for(pmap, sel)(rows, photons)
            np.testing.assert_array_equal(got, want)
            checked += int(want.sum()) * int((~want).sum()) > 0
    assert checked >= 140  # (each threshold splits the pairs)


def _near_numpy(cs, p, tri):
    """The numpy stage of coincident.CoincidentSurfaces.near the kernel replaced
    (percost55): per kind, the rows' axes tested one at a time against the float64 box."""
    from engine.coincident import GLASS, NONE, OTHER
    out = np.zeros(len(tri), bool)
    side = np.take(cs.side, np.maximum(tri, 0))
    side[tri < 0] = NONE
    for kind, partners in ((GLASS, cs.others), (OTHER, cs.glass)):
        rows = np.nonzero(side == kind)[0]
        for c in range(3):
            if not len(rows):
                break
            x = np.take(p[:, c], rows)
            # (numpy 1.26 compared a float32 array with the float64 box scalar in float32:
            # value-based casting, which NEP 50 ends; cast as it did)
            lo, hi = (p.dtype.type(partners.box[k, c]) for k in (0, 1))
            rows = rows[(x >= lo) & (x <= hi)]
        out[rows] = True
    return out


def test_touch_near_kernel_marks_the_numpy_stages_rows():
    """gatherkernels.touch_near (CoincidentSurfaces.near, percost55) against the numpy
    stage on random points, float64 and float32 (numpy compared float32 points with the
    box in float32): triangles of every side and none (-1), points on and one ulp either
    side of every face of the boxes, NaN points."""
    from engine.coincident import CoincidentSurfaces, GLASS, OTHER
    rng = np.random.default_rng(55)
    t, n = 300, 60_000
    side = rng.choice(np.array([0, GLASS, OTHER], np.int8), t)
    cs = object.__new__(CoincidentSurfaces)
    cs.side = side
    cs._boxes = {}
    lo = rng.normal(size=(2, 3))
    cs.others = SimpleNamespace(box=np.stack([lo[0], lo[0] + rng.random(3) + 0.1]))
    cs.glass = SimpleNamespace(box=np.stack([lo[1], lo[1] + rng.random(3) + 0.1]))
    tri = rng.integers(-1, t, n).astype(np.int64)
    # points around either box (a margin of 0.2 beyond it on each axis)
    box = np.stack([cs.others.box, cs.glass.box])[rng.integers(0, 2, n)]
    p = box[:, 0] - 0.2 + rng.random((n, 3)) * (box[:, 1] - box[:, 0] + 0.4)
    for k, box in enumerate((cs.others.box, cs.glass.box)):
        # points on the boxes' faces and a float32 / float64 ulp either side
        rows = rng.integers(0, n, (6, 3000))
        for j in range(6):
            axis, bound = j % 3, box[j // 3, j % 3]
            for sel, val in zip(np.array_split(rows[j], 5), (
                    bound, np.nextafter(bound, -np.inf), np.nextafter(bound, np.inf),
                    np.float64(np.float32(bound)), np.nextafter(np.float32(bound), np.inf))):
                p[sel, axis] = val
    p[::101] = np.nan
    for dtype in (np.float64, np.float32):
        q = np.ascontiguousarray(p, dtype)
        want = _near_numpy(cs, q, tri)
        np.testing.assert_array_equal(cs.near(q, tri), want)
        assert 0.01 < want.mean() < 0.5


def _clamp_map(rng, n, rgbe, bounces):
    """A stand-in map for the clamp's weights (the fields list_weights reads): powers
    over five decades (some zero), |L_p|_1 over five (some NaN, infinite, zero), chains
    of 0-12 scatters or no bounces."""
    from engine.photonlayout import encode_power
    power = (rng.random((n, 3)) * 10.0 ** rng.uniform(-4, 1, (n, 1))).astype(np.float32)
    power[rng.random(n) < 0.03] = 0.0
    rad = (rng.random(n) * 10.0 ** rng.uniform(-1, 4, n)).astype(np.float32)
    rad[rng.random(n) < 0.01] = np.nan
    rad[rng.random(n) < 0.01] = np.inf
    rad[rng.random(n) < 0.02] = 0.0
    b = rng.integers(0, 13, (n, 4)).astype(np.uint8) if bounces else None
    return SimpleNamespace(photons=SimpleNamespace(
        power=encode_power(power) if rgbe else power, radiance=rad, bounces=b))


def _list_weights_numpy(pmap, read, qrows, slots, scale, limit):
    """The numpy stage photonvisibility.clamp_weights replaced (kept here as its
    reference): Clamp Indirect's photonclamp.photon_weights over an estimate's read
    lists: read = (count, photons) (photonvisibility.
    _estimate_read's lists, (L,) and (L, W)), qrows (Q,) the rows of the block whose
    lists slots (Q,) are whole, scale (B,3) each row's clamp throughput x albedo, limit
    Clamp Indirect's. Returns None where no listed photon is over the limit (every
    weight 1: the estimates keep their bits), else (rows (V,), slots (V,), clamp_w (L,
    W) float64): the rows with some photon over the limit, their lists, and each listed
    photon's w_p (1 past a list's count and for lists not in slots)."""
    from engine import photonclamp
    from engine.photonkernels import B_TOTAL
    from engine.photonlayout import decode_power
    radiance = pmap.photons.radiance
    if radiance is None or not len(qrows):
        return None
    count, photons = read
    c = np.take(count, slots)
    width = int(c.max()) if len(c) else 0
    if width == 0:
        return None
    lists = np.take(photons, slots, axis=0)[:, :width]
    inside = np.arange(width)[None, :] < c[:, None]
    ph = np.where(inside, lists, 0)
    pw = pmap.photons.power
    pw = decode_power(pw[ph.reshape(-1)]) if pw.dtype == np.uint8 else \
        pw[ph.reshape(-1)].astype(np.float64)
    pw = pw.reshape(len(qrows), width, 3)
    bounces = getattr(pmap.photons, "bounces", None)
    chain = None if bounces is None else bounces[ph, B_TOTAL]
    w = photonclamp.photon_weights(radiance[ph], pw,
                                   np.take(scale, qrows, axis=0)[:, None, :], limit, chain)
    w = np.where(inside, w, 1.0)
    over = np.flatnonzero((w < 1.0).any(axis=1))
    if not len(over):
        return None
    clamp_w = np.ones(photons.shape)
    clamp_w[np.asarray(slots, np.int64)[:, None], np.arange(width)[None, :]] = w
    return (np.asarray(qrows, np.int64)[over], np.asarray(slots, np.int64)[over], clamp_w)


def test_clamp_weights_kernel_gives_list_weights_bits(monkeypatch):
    """photonvisibility.clamp_weights (percost56: one kernel pass over the read lists)
    against _list_weights_numpy, the numpy stage it replaced: the same rows, slots
    and weights bit for bit (or None alike), powers float32 or RGBE, with and without
    the photons' bounces, with the roulette share off, rows of zero scale, lists in any
    slot order and of any length (zero too)."""
    from engine import photonclamp
    from engine.photonvisibility import clamp_weights
    rng = np.random.default_rng(5600)
    n, lists, width = 4000, 300, 64
    seen_over = seen_none = 0
    for trial in range(16):
        pmap = _clamp_map(rng, n, rgbe=trial % 2 == 1, bounces=trial % 4 != 3)
        if trial == 8:
            monkeypatch.setattr(photonclamp, "ROULETTE", False)
        if trial == 9:
            monkeypatch.setattr(photonclamp, "ROULETTE", True)
        count = rng.integers(0, width + 1, lists)
        photons = rng.integers(0, n, (lists, width))
        qrows = np.sort(rng.choice(lists, 200, replace=False))
        slots = qrows.copy() if trial % 3 else rng.permutation(lists)[:200]
        scale = rng.random((lists, 3)) * 10.0 ** rng.uniform(-3, 1, (lists, 1))
        scale[:20] = 0.0
        limit = 10.0 if trial < 14 else np.inf  # (nothing over it: None)
        want = _list_weights_numpy(pmap, (count, photons), qrows, slots, scale, limit)
        got = clamp_weights(pmap, (count, photons), qrows, slots, scale, limit)
        if want is None:
            assert got is None
            seen_none += 1
            continue
        seen_over += 1
        assert got is not None and len(got) == 3
        for a, b in zip(got, want):
            assert a.dtype == b.dtype and np.array_equal(a, b)
        assert 0 < (want[2] < 1.0).sum() < want[2].size
    assert seen_over >= 12 and seen_none >= 2


def test_rejected_mask_sums_are_the_pairs_sums():
    """photonvisibility._rejected_lists' mask (percost56) in _visible_sums against the
    pairs it replaced (each rejected pair listed as a hidden one, with the traced
    pairs, sorted and bisected, as _with_rejected gave them): the same bits in every row
    estimated again, every other row's bits kept; rows with both kinds, with rejected
    photons only, and with hidden ones only."""
    from engine import photonvisibility as pv
    from engine.photonmap import PhotonMap
    from engine.photons import CAUSTIC, Photons
    rng = np.random.default_rng(5601)
    n, m = 1500, 120
    pos = np.c_[rng.random((n, 2)), np.zeros(n)].astype(np.float32)
    up = np.tile(np.float32([0, 0, 1]), (n, 1))
    power = (0.005 + 0.02 * rng.random((n, 3))).astype(np.float32)
    pmap = PhotonMap(Photons(pos, power, -up, up.copy(), np.full(n, CAUSTIC, np.uint8)))
    p = np.c_[0.1 + 0.8 * rng.random((m, 2)), np.zeros(m)]
    nrm = np.tile([0.0, 0.0, 1.0], (m, 1))
    E, count, photons, weight, factor, _ = pv._estimate_read(
        pmap, None, None, p, nrm, 0.1, 40, 8, "knn_simpson", None)
    count, photons = count.copy(), photons.copy()
    read = (count, photons, weight.copy(), factor.copy())
    listed = np.flatnonzero(count > 0)
    assert len(listed) == m
    # hidden pairs: a photon in 7 of the rows < 60, in list order (as _hidden_pairs)
    h_rows, h_ph = [], []
    for i in range(60):
        for j in range(count[i]):
            if rng.random() < 1 / 7:
                h_rows.append(i)
                h_ph.append(photons[i, j])
    h_rows, h_ph = np.int64(h_rows), np.int64(h_ph)
    a = 1000  # (the block's first row of p: reject's rows are p's)

    def reject(rows, ph):
        rows = np.asarray(rows)
        return ((rows - a) >= 30) & ((rows - a) < 90) & ((rows + ph) % 4 == 0)

    dropped = pv._rejected_lists(listed, listed, count, photons, a, reject)
    assert dropped is not None
    got = E.copy()
    pv._visible_sums(pmap, None, None, got, h_rows, h_rows, h_ph, read, None, dropped)
    # the pairs: hidden and rejected, each once, by row then photon
    pr = np.repeat(listed, count[listed])
    ph = np.concatenate([photons[i, :count[i]] for i in listed])
    drop = reject(pr + a, ph)
    key = np.unique(np.r_[h_rows * (n + 1) + h_ph, pr[drop] * (n + 1) + ph[drop]])
    rows, hid = key // (n + 1), key % (n + 1)
    want = E.copy()
    pv._visible_sums(pmap, None, None, want, rows, rows, hid, read)
    assert np.array_equal(got, want)
    changed = (got != E).any(axis=1)
    assert changed[:30].sum() > 5 and changed[30:60].sum() > 5 and changed[60:90].sum() > 5
    assert not changed[90:].any()
    assert set(rows) == set(dropped[0]) | set(h_rows)
    assert set(np.flatnonzero(changed)) <= set(np.unique(rows))
