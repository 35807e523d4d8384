"""The photon pass's compiled kernels (engine/photonkernels.py): their random stream,
their surface data against bsdf.surface_hit, and the photon pass's energy."""
import numpy as np
import pytest

from engine import RenderSettings
from engine import photonkernels as pk
from engine.accel import Accel
from engine.api import PaperScene, sphere_mesh
from engine.bsdf import surface_hit
from engine.geometry import prepare
from engine.scene import Material

from test_energy import closed_box, shoot


def _u(key, slot, bounce, dim):
    out = np.empty(len(slot))
    pk.uniforms(np.uint64(key), np.asarray(slot, np.int64), bounce, dim, out)
    return out


def test_uniform_stream_is_uniform_and_independent_across_slots_bounces_and_dimensions():
    slot = np.arange(200_000)
    a = _u(7, slot, 0, 0)
    assert a.min() >= 0.0 and a.max() < 1.0
    # mean 1/2 and variance 1/12 within ~5 standard errors
    assert abs(a.mean() - 0.5) < 5 * np.sqrt(1 / 12 / len(a))
    assert abs(a.var() * 12 - 1.0) < 0.02
    counts = np.bincount((a * 20).astype(int), minlength=20)
    chi2 = ((counts - len(a) / 20) ** 2 / (len(a) / 20)).sum()
    assert chi2 < 60  # 19 degrees of freedom: p ~ 1e-6
    others = [_u(7, slot, 0, 1), _u(7, slot, 1, 0), _u(8, slot, 0, 0), _u(7, slot + 1, 0, 0)]
    for b in others:
        assert abs(np.corrcoef(a, b)[0, 1]) < 0.01
        assert not np.array_equal(a, b)
    np.testing.assert_array_equal(a, _u(7, slot, 0, 0))  # same key and counter, same number


def _scene():
    s = PaperScene(width=16, height=12)
    s.add_material(Material("wall", (0.6, 0.5, 0.4)))
    s.add_material(Material("ball", (0.2, 0.7, 0.3)))
    s.add_box((0, 0, 1), (2, 2, 2), "wall", name="room")
    v, f, n, _ = sphere_mesh((0.3, -0.2, 0.6), 0.4, segments=24, rings=12)
    s.add_triangles(v, f, "ball", name="ball", normals=n)
    s.add_point_light((0.1, -0.2, 1.6), power=10.0)
    s.set_camera((0, -0.9, 1), (0, 0, 1), view_angle=90)
    return s


def _embree_layout(prim, u, v):
    """Accel.intersect's hits (prim (N,) int64, < 0: miss; u, v float64) in the layout of
    Accel.intersect_hits, as one geometry starting at row 0."""
    from engine.accel import rows_as_hits
    geom, prim32, starts = rows_as_hits(prim)
    return geom, prim32, u.astype(np.float32), v.astype(np.float32), starts


