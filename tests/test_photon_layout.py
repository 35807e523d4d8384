"""The compact layout of a map's photons (engine/photonlayout.py, docs/performance.md
"compact49"):
- octahedral directions and normals decode within OCT_MAX_ANGLE of the float32 vectors,
  the kernels' decode is the numpy one bit for bit, and a float32 array reads as itself;
- RGBE power keeps zeros exactly, each channel within 1/255.5 of the row's brightest, and
  is unbiased on random powers (the summed power within 5e-5);
- has_power and the row reads answer as the decoded values; a gather map's drop bounds
  and the photon guide's grids read compact maps as their values (compact51);
- a map holds 12 B of direction, normal and power a photon (36 with COMPACT off);
- a flat surface's compact photons get the straight visibility ray the float32 ones get;
- a real scene's estimates from the compact maps agree with the float32 maps' within
  0.2 % (the same shot, both layouts).
"""
import copy
import math

import numba
import numpy as np
import pytest

from engine import RenderSettings
from engine import photonlayout as L
from engine.api import cornell_box
from engine.photonmap import PhotonMap
from engine.photons import Photons
from engine.photonvisibility import _read_rays
from engine.render import _photon_pass, prepare_context


def _angle(a, b):
    """Angles (rad) between rows of a and b (N,3), accurate near 0 (atan2 of the cross
    product's length and the dot product; arccos loses small angles to rounding)."""
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), (a * b).sum(axis=1))


def _unit(n, rng):
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    edges = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
                      [1, 1, 0], [1, -1, 0], [-1, 1, 0], [-1, -1, 0], [1, 1, 1],
                      [-1, -1, -1], [0, 1, -1], [1e-9, 0, -1]], np.float64)
    edges /= np.linalg.norm(edges, axis=1)[:, None]
    return np.concatenate([edges, v]).astype(np.float32)


@numba.njit
def _kernel_vectors(a, out):
    for j in range(a.shape[0]):
        out[j, 0], out[j, 1], out[j, 2] = L.read_vector(a, j)


@numba.njit
def _kernel_powers(a, out):
    for j in range(a.shape[0]):
        out[j, 0], out[j, 1], out[j, 2] = L.read_power(a, j)


def test_octahedral_vectors_round_trip_within_the_bound():
    rng = np.random.default_rng(0)
    v = _unit(1_000_000, rng)
    code = L.encode_vectors(v)
    assert code.dtype == np.int16 and code.shape == (len(v), 2)
    back = L.decode_vectors(code)
    ang = _angle(back, v)
    assert ang.max() <= L.OCT_MAX_ANGLE, np.degrees(ang.max())
    assert ang.max() > 0.5 * L.OCT_MAX_ANGLE  # the bound is tight, not loose
    np.testing.assert_allclose(np.linalg.norm(back.astype(np.float64), axis=1), 1.0,
                               atol=1e-6)
    # The axes decode exactly; a decoded vector codes to itself again (to float32
    # rounding: on the equator either half's code of it, the fold's edge).
    np.testing.assert_array_equal(back[:6], v[:6])
    assert _angle(L.decode_vectors(L.encode_vectors(back)), back).max() < 1e-6
    # The kernels read the numpy decode's bits; a float32 array reads as itself.
    out = np.empty_like(back)
    _kernel_vectors(code, out)
    np.testing.assert_array_equal(out, back)
    _kernel_vectors(v, out)
    np.testing.assert_array_equal(out, v)


