"""Photon visibility traces the photons the estimate itself read (engine/photonvisibility.py:
PhotonMap.knn_irradiance's read lists, one search a row), not a second k-NN search's
candidates (the k nearest accepted photons within the radius, widened up to MAX_WIDEN_K
until k are accepted, as photonvisibility._candidate_rays searched before visreuse).

Both give the same hidden pairs wherever the estimate weighs a photon: the read lists are
the old candidates, but for the candidates a row's estimate weighs 0 (beyond its disc: a
row whose estimate stops widening with k / 2 accepted photons, where the old search went
on to find k), whose visibility could not change its sum. Checked on the lamp shade
piercing a wall (flat pairs, tests/test_leak_lampshade.py) and on a ball pierced by a wall
on a floor (curved pairs, tests/test_photon_visibility_curved.py)."""
import numpy as np

from engine import RenderSettings
from engine.photonlayout import vectors
from engine.photonmap import MAX_WIDEN_K, PhotonMap
from engine.photonvisibility import _hidden_pairs, hidden_photons
from engine.render import prepare_context, shoot_photons

from test_leak_lampshade import SETTINGS, lamp_scene
from test_photon_visibility_curved import RADIUS, K, ball_scene, on_ball
from engine.photons import Photons


def old_candidates(pmap, p, n, radius, k):
    """Brute force, per row: the k nearest accepted photons (photonmap._accepted: from the
    front, on a surface facing the same way) among the MAX_WIDEN_K nearest strictly
    within radius, nearest first (float64 squared distances from the float32 positions,
    float32 acceptance, as the kernels compute them)."""
    pos = pmap.photons.position
    # (the float32 values the kernels decode from a compact map: engine/photonlayout.py)
    di = vectors(pmap.photons.direction, dtype=np.float32)
    nm = vectors(pmap.photons.normal, dtype=np.float32)
    out = []
    for i in range(len(p)):
        d2 = (((p[i, 0] - pos[:, 0].astype(np.float64)) ** 2
               + (p[i, 1] - pos[:, 1].astype(np.float64)) ** 2)
              + (p[i, 2] - pos[:, 2].astype(np.float64)) ** 2)
        inside = np.flatnonzero(d2 < radius * radius)
        near = inside[np.argsort(d2[inside], kind="stable")][:MAX_WIDEN_K]
        n32 = n[i].astype(np.float32)
        cos_in = -(di[near, 0] * n32[0] + di[near, 1] * n32[1] + di[near, 2] * n32[2])
        same = (nm[near, 0] * n32[0] + nm[near, 1] * n32[1] + nm[near, 2] * n32[2]) > 0.5
        out.append((near[(cos_in > 0) & same][:k], d2))
    return out


def compare(pmap, accel, p, n, radius, k):
    """The read lists against old_candidates row by row, and the hidden pairs each gives
    (the same tracer, photonvisibility._hidden_pairs). Returns (pairs, rows whose lists
    differ)."""
    m = len(p)
    count = np.zeros(m, np.int64)
    read = np.empty((m, 4 * k), np.int64)
    pmap.knn_irradiance(p, n, radius, k, 1, "knn_simpson", read=(count, read))
    assert count.max() <= read.shape[1]
    old = old_candidates(pmap, p, n, radius, k)
    width = max(len(c) for c, _ in old)
    old_count = np.array([len(c) for c, _ in old], np.int64)
    old_list = np.zeros((m, max(width, 1)), np.int64)
    differ = 0
    weighed = []  # per row: the photons whose visibility can change its estimate
    for i, (cand, d2) in enumerate(old):
        old_list[i, :len(cand)] = cand
        got = read[i, :count[i]]
        if not np.array_equal(got, cand):
            differ += 1
            # The estimate read fewer: a prefix of the old list, the rest beyond its disc
            # (at or past its widest read photon: weight 0).
            assert np.array_equal(got, cand[:len(got)]) and len(got) >= k // 2
            assert d2[cand[len(got):]].min() >= d2[got].max()
        weighed.append(set(got.tolist()))
    rows = np.arange(m, dtype=np.int64)
    lift = np.zeros(0)
    old_rows, old_ph = _hidden_pairs(pmap, accel, p, n, lift, rows, rows, old_count,
                                     old_list)
    new_rows, new_ph = hidden_photons(pmap, accel, p, n, None, radius, k)
    new = set(zip(new_rows.tolist(), new_ph.tolist()))
    assert len(new) == len(new_rows)
    old_weighed = {(r, j) for r, j in zip(old_rows.tolist(), old_ph.tolist())
                   if j in weighed[r]}
    assert new == old_weighed
    return new, differ