def test_photon_surfaces_match_surface_hit():
    s = _scene()
    s.validate()
    geo, table = prepare(s)
    accel = Accel(geo.vertices32, geo.faces32, 1)
    rng = np.random.default_rng(3)
    n = 5000
    o = np.tile((0.1, -0.2, 1.6) - geo.offset, (n, 1)) + 0.2 * rng.random((n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    _, prim, u, v = accel.intersect(o, d)
    assert (prim >= 0).all()
    surf = pk.surface_arrays(n)
    pk.photon_surfaces(prim, u, v, d, geo.v0, geo.e1, geo.e2, geo.corner_normals,
                       geo.material, table.base_color, table.alpha, *surf)
    p, ng, ns, front, mat, base, alpha, offset = surf
    hit = surface_hit(geo, table, prim, u, v, d)
    assert len(geo.corner_normals)  # the smooth sphere's normals are interpolated
    np.testing.assert_allclose(p, hit.p, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ng, hit.ng, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ns, hit.ns, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(front, hit.front)
    np.testing.assert_array_equal(mat, hit.mat)
    np.testing.assert_array_equal(base, hit.base)
    np.testing.assert_array_equal(alpha, table.alpha[hit.mat])
    np.testing.assert_allclose(offset, hit.offset, rtol=1e-9, atol=0)


def test_closed_box_stores_the_geometric_series_of_the_emitted_power():
    """In a closed Lambertian box of albedo a every photon is stored at each bounce and
    survives Russian roulette with probability a at unchanged power: the stored power sums
    to P / (1 - a) in expectation (P (1 + a + a^2 + ...)). 20k photons: ~0.6 % standard
    error."""
    albedo, P = 0.8, 100.0
    # (bounce limits out of the way: tests/test_bounce_limits.py checks the cut series)
    ph = shoot(closed_box(albedo, P), RenderSettings(photons=20000, max_photon_depth=80,
                                                     max_bounces=1024, diffuse_bounces=1024))
    total = ph.power.astype(np.float64).sum(axis=0)
    np.testing.assert_allclose(total, P / (1 - albedo), rtol=0.025)
    # Russian roulette never raises a photon's power here (survival = albedo exactly).
    assert np.allclose(ph.power.astype(np.float64).sum(axis=1), 3 * P / 20000, rtol=1e-5)


def test_same_seed_same_photons_other_seed_other_photons():
    s = closed_box(0.5)
    a = shoot(s, RenderSettings(photons=3000, seed=1, chunk_size=1000))
    b = shoot(s, RenderSettings(photons=3000, seed=1, chunk_size=1000))
    c = shoot(s, RenderSettings(photons=3000, seed=2, chunk_size=1000))
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(a.power, b.power)
    assert len(a) != len(c) or not np.array_equal(a.position, c.position)


def test_scatter_computes_the_surface_data_as_photon_surfaces_does():
    """scatter's own surface data (given=False) and photon_surfaces' arrays (given=True,
    the path of textured materials and shared instances) give the same photons, bit for
    bit, with and without the visibility split-offs."""
    s = _scene()
    s.validate()
    geo, table = prepare(s)
    accel = Accel(geo.vertices32, geo.faces32, 1)
    rng = np.random.default_rng(5)
    n = 3000
    o = np.tile((0.1, -0.2, 1.6) - geo.offset, (n, 1)) + 0.2 * rng.random((n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    _, prim, u, v = accel.intersect(o, d)
    prim[::7] = -1  # some misses
    geom, prim32, u32, v32, starts = _embree_layout(prim, u, v)
    surf = pk.surface_arrays(n)
    pk.photon_surfaces(prim, u, v, d, geo.v0, geo.e1, geo.e2, geo.corner_normals,
                       geo.material, table.base_color, table.alpha, *surf)
    power = rng.random((n, 3))
    flags = rng.integers(0, 16, n).astype(np.int64)
    # Each triangle hides from some ray kinds: split-off copies pass it.
    visibility = rng.integers(0, 64, geo.count).astype(np.uint8)
    plain = pk.plain_materials(table.closure_params)
    for vis_on in (False, True):
        kinds = np.full(n, pk.SEGMENT_KINDS, np.int64)
        out = []
        for given in (True, False):
            st, nx = pk.store_arrays(n), pk.next_arrays(2 * n)
            counts = pk.scatter(np.uint64(11), 1, d, power, flags, kinds, np.arange(n), _NO_BNC(n), geom,
                                prim32, starts, u32, v32, geo.v0, geo.e1, geo.e2,
                                geo.corner_normals, geo.material, table.base_color,
                                table.alpha, given,
                                *(surf if given else pk.surface_arrays(0)),
                                # bump factors of 1, or none (the same: x * 1.0 is x)
                                np.ones(n) if given else np.zeros(0),
                                table.closure_params, plain, table.ior, visibility,
                                geo.object_id, np.zeros(1, np.bool_), 0, False, vis_on,
                                pk._NO_LIMITS, *st, *nx, _scratch_rows(n))
            out.append((counts, [a[:counts[0]] for a in st] + [a[:counts[1]] for a in nx]))
        (c1, a1), (c2, a2) = out
        assert c1 == c2 and c1[0] > 0 and c1[1] > 0
        for x, y in zip(a1, a2):
            np.testing.assert_array_equal(x, y)


def test_a_shot_in_many_chunks_is_the_same_on_one_and_two_workers():
    """The chunks' stored photons are copied into the shot in chunk order (photons._Shot,
    its arrays grown as the rate of stored photons rises): the same photons for any
    worker count."""
    s = closed_box(0.7)
    a = shoot(s, RenderSettings(photons=6000, seed=4, chunk_size=500, workers=1))
    b = shoot(s, RenderSettings(photons=6000, seed=4, chunk_size=500, workers=2))
    assert len(a) > 6000 and a.emitted == b.emitted == 6000
    for name in ("position", "power", "direction", "normal", "kind"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        assert getattr(a, name).flags.c_contiguous


def test_plain_materials_scatter_as_with_the_full_set_of_lobes(monkeypatch):
    """scatter's plain-material path (only the diffuse and pass weights written, Russian
    roulette over those two lobes) gives the photons the full closure set-up and the
    roulette over every lobe give, bit for bit: plain = all False sends every hit through
    principled.setup. Glass and plain hits alternate in the blocks (a plain hit after a
    glass one must not read the glass lobes' weights), and a translucent wall uses the
    pass lobe. The ball's normals bend up to ~11 degrees, where SMOOTH_GLASS rows take
    engine/glassadjoint.py, which FULL rows do not have yet (docs/accuracy.md,
    smoothglass43): off here, so both paths sample the glass lobe."""
    monkeypatch.setattr(pk, "GLASS_ADJOINT_MODE", pk.GLASS_ADJOINT_NEVER)
    s = _scene()
    s.add_material(Material("glass", (1.0, 1.0, 1.0), transmission=1.0, ior=1.45))
    s.add_material(Material("veil", (0.3, 0.6, 0.9), alpha=0.4))
    v, f, n, _ = sphere_mesh((-0.3, 0.2, 1.3), 0.35, segments=16, rings=8)
    s.add_triangles(v, f, "glass", name="glass ball", normals=n)
    s.add_box((0.5, 0.4, 1.2), (0.3, 0.3, 0.3), "veil", name="veil")
    s.validate()
    geo, table = prepare(s)
    accel = Accel(geo.vertices32, geo.faces32, 1)
    rng = np.random.default_rng(9)
    n = 6000
    o = np.tile((0.1, -0.2, 1.6) - geo.offset, (n, 1)) + 0.2 * rng.random((n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    _, prim, u, v = accel.intersect(o, d)
    prim[::11] = -1  # some misses
    geom, prim32, u32, v32, starts = _embree_layout(prim, u, v)
    plain = pk.plain_materials(table.closure_params)
    assert plain.any() and not plain.all()
    classes = pk.lobe_classes(table.closure_params)
    assert (classes == pk.SMOOTH_GLASS).sum() == 1 and np.array_equal(classes == pk.PLAIN, plain)
    mats = table.closure_params.shape[0]
    hit_mat = geo.material[prim[prim >= 0]]
    assert (~plain[hit_mat]).sum() > 100 and plain[hit_mat].sum() > 1000
    assert (classes[hit_mat] == pk.SMOOTH_GLASS).sum() > 100
    power = rng.random((n, 3))
    flags = rng.integers(0, 16, n).astype(np.int64)
    out = []
    for row_plain in (classes, plain, np.zeros(mats, np.bool_)):
        st, nx = pk.store_arrays(n), pk.next_arrays(2 * n)
        counts = pk.scatter(np.uint64(13), 2, d, power, flags,
                            np.full(n, pk.SEGMENT_KINDS, np.int64), np.arange(n), _NO_BNC(n), geom,
                            prim32, starts, u32, v32, geo.v0, geo.e1, geo.e2,
                            geo.corner_normals, geo.material, table.base_color,
                            table.alpha, False, *pk.surface_arrays(0), np.ones(n),
                            table.closure_params, row_plain, table.ior,
                            np.full(geo.count, 255, np.uint8), geo.object_id,
                            np.zeros(1, np.bool_), 0, False, False, pk._NO_LIMITS, *st, *nx,
                            _scratch_rows(n))
        out.append((counts, [a[:counts[0]] for a in st] + [a[:counts[1]] for a in nx]))
    (c0, a0), (c1, a1), (c2, a2) = out
    assert c0 == c1 == c2 and c1[0] > 1000 and c1[1] > 1000
    for x, y, z in zip(a0, a1, a2):
        np.testing.assert_array_equal(x, y)
        np.testing.assert_array_equal(x, z)


def test_smooth_glass_sets_up_as_principled_setup():
    """photonkernels.smooth_glass (scatter's SMOOTH_GLASS set-up) writes the weights and
    glass columns principled.setup writes, bit for bit: Glass and Principled nodes,
    tinted, translucent (alpha < 1), Add Shader weight, roughness 0 and just above 0
    (still a delta lobe), with and without Multiscatter GGX, from both sides, at view
    cosines from grazing (and below 0) to normal; and the glass tables its x = 0 lookups
    read are finite (their zero terms then change no bit)."""
    from engine.closures import principled as pr, tables
    for tab in (tables.GLASS_E, tables.GLASS_EAVG, tables.GLASS_INV_E, tables.GLASS_INV_EAVG,
                tables.SCHLICK_IOR_S):
        assert np.all(np.isfinite(tab))
    rng = np.random.default_rng(21)
    rows = []
    for node in (pr.NODE_GLASS, pr.NODE_PRINCIPLED):
        for rough in (0.0, 0.009):
            for multi in (0.0, 1.0):
                for ior in (1.0, 1.45, 2.4, 0.8):
                    q = np.zeros(pr.N_MAT)
                    q[pr.M_ALPHA] = 1.0
                    q[pr.M_TRANS] = 1.0
                    q[pr.M_ROUGH] = rough
                    q[pr.M_IOR] = ior
                    q[pr.M_SPEC] = 1.0
                    q[pr.M_LEVEL] = 0.5 if ior != 2.4 else 0.7
                    q[pr.M_STINT:pr.M_STINT + 3] = (1.0, 0.8, 0.5)
                    q[pr.M_MULTI] = multi
                    q[pr.M_NODE] = node
                    q[pr.M_TTINT:pr.M_TTINT + 3] = (1.0, 0.9, 0.7)
                    q[pr.M_ADD] = 0.0 if ior != 1.45 else 0.5
                    rows.append(q)
    params = np.array(rows)
    assert np.all(pk.lobe_classes(params) == pk.SMOOTH_GLASS)
    n = 4000
    mat = rng.integers(0, len(params), n).astype(np.int64)
    base = rng.random((n, 3))
    base[::7] = 1.0
    cos_o = np.concatenate([[-0.1, 0.0, 1e-5, 1.0], rng.random(n - 4)])
    front = rng.random(n) < 0.5
    alpha = np.where(rng.random(n) < 0.3, rng.random(n), 1.0)
    prm = np.zeros((n, pr.N_PACK))
    w = np.zeros((n, pr.N_LOBES, 3))
    pr.setup(mat, params, base, cos_o, front, alpha, prm, w)
    gprm = np.zeros((1, pr.N_PACK))
    wj = np.zeros((pr.N_LOBES, 3))
    cols = ([pr.P_GLASS_RW + c for c in range(3)] + [pr.P_GLASS_TW + c for c in range(3)]
            + [pr.P_GLASS_F0 + c for c in range(3)] + [pr.P_GLASS_ALPHA, pr.P_GLASS_ETA])
    for i in range(n):
        pk.smooth_glass(params, mat[i], alpha[i], base, i, cos_o[i], front[i], gprm, wj)
        for lobe in (pr.L_DIFFUSE, pr.L_PASS, pr.L_GLASS_R, pr.L_GLASS_T):
            assert wj[lobe].tobytes() == w[i, lobe].tobytes(), (i, lobe)
        assert gprm[0, cols].tobytes() == prm[i, cols].tobytes(), i
        for lobe in (pr.L_METAL, pr.L_SPEC, pr.L_COAT, pr.L_SHEEN):
            assert not np.any(w[i, lobe])


def test_smooth_glass_at_with_a_call_s_constants_sets_up_as_principled_setup():
    """scatter's SMOOTH_GLASS set-up as scatter calls it: one table of constants per
    call (smooth_glass_consts, a row per material and side), shared by every hit, whose
    tints, f0 and energy compensation's Fms are kept from the row's last base colour.
    Runs of hits of one material and base colour (an untextured base), base colours that
    change from hit to hit (a texture), a base of -0.0 after 0.0 (the clamps keep the
    sign) and NaN: the weights, glass columns and remap principled.setup and the one-hit
    smooth_glass give, bit for bit; and the sampler with the row's f0 and 1 / eta gives
    principled._glass_sample's bits."""
    from engine.closures import principled as pr
    rng = np.random.default_rng(55)
    rows = []
    for node in (pr.NODE_GLASS, pr.NODE_PRINCIPLED):
        for rough in (0.0, 0.009):
            for multi in (0.0, 1.0):
                for ior in (1.45, 0.8):
                    q = np.zeros(pr.N_MAT)
                    q[pr.M_ALPHA] = q[pr.M_TRANS] = q[pr.M_SPEC] = 1.0
                    q[pr.M_ROUGH], q[pr.M_IOR], q[pr.M_LEVEL] = rough, ior, 0.5
                    q[pr.M_STINT:pr.M_STINT + 3] = (1.0, 0.8, 0.5)
                    q[pr.M_MULTI], q[pr.M_NODE] = multi, node
                    q[pr.M_TTINT:pr.M_TTINT + 3] = (1.0, 0.9, 0.7)
                    rows.append(q)
    params = np.array(rows)
    assert np.all(pk.lobe_classes(params) == pk.SMOOTH_GLASS)
    n = 6000
    # runs of 1-40 hits sharing a material, side and base colour
    mat = np.empty(n, np.int64)
    front = np.empty(n, bool)
    base = np.empty((n, 3))
    i = 0
    while i < n:
        k = min(int(rng.integers(1, 40)), n - i)
        mat[i:i + k] = rng.integers(0, len(params))
        front[i:i + k] = rng.random() < 0.5
        base[i:i + k] = (1.0, 1.0, 1.0) if rng.random() < 0.5 else rng.random(3)
        i += k
    textured = rng.random(n) < 0.2
    base[textured] = rng.random((int(textured.sum()), 3))
    base[100:104] = ((0.0, 0.5, 1.0), (-0.0, 0.5, 1.0), (0.0, -0.0, 1.0), (np.nan, 0.5, 1.0))
    mat[100:104] = mat[100]
    front[100:104] = front[100]
    cos_o = np.concatenate([[-0.1, 0.0, 1e-5, 1.0], rng.random(n - 4)])
    alpha = np.where(rng.random(n) < 0.3, rng.random(n), 1.0)
    prm = np.zeros((n, pr.N_PACK))
    w = np.zeros((n, pr.N_LOBES, 3))
    pr.setup(mat, params, base, cos_o, front, alpha, prm, w)
    sg = np.zeros((2 * len(params), pk.SG_N))
    gprm = np.zeros((1, pr.N_PACK))
    wj = np.zeros((pr.N_LOBES, 3))
    gprm1 = np.zeros((1, pr.N_PACK))
    wj1 = np.zeros((pr.N_LOBES, 3))
    cols = ([pr.P_GLASS_RW + c for c in range(3)] + [pr.P_GLASS_TW + c for c in range(3)]
            + [pr.P_GLASS_F0 + c for c in range(3)] + [pr.P_GLASS_ALPHA, pr.P_GLASS_ETA])
    for i in range(n):
        r = 2 * mat[i] + (1 if front[i] else 0)
        if sg[r, pk._SG_SET] == 0.0:
            pk.smooth_glass_consts(params, mat[i], front[i], sg, r)
        remap = pk.smooth_glass_at(params, mat[i], alpha[i], base, i, cos_o[i], gprm, wj, sg, r)
        remap1 = pk.smooth_glass(params, mat[i], alpha[i], base, i, cos_o[i], front[i],
                                 gprm1, wj1)
        assert np.float64(remap).tobytes() == np.float64(remap1).tobytes(), i
        for lobe in (pr.L_DIFFUSE, pr.L_PASS, pr.L_GLASS_R, pr.L_GLASS_T):
            assert wj[lobe].tobytes() == w[i, lobe].tobytes(), (i, lobe)
        assert gprm[0, cols].tobytes() == prm[i, cols].tobytes(), i
        if i % 3 == 0 and 0.0 < cos_o[i]:
            oz = cos_o[i]
            ox = np.sqrt(1.0 - oz * oz)
            u3 = rng.random()
            mu = min(max(oz, 0.0), 1.0)
            want = pr._glass_sample(gprm, 0, ox, 0.0, oz, 0.0, 0.0, u3)
            got = pk._smooth_glass_sample_at(gprm, ox, 0.0, oz, u3, mu, remap,
                                             sg[r, pk._SG_F0E], sg[r, pk._SG_INV_ETA])
            assert np.array(got[:6]).tobytes() == np.array(want[:6]).tobytes(), i
            assert got[6] == want[6]


def test_smooth_glass_samples_as_principled_glass_sample():
    """scatter's smooth glass sampler (photonkernels._smooth_glass_sample, given the
    Fresnel remap smooth_glass returned for the hit's cosine) gives the direction,
    weight and side of principled._glass_sample, bit for bit: the set-ups above, wo from
    grazing to normal on both sides, reflect and refract, total internal reflection, and
    a remap that does not belong to the cosine (recomputed: the same bits)."""
    from engine.closures import principled as pr
    rng = np.random.default_rng(22)
    params = []
    for node in (pr.NODE_GLASS, pr.NODE_PRINCIPLED):
        for multi in (0.0, 1.0):
            for ior in (1.0, 1.45, 2.4, 0.8):
                q = np.zeros(pr.N_MAT)
                q[pr.M_ALPHA] = q[pr.M_TRANS] = q[pr.M_SPEC] = 1.0
                q[pr.M_IOR], q[pr.M_LEVEL], q[pr.M_MULTI], q[pr.M_NODE] = ior, 0.5, multi, node
                q[pr.M_STINT:pr.M_STINT + 3] = (1.0, 0.8, 0.5)
                q[pr.M_TTINT:pr.M_TTINT + 3] = (1.0, 0.9, 0.7)
                params.append(q)
    params = np.array(params)
    base = rng.random((1, 3))
    gprm = np.zeros((1, pr.N_PACK))
    wj = np.zeros((pr.N_LOBES, 3))
    seen = set()
    for k in range(6000):
        m = int(rng.integers(0, len(params)))
        front = bool(rng.random() < 0.5)
        z = (1e-6, 1.0, 0.05)[k] if k < 3 else rng.random()
        phi = 2 * np.pi * rng.random()
        r = np.sqrt(max(0.0, 1.0 - z * z))
        ox, oy, oz = r * np.cos(phi), r * np.sin(phi), z
        remap = pk.smooth_glass(params, m, 1.0, base, 0, oz, front, gprm, wj)
        mu = min(max(oz, 0.0), 1.0)
        u3 = rng.random()
        want = pr._glass_sample(gprm, 0, ox, oy, oz, 0.0, 0.0, u3)
        for given in ((mu, remap), (0.5 * mu, remap), (mu, -1.0)):
            got = pk._smooth_glass_sample(gprm, ox, oy, oz, u3, *given)
            assert np.array(got[:6]).tobytes() == np.array(want[:6]).tobytes(), (k, given)
            assert got[6] == want[6]
        seen.add((want[6], remap >= 0.0, want[3] == 0.0))
    # reflected and refracted, with and without a remap from the set-up, and TIR's zero
    assert {(False, False, False), (True, False, False), (False, True, False),
            (True, True, False)} <= seen


def test_a_chunk_traced_with_used_buffers_stores_the_photons_of_fresh_ones():
    """_trace_chunk borrows its emission rows, path flags, ray kinds, bump factors,
    continued rays and stored-photon blocks from the trace's pool: buffers left full of
    NaN and garbage by earlier chunks (and larger than needed) give the photons of new
    ones, bit for bit."""
    import engine.photons as P
    from engine.lights import allocate_photons
    from engine.render import prepare_context

    s = closed_box(0.6)
    s.add_material(Material("glass", (1.0, 1.0, 1.0), transmission=1.0, ior=1.5))
    v, f, n, _ = sphere_mesh((0.2, 0.1, 0.5), 0.3, segments=16, rings=8)
    s.add_triangles(v, f, "glass", name="glass ball", normals=n)
    st = RenderSettings(photons=4000, workers=1)
    ctx = prepare_context(s, st)
    light = ctx.lights[0]
    count = int(allocate_photons(ctx.lights, st.photons)[0])

    def chunk(pool):
        rng = np.random.default_rng([st.seed, 1, 0, 0])
        stored = P._trace_chunk(ctx, ctx.accel, light, count, count, rng, False, None, None,
                                None, pool)
        return [np.concatenate([a[:k] for a, k in [(arrays[i], k)
                                                    for arrays, k in stored.parts()]])
                for i in range(6)]

    fresh = chunk(P._Buffers())
    used = P._Buffers()
    junk = np.random.default_rng(1)
    for make, rows in ((pk.next_arrays, 3 * count), (pk.next_arrays, 2 * count),
                       (pk.store_arrays, 4 * count), (P._factors, 2 * count)):
        arrays = make(rows)
        for a in arrays:
            a[...] = junk.integers(0, 255, a.shape) if a.dtype.kind in "iub" else np.nan
        used.give(arrays, make)
    again = chunk(used)
    assert len(fresh[0]) > count
    for x, y in zip(fresh, again):
        np.testing.assert_array_equal(x, y)
    ctx.accel.close()


def _room_with_fine_ball():
    """(geo, table) of _scene() prepared with a 138,600-triangle ball: more than two
    Embree mesh pieces (accel.MESH_TRIANGLES), so hits land in later geometries."""
    from engine import accel as accel_mod
    s = _scene()
    v, f, n, _ = sphere_mesh((-0.3, 0.2, 1.3), 0.35, segments=330, rings=210)
    s.add_triangles(v, f, "ball", name="fine ball", normals=n)
    s.validate()
    geo, table = prepare(s)
    assert geo.count > 2 * accel_mod.MESH_TRIANGLES
    return geo, table


def test_intersect_traced_in_a_kernel_is_embreex_answer_bit_for_bit():
    """Accel.intersect through the compiled rtcIntersect8 loop (_intersect_rows) gives
    the arrays embreex's run() gives (_intersect_run): t, prim, u, v with their dtypes,
    bit for bit, on a mesh in several pieces (hits in later geometries), for float64 and
    float32 rays, unbounded and bounded tmax (short rays, NaN, inf, float32's max and
    above, negative, a scalar), on one thread and split over two."""
    from engine import accel as accel_mod

    if not accel_mod._kernel_hits_address():
        pytest.skip("rtcIntersect8 not reachable from a kernel here")
    geo, _ = _room_with_fine_ball()
    rng = np.random.default_rng(22)
    m = 3 * accel_mod.MIN_PER_THREAD
    o = np.tile((0.1, -0.2, 1.6) - geo.offset, (m, 1)) + 0.2 * rng.random((m, 3))
    d = rng.normal(size=(m, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    o[::11] = 1e6  # misses
    tmax = rng.random(m) * 2.0
    tmax[::7] = np.nan
    tmax[1::7] = np.inf
    tmax[2::7] = 1e300  # above float32's max
    tmax[3::7] = -1.0
    tmax[4::7] = np.finfo(np.float32).max
    for threads in (1, 2):
        accel = Accel(geo.vertices32, geo.faces32, threads)
        try:
            for args in ((o, d, None), (o, d, tmax), (o.astype(np.float32), d, tmax),
                         (o, d.astype(np.float32), 0.4), (o[::2], d[::2], tmax[::2]),
                         (o[:0], d[:0], None)):
                got = accel.intersect(*args)
                want = accel._intersect_run(*args)
                for x, y in zip(got, want):
                    assert x.dtype == y.dtype and x.shape == y.shape
                    np.testing.assert_array_equal(x.view(np.uint8), y.view(np.uint8))
                if len(args[0]):
                    hit = got[1] >= 0
                    assert 0 < hit.sum() < len(hit)
                    assert (got[1][hit] >= accel_mod.MESH_TRIANGLES).sum() > 100
        finally:
            accel.close()


def test_occlusion_traced_in_packets_is_embreex_answer():
    """Accel.occluded and occluded_into through the packet kernel (rtcOccluded8,
    _occluded_packets) answer as embreex's run(query="OCCLUDED") one ray at a time, on a
    room with a fine ball in several mesh pieces: rays between random surface points
    (lifted by 1e-5 or not at all, ends on the surfaces: the hardest cases for a
    traversal's rounding), rays grazing the walls in their planes, short, long and
    zero-length rays, NaN and inf tmax, counts that leave a packet's lanes empty, on
    one thread and split over two."""
    from engine import accel as accel_mod

    if not accel_mod._kernel_occluded_address():
        pytest.skip("rtcOccluded8 not reachable from a kernel here")
    geo, _ = _room_with_fine_ball()
    rng = np.random.default_rng(23)
    tri = geo.vertices32[geo.faces32].astype(np.float64)  # (T,3,3)
    m = 3 * accel_mod.MIN_PER_THREAD + 5

    def on_surface(k):
        t = rng.integers(0, len(tri), k)
        a, b = rng.random(k), rng.random(k)
        flip = a + b > 1
        a[flip], b[flip] = 1 - a[flip], 1 - b[flip]
        p = tri[t, 0] + a[:, None] * (tri[t, 1] - tri[t, 0]) + b[:, None] * (tri[t, 2] - tri[t, 0])
        nrm = np.cross(tri[t, 1] - tri[t, 0], tri[t, 2] - tri[t, 0])
        return p, nrm / np.maximum(np.linalg.norm(nrm, axis=1), 1e-30)[:, None]

    p0, n0 = on_surface(m)
    p1, n1 = on_surface(m)
    lift = np.where(rng.random(m) < 0.5, 1e-5, 0.0)[:, None]
    a, b = p0 + lift * n0, p1 + lift * n1
    d = b - a
    t = np.linalg.norm(d, axis=1)
    d /= np.maximum(t, 1e-300)[:, None]
    # Grazing: along a wall's plane (the room spans [-1, 1] x [-1, 1] x [0, 2]).
    g = slice(0, m // 4)
    a[g, 2] = 0.0
    d[g, 2] = 0.0
    d[g] /= np.maximum(np.linalg.norm(d[g], axis=1), 1e-300)[:, None]
    t[::13] = 0.0
    t[1::13] = np.inf
    t[2::13] = np.nan
    t[3::13] = 50.0
    o32, d32 = a.astype(np.float32), d.astype(np.float32)
    blocked_counts = []
    for threads in (1, 2):
        accel = Accel(geo.vertices32, geo.faces32, threads)
        try:
            for k in (m, m - 3, 7, 1, 0):
                want = np.asarray(accel._scene.run(
                    o32[:k], d32[:k], dists=Accel._prepare(o32[:k], d32[:k], t[:k])[2],
                    query="OCCLUDED")) == 0 if k else np.zeros(0, bool)
                got = accel.occluded(a[:k], d[:k], t[:k])
                np.testing.assert_array_equal(got, want)
                t32 = Accel._prepare(o32[:k], d32[:k], t[:k])[2]
                into = np.empty(k, bool)
                accel.occluded_into(o32[:k], d32[:k], t32, into)
                np.testing.assert_array_equal(into, want)
                blocked_counts.append(int(want.sum()))
        finally:
            accel.close()
    assert 0.1 * m < blocked_counts[0] < 0.9 * m  # both answers well represented


def test_intersect_hits_are_the_hits_of_intersect_on_a_mesh_in_pieces():
    """Accel.intersect_hits (Embree's own int32 ids and float32 barycentrics, which the
    photon pass hands to scatter) names the triangles and barycentrics Accel.intersect
    does, bit for bit, on a mesh Embree holds in several pieces (geometries of
    MESH_TRIANGLES), on one thread and split over two; and scatter gives the same photons
    from either answer."""
    from engine import accel as accel_mod

    geo, table = _room_with_fine_ball()
    rng = np.random.default_rng(21)
    m = 3 * accel_mod.MIN_PER_THREAD
    o = np.tile((0.1, -0.2, 1.6) - geo.offset, (m, 1)) + 0.2 * rng.random((m, 3))
    d = rng.normal(size=(m, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    d = d32.astype(np.float64)
    o32[::9] = 1e6  # misses: outside the room, pointing anywhere
    power = rng.random((m, 3))
    flags = rng.integers(0, 16, m).astype(np.int64)
    plain = pk.plain_materials(table.closure_params)
    for threads in (1, 2):
        accel = Accel(geo.vertices32, geo.faces32, threads)
        t, prim, u, v = accel.intersect(o32, d32)
        tfar = np.full(m, np.finfo(np.float32).max, np.float32)
        geom, prim32, u32, v32, starts = accel.intersect_hits(o32, d32, tfar)
        accel.close()
        assert len(starts) > 2 and geom.dtype == prim32.dtype == np.int32
        assert u32.dtype == v32.dtype == np.float32
        hit = geom >= 0
        assert hit.sum() > m // 2 and (~hit).sum() >= m // 9
        assert (geom[hit] > 0).sum() > 100  # hits in later pieces (starts > 0)
        np.testing.assert_array_equal(prim < 0, ~hit)
        np.testing.assert_array_equal(starts[geom[hit]] + prim32[hit], prim[hit])
        np.testing.assert_array_equal(u32.astype(np.float64)[hit], u[hit])
        np.testing.assert_array_equal(v32.astype(np.float64)[hit], v[hit])
        np.testing.assert_array_equal(tfar[hit].astype(np.float64), t[hit])
        # The same query into the caller's arrays (junk before): traced by the kernel
        # through rtcIntersect8 (a single Embree scene; the pieces are its geometries),
        # embreex's answer bit for bit, misses and tfar included; some rays end short.
        tmax = np.full(m, np.finfo(np.float32).max, np.float32)
        tmax[::5] = rng.random(len(tmax[::5])).astype(np.float32) * 0.5
        accel = Accel(geo.vertices32, geo.faces32, threads)
        want_t = tmax.copy()
        want = accel.intersect_hits(o32, d32, want_t)
        got_t = tmax.copy()
        out_arrays = (np.full(m, 77, np.int32), np.full(m, -5, np.int32),
                      np.full(m, np.nan, np.float32), np.full(m, 3.0, np.float32))
        got = accel.intersect_hits(o32, d32, got_t, out_arrays)
        accel.close()
        assert all(a is b for a, b in zip(got[:4], out_arrays))
        assert (want[0] < 0).sum() > (~hit).sum()  # the short rays miss more
        for x, y in zip(list(got) + [got_t], list(want) + [want_t]):
            assert x.dtype == y.dtype
            np.testing.assert_array_equal(x.view(np.uint8), y.view(np.uint8))
        out = []
        for geom_k, prim_k, u_k, v_k, starts_k in ((geom, prim32, u32, v32, starts),
                                                   _embree_layout(prim, u, v)):
            st, nx = pk.store_arrays(m), pk.next_arrays(2 * m)
            counts = pk.scatter(np.uint64(17), 0, d, power, flags,
                                np.full(m, pk.SEGMENT_KINDS, np.int64), np.arange(m), _NO_BNC(m), geom_k,
                                prim_k, starts_k, u_k, v_k, geo.v0, geo.e1, geo.e2,
                                geo.corner_normals, geo.material, table.base_color,
                                table.alpha, False, *pk.surface_arrays(0), np.ones(m),
                                table.closure_params, plain, table.ior,
                                np.full(geo.count, 255, np.uint8), geo.object_id,
                                np.zeros(1, np.bool_), 0, False, False, pk._NO_LIMITS, *st,
                                *nx, _scratch_rows(m))
            out.append((counts, [a[:counts[0]] for a in st] + [a[:counts[1]] for a in nx]))
        (c1, a1), (c2, a2) = out
        assert c1 == c2 and c1[0] > m // 4 and c1[1] > m // 4
        for x, y in zip(a1, a2):
            np.testing.assert_array_equal(x, y)


def test_intersect_hits_into_arrays_uses_the_trace_kernel_and_checks_them():
    """With the embreex wheel's Embree the probes accept the trace kernels (rtcIntersect8
    from compiled code answers as embreex's run()), and intersect_hits refuses output
    arrays of the wrong type or length (a short array would be written past its end)."""
    import pytest

    from engine import accel as accel_mod

    if accel_mod._LIBRARY is not None:
        assert accel_mod._kernel_hits_address() != 0
        assert accel_mod._kernel_packets_address() != 0
    v = np.array([[0, 0, 1], [1, 0, 1], [0, 1, 1]], np.float32)
    accel = Accel(v, np.array([[0, 1, 2]]))
    o = np.array([[0.2, 0.2, 0.0], [5.0, 5.0, 0.0]], np.float32)
    d = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0]], np.float32)
    tfar = np.full(2, np.finfo(np.float32).max, np.float32)
    ids, uv = np.zeros(2, np.int32), np.zeros(2, np.float32)
    geom, prim, u, v, starts = accel.intersect_hits(o, d, tfar, (ids, ids.copy(), uv, uv.copy()))
    assert list(geom) == [0, -1] and list(prim) == [0, -1] and abs(tfar[0] - 1.0) < 1e-6
    assert abs(u[0] - 0.2) < 1e-6 and abs(v[0] - 0.2) < 1e-6 and (u[1], v[1]) == (0, 0)
    for bad in ((ids[:1], ids, uv, uv), (ids, ids, uv.astype(np.float64), uv),
                (ids, ids.astype(np.int64), uv, uv)):
        with pytest.raises(ValueError):
            accel.intersect_hits(o, d, tfar, bad)
    accel.close()


def test_scatter_refuses_short_scratch_rows():
    """scatter's scratch rows (2, >= m) come from the caller: fewer raise rather than
    write past the end."""
    import pytest

    m = 4
    d = np.tile([0.0, 0.0, -1.0], (m, 1))
    with pytest.raises(ValueError):
        pk.scatter(np.uint64(1), 0, d, np.ones((m, 3)), np.zeros(m, np.int64),
                   np.full(m, pk.SEGMENT_KINDS, np.int64), np.arange(m), _NO_BNC(m),
                   np.full(m, -1, np.int32), np.zeros(m, np.int32), np.zeros(1, np.int64),
                   np.zeros(m, np.float32), np.zeros(m, np.float32), np.zeros((1, 3)),
                   np.zeros((1, 3)), np.zeros((1, 3)), np.zeros((0, 3, 3), np.float32),
                   np.zeros(1, np.int32), np.ones((1, 3)), np.ones(1), False,
                   *pk.surface_arrays(0), np.zeros(0), np.zeros((1, 30)), np.ones(1, np.bool_),
                   np.ones(1), np.zeros(1, np.uint8), np.zeros(1, np.int32),
                   np.zeros(1, np.bool_), 0, False, False, pk._NO_LIMITS, *pk.store_arrays(m),
                   *pk.next_arrays(2 * m), np.empty((2, m - 1), np.int64))


def _NO_BNC(m):
    """Photons that have not bounced yet (packed bounce counts, photonkernels.B_TOTAL)."""
    return np.zeros(m, np.int64)


def _scratch_rows(m):
    """scatter's scratch rows, filled with junk (its output must not depend on them)."""
    return np.full((2, m), -12345, np.int64)


def test_rows_as_hits_round_trips_triangle_rows():
    """accel.rows_as_hits (intersect_hits' layout for rows already resolved: the fallback
    BVHs and shared instances): starts[geom] + prim is the row again, misses get geom < 0,
    ids are int32 as Embree's."""
    from engine.accel import rows_as_hits
    rows = np.array([5, -1, 0, 123456, -1, 7], np.int64)
    geom, prim, starts = rows_as_hits(rows)
    assert geom.dtype == np.int32 and prim.dtype == np.int32 and starts.dtype == np.int64
    hit = rows >= 0
    np.testing.assert_array_equal(geom < 0, ~hit)
    np.testing.assert_array_equal(starts[geom[hit]] + prim[hit], rows[hit])