def test_rgbe_power_keeps_zeros_and_is_unbiased():
    rng = np.random.default_rng(1)
    n = 1_000_000
    # Photon powers: a colour times a per-photon scale over 20 octaves (a light's share,
    # Horvitz-Thompson factors, caustic throughput), some channels and rows exactly 0.
    c = (rng.random((n, 3)) * np.exp2(rng.uniform(-30, -10, n))[:, None]).astype(np.float32)
    c[::7, 1] = 0.0
    c[::11, 2] = 0.0
    c[::13] = 0.0
    code = L.encode_power(c)
    assert code.dtype == np.uint8 and code.shape == (n, 4)
    back = L.decode_power(code)
    c64 = c.astype(np.float64)
    np.testing.assert_array_equal(back[c == 0.0], 0.0)
    assert not code[::13].any()  # a powerless photon is all zero bytes (masks test it so)
    assert np.all(np.any(code != 0, axis=1) == np.any(c != 0.0, axis=1))
    top = c64.max(axis=1)
    lit = top > 0
    err = (back - c64)[lit] / top[lit][:, None]
    # Half a step: 2^(E - 9) of a brightest in [2^(E-1), 2^E), 2^(E - 8) of one that
    # rounded up to 256 steps (>= 255.5 2^(E - 8)).
    assert np.abs(err).max() <= 1.0 / 255.5
    # Round to nearest: no drift on average per photon (relative to its brightest: the
    # rounding's noise is 6e-7 over 10^6), nor in any channel's sum (its noise ~1e-5:
    # the brightest few thousand photons of 20 octaves carry the sum).
    np.testing.assert_allclose(back.sum(axis=0), c64.sum(axis=0), rtol=5e-5)
    assert np.abs(err.mean(axis=0)).max() < 5e-6
    # A float32 copy holds the same values (what round_trip gives), and the kernels
    # read them bit for bit.
    np.testing.assert_array_equal(L.decode_power(code, np.float32).astype(np.float64), back)
    out = np.empty((n, 3))
    _kernel_powers(code, out)
    np.testing.assert_array_equal(out, back)
    _kernel_powers(c, out)
    np.testing.assert_array_equal(out, c64)


def test_has_power_and_row_reads_answer_as_the_decoded_values():
    """has_power (the gather map's drop bounds and masks test it) says whether the decoded
    power has a nonzero channel, for RGBE codes and float arrays alike, without decoding:
    a powerless photon is all zero bytes, and no code with a nonzero byte decodes to 0
    (down to below RGBE's range, 2^-136, where the exponent byte stays 0). vectors /
    powers take rows of any shape (guiding's (P, k) neighbour rows)."""
    rng = np.random.default_rng(7)
    n = 200_000
    c = (rng.random((n, 3)) * np.exp2(rng.uniform(-150, 40, n))[:, None]).astype(np.float32)
    c[::5, 0] = 0.0
    c[::9] = 0.0
    code = L.encode_power(c)
    back = L.decode_power(code)
    on = L.has_power(code)
    np.testing.assert_array_equal(on, np.any(back != 0.0, axis=1))
    assert on.sum() > 0.8 * n and (~on).sum() > n / 9  # (zeros, and some below the range)
    np.testing.assert_array_equal(L.has_power(c), np.any(c != 0.0, axis=1))
    rows = rng.integers(0, n, (50, 7))
    np.testing.assert_array_equal(L.powers(code, rows), back[rows])
    np.testing.assert_array_equal(L.powers(c, rows), c.astype(np.float64)[rows])
    v = _unit(n, rng)[:n]
    vc = L.encode_vectors(v)
    np.testing.assert_array_equal(L.vectors(vc, rows, np.float32), L.decode_vectors(vc)[rows])
    np.testing.assert_array_equal(L.vectors(v, rows), v.astype(np.float64)[rows])