def test_lamp_shade_reads_give_the_old_hidden_pairs():
    """The lamp shade's wall and floor, near the rim and the wall's foot: the hidden pairs
    from the estimate's read lists are the old search's (every one the estimate weighs)."""
    ctx = prepare_context(lamp_scene(), RenderSettings(**SETTINGS))
    pmap = PhotonMap(shoot_photons(ctx, {})[-1])
    rng = np.random.default_rng(11)
    wall = np.column_stack([rng.uniform(-0.6, 0.6, 200), np.full(200, 2.0),
                            np.r_[rng.uniform(1.0, 2.1, 150), rng.uniform(0.01, 0.2, 50)]])
    floor = np.column_stack([rng.uniform(-1.0, 1.0, 100), rng.uniform(1.7, 1.99, 100),
                             np.zeros(100)])
    p = np.concatenate([wall, floor]) - ctx.geo.offset
    n = np.concatenate([np.tile([0.0, -1.0, 0.0], (200, 1)), np.tile([0.0, 0.0, 1.0], (100, 1))])
    pairs, differ = compare(pmap, ctx.accel, p, n, 0.19, 64)
    print(f"lamp: {len(pairs)} hidden pairs, {len({r for r, _ in pairs})} rows, "
          f"{differ} rows read fewer than the old candidates")
    assert len({r for r, _ in pairs}) > 20   # the rim's rows hide photons


def test_curved_pairs_reads_give_the_old_hidden_pairs():
    """Photons and rows on a ball on a floor, a wall through it (curved pairs: two-segment
    paths): the same hidden pairs from the read lists as from the old search."""
    ctx = prepare_context(ball_scene(floor=True, slab=True), RenderSettings(spp=1))
    off = ctx.geo.offset
    rng = np.random.default_rng(2)
    pp, pn = on_ball(rng, 3000)
    ph = Photons((pp - off).astype(np.float32), np.ones((len(pp), 3), np.float32),
                 (-pn).astype(np.float32), pn.astype(np.float32), np.zeros(len(pp), np.uint8),
                 len(pp))
    pmap = PhotonMap(ph)
    q, qn = on_ball(rng, 600)
    pairs, differ = compare(pmap, ctx.accel, q - off, qn, RADIUS, K)
    print(f"ball: {len(pairs)} hidden pairs, {len({r for r, _ in pairs})} rows, "
          f"{differ} rows read fewer than the old candidates")
    assert len(pairs) > 100   # the wall hides what is across it


def test_cut_read_lists_are_read_again_whole(monkeypatch):
    """Rows whose read list is longer than the list's width (READ_WIDTH x k) are read
    again as wide as they need: with a one-photon list every row is, and the estimates
    and hidden pairs are those of the full lists, with and without a footprint floor."""
    from engine import photonvisibility
    ctx = prepare_context(lamp_scene(), RenderSettings(**SETTINGS))
    pmap = PhotonMap(shoot_photons(ctx, {})[-1])
    rng = np.random.default_rng(13)
    p = np.column_stack([rng.uniform(-0.6, 0.6, 200), np.full(200, 2.0),
                         rng.uniform(1.0, 2.1, 200)]) - ctx.geo.offset
    n = np.tile([0.0, -1.0, 0.0], (200, 1))
    for r_floor in (None, rng.uniform(0.0, 0.3, 200)):
        want = photonvisibility.visible_irradiance(pmap, ctx.accel, p, n, None, 0.19, 64, 1,
                                                   "knn_simpson", r_floor=r_floor)
        pairs = hidden_photons(pmap, ctx.accel, p, n, None, 0.19, 64, r_floor)
        with monkeypatch.context() as m:
            m.setattr(photonvisibility, "READ_WIDTH", 0)
            got = photonvisibility.visible_irradiance(pmap, ctx.accel, p, n, None, 0.19, 64,
                                                      1, "knn_simpson", r_floor=r_floor)
            cut = hidden_photons(pmap, ctx.accel, p, n, None, 0.19, 64, r_floor)
        assert len(pairs[0]) > 100
        assert np.array_equal(got, want)
        for a, b in zip(pairs, cut):
            assert np.array_equal(a, b)


def test_read_list_sums_give_the_masked_searchs_bits(monkeypatch):
    """visible_irradiance's rows that hide a photon are summed again from their read lists
    (photonvisibility._visible_sums: each read photon's weight and the row's factor from
    the first search) instead of a second, masked search (_reestimate): the same bits,
    with camera-side counts that leave some photons unusable (chaincounts' masks), with a
    footprint floor (floored foci), and with every list cut and read again whole."""
    from engine import photonvisibility as pv
    ctx = prepare_context(lamp_scene(), RenderSettings(**SETTINGS))
    ph = shoot_photons(ctx, {})[-1]
    rng = np.random.default_rng(21)
    # Counts per photon (total, diffuse, glossy, transmission) so that the rows' camera
    # counts below keep some photons and not others.
    b = rng.integers(0, 3, (len(ph), 4)).astype(np.uint8)
    b[:, 0] = b[:, 1:].sum(1)
    pmap = PhotonMap(ph, keep_source=True)
    pmap.photons.bounces = b[pmap.source]  # (the map's order)
    m = 300
    p = np.column_stack([rng.uniform(-0.6, 0.6, m), np.full(m, 2.0),
                         rng.uniform(1.0, 2.1, m)]) - ctx.geo.offset
    n = np.tile([0.0, -1.0, 0.0], (m, 1))
    limits = np.array([4, 3, 3, 3], np.int64)
    counts = np.zeros((m, 4), np.int64)
    counts[:, 1] = rng.integers(0, 2, m)
    counts[:, 0] = counts[:, 1]
    radius, k = 0.19, 64
    floors = (None, rng.uniform(0.0, 0.3, m))
    changed = 0
    for width in (pv.READ_WIDTH, 0):
        with monkeypatch.context() as mp:
            mp.setattr(pv, "READ_WIDTH", width)
            for r_floor in floors:
                for lim, cnt in ((None, None), (limits, counts)):
                    got = pv.visible_irradiance(pmap, ctx.accel, p, n, None, radius, k, 1,
                                                "knn_simpson", r_floor=r_floor, limits=lim,
                                                counts=cnt)
                    E, rows, hid = pv._estimate_hidden(pmap, ctx.accel, p, n, None, radius,
                                                       k, 1, "knn_simpson", r_floor, lim,
                                                       cnt, None)
                    assert len(np.unique(rows)) > 10
                    plain = E.copy()
                    want = pv._reestimate(E, pmap, p, n, radius, k, 1, "knn_simpson",
                                          r_floor, lim, cnt, rows, hid)
                    assert np.array_equal(got, want)
                    changed += int((got != plain).any(1).sum())
                    if cnt is not None:  # the counts' masks do drop photons here
                        unmasked = pv.visible_irradiance(pmap, ctx.accel, p, n, None,
                                                         radius, k, 1, "knn_simpson",
                                                         r_floor=r_floor)
                        assert not np.array_equal(got, unmasked)
    assert changed > 100
    # Floored foci were among the rows (factor != 1: their estimate is f x the plain sum):
    # the footprint floor exceeds many rows' k-th distance on the lit wall.
    count = np.zeros(m, np.int64)
    read = (count, np.empty((m, 8 * k), np.int64), np.empty((m, 8 * k)), np.empty(m))
    pmap.knn_irradiance(p, n, radius, k, 1, "knn_simpson", r_floor=floors[1], read=read)
    assert ((read[3] != 1.0) & (count > 0)).sum() > 10


def test_estimate_blocks_give_the_same_bits(monkeypatch):
    """_estimate_hidden reads its rows in blocks (READ_ROWS; SERIAL_READ_ROWS for a map
    no other thread shares, as a camera chunk's): each row's estimate, read list and
    visibility are its own, so blocks of 7 or 64 rows give the bits of one block, with a
    footprint floor, camera-side counts and the hidden pairs (offset by each block's
    start)."""
    from engine import photonvisibility as pv
    ctx = prepare_context(lamp_scene(), RenderSettings(**SETTINGS))
    ph = shoot_photons(ctx, {})[-1]
    rng = np.random.default_rng(31)
    b = rng.integers(0, 3, (len(ph), 4)).astype(np.uint8)
    b[:, 0] = b[:, 1:].sum(1)
    pmap = PhotonMap(ph, keep_source=True)
    pmap.photons.bounces = b[pmap.source]
    assert pmap.workers == 1  # (SERIAL_READ_ROWS' case)
    m = 300
    p = np.column_stack([rng.uniform(-0.6, 0.6, m), np.full(m, 2.0),
                         rng.uniform(1.0, 2.1, m)]) - ctx.geo.offset
    n = np.tile([0.0, -1.0, 0.0], (m, 1))
    limits = np.array([4, 3, 3, 3], np.int64)
    counts = np.zeros((m, 4), np.int64)
    counts[:, 1] = rng.integers(0, 2, m)
    counts[:, 0] = counts[:, 1]
    r_floor = rng.uniform(0.0, 0.3, m)
    for lim, cnt in ((None, None), (limits, counts)):
        def run(rows):
            with monkeypatch.context() as mp:
                mp.setattr(pv, "SERIAL_READ_ROWS", rows)
                return pv._estimate_hidden(pmap, ctx.accel, p, n, None, 0.19, 64, 1,
                                           "knn_simpson", r_floor, lim, cnt, None,
                                           visible=True)
        whole = run(m)
        assert len(np.unique(whole[1])) > 10  # rows that hide photons
        for rows in (7, 64):
            got = run(rows)
            for a, w in zip(got, whole):
                assert np.array_equal(a, w)