def test_drop_bounds_and_guides_read_compact_maps_as_their_values(monkeypatch):
    """A gather map's drop bounds (a mask's photons of nonzero power in a point's disc)
    are the float32 maps' with COMPACT on (the estimating map compact, its zero-power
    photons all zero bytes), and a mask of powerless photons bounds nothing; the photon
    guide's grids from a compact map's photons are those of round_trip's float32 ones,
    bit for bit (engine/guiding.py reads through vectors / powers)."""
    from engine.guiding import GatherGuide
    from engine.photonmap import GatherMap
    from engine.photons import INDIRECT
    rng = np.random.default_rng(8)
    n = 20000
    ph = _plane_photons(n, rng)
    ph.direction[:, 2] = np.minimum(ph.direction[:, 2], -0.3)  # (no grazing photon)
    ph.direction /= np.linalg.norm(ph.direction, axis=1)[:, None]
    dark = rng.random(n) < 0.3
    ph.power[dark] = 0.0
    some = rng.random(n) < 0.2
    bounds = {(0, 1): some, (0, 2): some & dark, (1, 1): dark}
    got = {}
    for compact in (True, False):
        monkeypatch.setattr(L, "COMPACT", compact)
        g = GatherMap(ph, 0.05, 32, 1, "knn_simpson", keep=~some, drop_bounds=bounds,
                      max_points=3000, bounces=np.zeros((n, 4), np.uint8))
        assert (g.estimating.photons.power.dtype == np.uint8) == compact
        got[compact] = g
    for key in bounds:
        np.testing.assert_array_equal(got[True].drop_bounds[key], got[False].drop_bounds[key])
    assert got[True].drop_bounds[(0, 1)].any()
    assert not got[True].drop_bounds[(0, 2)].any() and not got[True].drop_bounds[(1, 1)].any()
    ph.kind[:] = INDIRECT
    q = ph.position[:40].astype(np.float64)
    nq = np.tile([0.0, 0.0, 1.0], (40, 1))
    for source in ("indirect", "flux"):
        a = GatherGuide(q, nq, L.compact(copy.copy(ph)), 0.05, source=source)
        b = GatherGuide(q, nq, L.round_trip(ph), 0.05, source=source)
        np.testing.assert_array_equal(a.row_prob, b.row_prob)
        np.testing.assert_array_equal(a.col_prob, b.col_prob)


def _plane_photons(n, rng):
    pos = np.c_[rng.random((n, 2)), np.zeros(n)].astype(np.float32)
    up = np.tile(np.float32([0, 0, 1]), (n, 1))
    d = rng.normal(size=(n, 3))
    d[:, 2] = -np.abs(d[:, 2])
    d /= np.linalg.norm(d, axis=1)[:, None]
    return Photons(pos, rng.random((n, 3)).astype(np.float32), d.astype(np.float32), up,
                   np.zeros(n, np.uint8))


def test_a_map_holds_12_bytes_of_direction_normal_and_power(monkeypatch):
    ph = _plane_photons(5000, np.random.default_rng(2))
    monkeypatch.setattr(L, "COMPACT", True)
    pm = PhotonMap(ph)
    q = pm.photons
    assert (q.direction.dtype, q.normal.dtype, q.power.dtype) == (np.int16, np.int16,
                                                                   np.uint8)
    assert (q.direction.nbytes + q.normal.nbytes + q.power.nbytes) == 12 * len(ph)
    monkeypatch.setattr(L, "COMPACT", False)
    f = PhotonMap(ph).photons
    assert f.power.dtype == f.direction.dtype == f.normal.dtype == np.float32
    assert (f.direction.nbytes + f.normal.nbytes + f.power.nbytes) == 36 * len(ph)
    # The same photons, in the same order, the compact ones round_trip's values.
    rt = L.round_trip(f)
    np.testing.assert_array_equal(L.vectors(q.direction, dtype=np.float32), rt.direction)
    np.testing.assert_array_equal(L.powers(q.power, dtype=np.float32), rt.power)
    assert _angle(rt.normal, f.normal).max() == 0.0  # +z is exact