def test_read_list_sums_take_pairs_in_any_order():
    """_visible_sums walks each row's hidden photons along its read list (the order
    _hidden_pairs gives them); pairs shuffled (rows and photons in any order) are sorted
    and bisected instead: the same sums, which differ from the unmasked estimate."""
    from engine import photonvisibility as pv
    ctx = prepare_context(lamp_scene(), RenderSettings(**SETTINGS))
    pmap = PhotonMap(shoot_photons(ctx, {})[-1])
    rng = np.random.default_rng(8)
    m = 200
    p = np.column_stack([rng.uniform(-0.6, 0.6, m), np.full(m, 2.0),
                         rng.uniform(1.0, 2.1, m)]) - ctx.geo.offset
    n = np.tile([0.0, -1.0, 0.0], (m, 1))
    E, count, photons, weight, factor, _ = pv._estimate_read(
        pmap, None, None, p, n, 0.19, 64, 1, "knn_simpson", None)
    todo = np.flatnonzero((count > 0) & (count <= photons.shape[1]))
    rows, hid = pv._hidden_pairs(pmap, ctx.accel, p, n, np.zeros(0), todo, todo, count,
                                 photons)
    assert len(np.unique(rows)) > 10
    read = (count, photons, weight, factor)
    walked, shuffled = E.copy(), E.copy()
    pv._visible_sums(pmap, None, None, walked, rows, rows, hid, read)
    perm = rng.permutation(len(rows))
    pv._visible_sums(pmap, None, None, shuffled, rows[perm], rows[perm], hid[perm], read)
    assert np.array_equal(walked, shuffled)
    assert (walked != E).any(1).sum() > 10


def test_orientation_keys_unique_as_numpy():
    """The pre-test's distinct orientations (onesurface._unique_keys) are
    np.unique(axis=0)'s arrays: one orientation, a few, and random normals (keys at both
    ends of their range)."""
    from engine.onesurface import _orientation_keys, _unique_keys
    rng = np.random.default_rng(3)
    cases = [np.tile([0.0, 0.0, 1.0], (50, 1)),
             np.r_[np.tile([0.0, -1.0, 0.0], (30, 1)), np.tile([1.0, 0.0, 0.0], (20, 1)),
                   np.tile([0.0, 1.0, 0.0], (5, 1))],
             rng.normal(size=(2000, 3))]
    for n in cases:
        rk = _orientation_keys(n)
        got, which = _unique_keys(rk)
        want, inverse = np.unique(rk, axis=0, return_inverse=True)
        assert np.array_equal(got, want)
        assert np.array_equal(which, inverse.reshape(-1))
        assert np.array_equal(got[which], rk)


def test_estimate_memory_counts_each_threads_read_lists():
    """Each render thread keeps its visibility read lists (photonvisibility._read_buffers)
    for its life; estimate_memory counts them, at their largest (READ_ROWS rows, READ_WIDTH
    x k wide), once per thread."""
    import threading

    from engine import RenderSettings
    from engine import photonvisibility as pv
    from engine.resources import estimate_memory
    from engine.scene import Scene
    s = RenderSettings(photons=1000, k_nearest=32, workers=2)
    got = {}

    def read():
        ids, weights = pv._read_buffers(pv.READ_ROWS, pv.READ_WIDTH * s.k_nearest)
        got["bytes"] = ids.nbytes + weights.nbytes

    t = threading.Thread(target=read)
    t.start()
    t.join()
    part = estimate_memory(Scene(), s).parts["visibility read lists"]
    assert part == s.threads * got["bytes"]