def test_flat_surface_photons_get_the_straight_ray():
    """A compact photon on the query's plane decodes within the round trip of the
    query's normal: one straight ray (photonmap._ray_ends), as its float32 twin gets,
    not _bent_path's two segments."""
    rng = np.random.default_rng(3)
    ph = _plane_photons(64, rng)
    tilt = (np.float64([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])).astype(np.float32)
    ph.normal[:] = tilt
    for compact in (True, False):
        old = L.COMPACT
        L.COMPACT = compact
        try:
            pmap = PhotonMap(ph)
        finally:
            L.COMPACT = old
        normal = pmap.photons.normal
        if compact:  # not the query's normal's bits: the snap makes the straight ray
            assert normal.dtype == np.int16
            assert _angle(L.vectors(normal), np.tile(tilt, (64, 1))).max() > 0
        q = np.float64([[0.5, 0.5, 0.0]])
        n = tilt.astype(np.float64)[None]
        rows = np.zeros(1, np.int64)
        slots = np.zeros(1, np.int64)
        count = np.int64([16])
        photons = np.arange(16, dtype=np.int64)[None]
        o32, d32 = np.empty((32, 3), np.float32), np.empty((32, 3), np.float32)
        t32, rr, rp = np.empty(32, np.float32), np.empty(32, np.int64), np.empty(32, np.int64)
        m = _read_rays(pmap.photons.position, normal, q, n, np.zeros(0), rows, slots,
                       count, photons, o32, d32, t32, rr, rp)
        assert m == 16


@pytest.fixture(scope="module")
def _both_layouts():
    """The Cornell box's photon pass (the same shot) with compact and float32 maps."""
    st = RenderSettings(photons=30000, caustic_photons=20000, final_gather=False,
                        workers=1, seed=4)
    out = {}
    for compact in (True, False):
        old = L.COMPACT
        L.COMPACT = compact
        try:
            ctx = prepare_context(cornell_box(width=32, height=24), st)
            _photon_pass(ctx, {}, None, None)
        finally:
            L.COMPACT = old
        out[compact] = ctx
    return st, out


def test_compact_estimates_match_the_float32_maps(_both_layouts):
    st, ctx = _both_layouts
    rng = np.random.default_rng(5)
    for field, radius in (("global_map", "global_radius"), ("caustic_map", "caustic_radius")):
        a, b = getattr(ctx[True], field), getattr(ctx[False], field)
        assert len(a) == len(b) > 500
        np.testing.assert_array_equal(a.photons.position, b.photons.position)
        assert a.photons.power.dtype == np.uint8 and b.photons.power.dtype == np.float32
        sel = rng.choice(len(b), 1000, replace=False)
        r = getattr(ctx[False], radius)
        q = b.photons.position[sel].astype(np.float64) + rng.normal(size=(1000, 3)) * r * 0.1
        nq = b.photons.normal[sel].astype(np.float64)
        for est in ("knn_simpson", "knn_cone", "classic"):
            Ea = a.irradiance(q, nq, r, st.k_nearest, st.min_photons, est)
            Eb = b.irradiance(q, nq, r, st.k_nearest, st.min_photons, est)
            lit = Eb.sum(axis=1) > 0
            assert lit.sum() > 500
            # The summed light within 0.2 %; a single estimate within 2 % (a photon's
            # channel moves by at most 1/256 of its brightest; the acceptance of a
            # grazing photon may flip).
            np.testing.assert_allclose(Ea.sum(), Eb.sum(), rtol=2e-3)
            rel = np.abs(Ea - Eb).sum(axis=1)[lit] / Eb.sum(axis=1)[lit]
            assert np.median(rel) < 2e-3 and np.quantile(rel, 0.99) < 2e-2, est


@numba.njit
def _kernel_axes(a, nq, out, t):
    """Per row j of a: read_axis's (x, y, z, w), the cosine g with nq, cos_below(g, t) and
    cos_at_most(g, t)."""
    for j in range(a.shape[0]):
        x, y, z, w = L.read_axis(a, j)
        g = x * nq[0] + y * nq[1] + z * nq[2]
        out[j, 0], out[j, 1], out[j, 2], out[j, 3] = x, y, z, w
        out[j, 4] = L.cos_below(a, g, w, t)
        out[j, 5] = L.cos_at_most(a, g, w, t)


def test_axis_reads_compare_cosines_as_the_decoded_unit_vectors():
    """compact50: the k-NN rows' photon tests read the octahedral point unnormalised
    (read_axis) and compare g |g| with t |t| w (cos_below, cos_at_most): the decisions of
    the decoded unit vectors' cosines except within float32 rounding of the threshold;
    a float32 array reads as itself and compares its cosine as before."""
    rng = np.random.default_rng(6)
    nq = np.float32([0.36, -0.48, 0.8])
    e1 = np.float64([0.8, 0.6, 0.0])  # e1, e2, nq: an orthonormal frame
    e2 = np.cross(nq.astype(np.float64), e1)
    out = np.empty((200_000 + 14, 6), np.float64)
    for t in (0.5, math.cos(math.radians(1.0)), -math.cos(math.radians(1.0))):
        # Random vectors and vectors whose cosine with nq lies within 1e-3 of t.
        c = np.clip(t + rng.uniform(-1e-3, 1e-3, 100_000), -1.0, 1.0)
        phi = rng.uniform(0.0, 2.0 * np.pi, len(c))
        s = np.sqrt(1.0 - c * c)[:, None]
        ring = c[:, None] * nq + s * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * e2)
        v = np.concatenate([_unit(100_000, rng), ring.astype(np.float32)])
        code = L.encode_vectors(v)
        back = L.decode_vectors(code).astype(np.float64)
        cos_d = back @ nq.astype(np.float64)
        _kernel_axes(code, nq, out, t)
        # The octahedron's point is along the decoded vector: oct_decode normalises it.
        x, w = out[:, :3].astype(np.float32), out[:, 3].astype(np.float32)
        np.testing.assert_array_equal(x * (np.float32(1.0) / np.sqrt(w))[:, None],
                                      L.decode_vectors(code))
        near = np.abs(cos_d - t) < 1e-6
        assert np.array_equal(out[~near, 4] == 1, (cos_d < t)[~near])
        assert np.array_equal(out[~near, 5] == 1, (cos_d <= t)[~near])
        assert near.mean() < 2e-3 and (out[:, 4] == 1).mean() > 0.1
        _kernel_axes(v, nq, out, t)
        np.testing.assert_array_equal(out[:, :3], v)
        assert (out[:, 3] == 1.0).all()
        g = v @ nq  # float32: the kernels' float32 sums, to rounding
        far = np.abs(g.astype(np.float64) - t) > 1e-6
        assert np.array_equal(out[far, 4] == 1, (g < t)[far])


def test_compact_estimates_are_the_decoded_maps_bits(_both_layouts):
    """compact50: a compact map's estimates (its photons tested along their octahedral
    axes, each row's tests made once) are bit for bit those of a float32 map holding the
    decoded values (round_trip's: the same photons, tree and order)."""
    import copy
    st, ctx = _both_layouts
    rng = np.random.default_rng(7)
    for field, radius in (("global_map", "global_radius"), ("caustic_map", "caustic_radius")):
        a = getattr(ctx[True], field)
        b = copy.copy(a)
        b.photons = copy.copy(a.photons)
        b.photons.direction = L.vectors(a.photons.direction, dtype=np.float32)
        b.photons.normal = L.vectors(a.photons.normal, dtype=np.float32)
        b.photons.power = L.powers(a.photons.power, dtype=np.float32)
        sel = rng.choice(len(a), 1000, replace=False)
        r = getattr(ctx[True], radius)
        q = a.photons.position[sel].astype(np.float64) + rng.normal(size=(1000, 3)) * r * 0.1
        nq = b.photons.normal[sel].astype(np.float64)
        for est in ("knn_simpson", "knn_cone", "classic", "radius"):
            Ea, Ba = a.irradiance(q, nq, r, st.k_nearest, st.min_photons, est,
                                  return_boundary=True)
            Eb, Bb = b.irradiance(q, nq, r, st.k_nearest, st.min_photons, est,
                                  return_boundary=True)
            assert (Eb.sum(axis=1) > 0).sum() > 500
            np.testing.assert_array_equal(Ea, Eb, err_msg=est)
            np.testing.assert_array_equal(Ba, Bb, err_msg=est)
